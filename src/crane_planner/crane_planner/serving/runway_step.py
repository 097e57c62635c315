"""The planner's side of cranes sharing a runway: this crane's occupancy published, the others' kept, and a
goal from rest started late enough to keep clear of them (contract "Cranes sharing a runway"; docs/runway.md).

- **Published**: a goal's motion, once placed, is claimed: its occupancy (``runway.prediction.plan_occupancy``:
  from the trajectory's start, the settle window included) is published, stamped when it was first
  published. A motion sent from a state (a goal during a motion, a goal from a swinging load, a cancel's
  stop, a settle: ``RunwayStep.moving``) is published as it is sent, spliced after what the crane does until
  its handover; it is not placed (a handover cannot wait). With no goal claimed and the streamer holding, a
  ``holding`` occupancy where it holds: at start-up once the hold is known, after a goal ends (done,
  aborted, canceled, stopped), and once the streamer holds after a published motion no goal ends (a settle).
- **Kept**: the newest occupancy of every other crane, by name (``Neighbours``); an unusable one (the node
  says why) is ignored and counted.
- **Placed** (``RunwayStep.place``, for a preview and a goal alike): the motion starts no earlier than the
  claim window and ``publish_lead`` allow (``earliest``), then ``runway.schedule`` delays it by the least that
  keeps it ``runway_min_distance`` from every other's occupancy (``wait``), or refuses it naming the crane
  (``refuse``, or no delay helps): ``RunwayConflict``. A goal (not a preview) refused because of a crane that
  holds is placed again for up to a claim window first (``starting``): that crane may be sending a motion out
  of the way.
- **First published, first served**: between its claim and its trajectory's sending (at least the claim
  window), a goal is checked again (``RunwayStep.recheck``): if it conflicts with an occupancy published
  before its own (ties by crane name) or with a crane that holds, it is placed again, later, among all the
  others and published again (the same stamp). One published later is that crane's to avoid.

Pure Python, no ROS import: the node translates the messages and gives ``publish``.
"""
from __future__ import annotations

import dataclasses
import enum
import threading
from dataclasses import dataclass
from typing import Any, Callable

from crane_msgs_py.messages.names import HOIST_JOINT

from ..planning.continuation import problem_start
from ..planning.plan import Plan, PlanError
from ..runway.guard import PLAN_MARGIN
from ..runway.occupancy import Closest, Footprint, Occupancy, holding
from ..runway.prediction import plan_occupancy
from ..runway.schedule import Conflict, conflicts, schedule
from .config import Config
from .crane_view import HOLDING
from .moves import CheckedMove, model_at_rope, origin_of

#: The shortest claim window (s): a motion's occupancy is published at least this long (and at least
#: ``publish_lead``) before its trajectory is sent, so that another crane's planner hears it, and a crane that
#: published before it is heard, in time (DDS delivers within milliseconds on a LAN).
MIN_CLAIM_WINDOW = 0.1


class RunwayConflict(PlanError):
    """A goal that no start keeps clear of another crane, or refused by ``runway_policy``; ``crane`` names it,
    ``holding``: whether that crane's occupancy it was placed against was a hold."""

    def __init__(self, crane: str, message: str, holding: bool = False):
        super().__init__(f'runway: {message}')
        self.crane, self.holding = crane, holding


def claim_window(config: Config) -> float:
    """How long (s) a motion's occupancy is published before its trajectory is sent."""
    return max(config.publish_lead, MIN_CLAIM_WINDOW)


def precedes(other: Occupancy, mine: Occupancy) -> bool:
    """Whether ``other`` was published before ``mine`` (first published, first served; ties by crane name)."""
    return (other.published_ns, other.crane) < (mine.published_ns, mine.crane)


def is_hold(occupancy: Occupancy) -> bool:
    """Whether ``occupancy`` is a crane standing still (one sample): nothing its crane can move out of the way."""
    return len(occupancy.t) == 1


@dataclass(frozen=True)
class Placement:
    """A motion's place among the other cranes.

    Args:
        asked_ns: the start the goal asked for (ns; one as soon as possible: the earliest it could have).
        base: its occupancy started at the earliest allowed start (not before the claim window and
            ``publish_lead``, nor before ``asked_ns``), not published yet.
        delay: s from ``base``'s start to the motion's.
        waited_for: the crane it waits for ('' if none).
        closest: where it then comes closest to another crane (None: no other).
        published_ns: its claim's stamp (0: not claimed, a preview).
    """

    asked_ns: int
    base: Occupancy
    delay: float
    waited_for: str
    closest: Closest | None
    published_ns: int = 0

    @property
    def start_ns(self) -> int:
        """When the motion starts (ns, ROS time): its trajectory's stamp."""
        return self.base.start_ns + round(self.delay * 1e9)

    @property
    def runway_delay(self) -> float:
        """How much later (s) than asked the motion starts (PlanInfo's ``runway_delay``)."""
        return max(0.0, (self.start_ns - self.asked_ns) * 1e-9)

    @property
    def end_ns(self) -> int:
        """When its occupancy's last sample is reached (ns)."""
        return self.base.end_ns + round(self.delay * 1e9)

    @property
    def occupancy(self) -> Occupancy:
        """The occupancy as published: ``base`` delayed, with the claim's stamp."""
        return dataclasses.replace(self.base.delayed(self.delay), published_ns=self.published_ns)


class Neighbours:
    """The newest occupancy of every other crane by name, and the unusable ones ignored (count, last reason);
    thread-safe."""

    def __init__(self, me: Callable[[], str]):
        self._me = me
        self._lock = threading.Lock()
        self._latest: dict[str, Occupancy] = {}
        self.ignored, self.last_ignored = 0, ''

    def heard(self, occupancy: Occupancy) -> bool:
        """Keep ``occupancy`` as its crane's newest (False: this crane's own, not kept)."""
        if occupancy.crane == self._me():
            return False
        with self._lock:
            self._latest[occupancy.crane] = occupancy
        return True

    def ignore(self, reason: str) -> int:
        """Count an unusable occupancy (``reason``: why); the count so far."""
        with self._lock:
            self.ignored, self.last_ignored = self.ignored + 1, reason
            return self.ignored

    def others(self) -> list[Occupancy]:
        with self._lock:
            return list(self._latest.values())


class Published(enum.Enum):
    """What this crane last published on the runway."""

    NOTHING = 'nothing'  # nothing yet (the streamer's hold not known)
    HOLD = 'hold'  # where the streamer holds, no goal claimed
    CLAIMED = 'claimed'  # a goal's motion, its trajectory not sent yet (its claim window)
    SENT = 'sent'  # a goal's motion, sent: the crane moves (or will) as published
    RELEASED = 'released'  # the goal has ended: a hold is due once the streamer holds


P = Published
#: state -> the states it may change to (a new goal's claim replaces whatever was published; so does a motion
#: sent from a state: ``RunwayStep.moving``).
TRANSITIONS = {
    P.NOTHING: {P.HOLD, P.CLAIMED, P.SENT},
    P.HOLD: {P.HOLD, P.CLAIMED, P.SENT},
    P.CLAIMED: {P.CLAIMED, P.SENT, P.RELEASED},
    P.SENT: {P.CLAIMED, P.SENT, P.RELEASED},
    P.RELEASED: {P.HOLD, P.CLAIMED, P.SENT},
}


class IllegalTransition(RuntimeError):
    """What this crane publishes asked to change in a way ``TRANSITIONS`` does not allow."""


class RunwayStep:
    """This crane's occupancy and the others', for the goals (see the module docstring).

    Args:
        config: the node's current ``Config`` (``runway``: the runway parameters; off: nothing is done).
        clock: ROS time now (ns).
        publish: ``publish(Occupancy)`` on the runway (None: the node has no runway, nothing is done).
        book: the other cranes' occupancies as the node hears them (None: a book of its own).
    """

    def __init__(self, config: Callable[[], Config], clock: Callable[[], int],
                 publish: Callable[[Occupancy], Any] | None = None, book: Neighbours | None = None):
        self._config, self._clock, self._publish = config, clock, publish
        self.book = book if book is not None else Neighbours(lambda: self._config().runway.crane)
        self._lock = threading.Lock()  # what is published, and the publishing itself, in order
        self.state = P.NOTHING
        self._claim: tuple[Any, Placement] | None = None  # (goal key, its placement) while claimed or sent
        self._held: tuple | None = None  # the hold last published (cart, bridge), m
        self.last: Occupancy | None = None  # what it published last
        self._follows_last = False  # the crane moves (or stands) as ``last`` says: not a claim yet to be sent

    @property
    def on(self) -> bool:
        return self._publish is not None and self._config().runway.on

    def _out(self, occupancy: Occupancy, follows: bool = False) -> None:  # (under the lock)
        self.last, self._follows_last = occupancy, follows
        self._publish(occupancy)

    def _change(self, state: Published) -> None:
        if state not in TRANSITIONS[self.state]:
            raise IllegalTransition(f'runway: {self.state.value} -> {state.value}')
        self.state = state

    # -- placing a motion ---------------------------------------------------------------

    def place(self, checked: CheckedMove, plan: Plan, settle: float) -> Placement | None:
        """``plan`` (of ``checked``, observed ``settle`` s after it) placed among the other cranes (None: no
        runway); ``RunwayConflict`` names the crane in its way. Publishes nothing (a preview's too)."""
        if not self.on:
            return None
        config, now = self._config(), self._clock()
        r = config.runway
        earliest = now + round((claim_window(config) + config.publish_lead) * 1e9)
        asked = checked.start_ns or earliest
        base = plan_occupancy(r.crane, plan, model_at_rope(checked, config.params), origin_of(checked), r.offset,
                              max(asked, earliest), now, r.shape, settle)
        scheduled = self._scheduled(base, self.book.others())
        return Placement(asked, base, scheduled.delay, scheduled.waited_for, scheduled.closest)

    def _scheduled(self, base: Occupancy, others: list[Occupancy]):
        r = self._config().runway
        try:
            return schedule(base, others, r.min_distance, r.policy, margin=PLAN_MARGIN)
        except Conflict as exc:
            holds = any(o.crane == exc.crane and is_hold(o) for o in others)
            raise RunwayConflict(exc.crane, str(exc), holds) from None

    def claim(self, key, placement: Placement) -> Placement:
        """A goal's motion claimed: its occupancy published, stamped now (first published, first served)."""
        claimed = dataclasses.replace(placement, published_ns=self._clock())
        with self._lock:
            self._change(P.CLAIMED)
            self._claim = (key, claimed)
            self._out(claimed.occupancy)
        return claimed

    def recheck(self, key, placement: Placement) -> Placement | None:
        """During the claim window: None if ``placement`` (claimed) keeps clear of every occupancy published
        before it and every crane that holds; else placed again among all the others, no earlier than its
        trajectory can still be sent (``publish_lead`` from now), and published again with its stamp.
        ``RunwayConflict`` if no start keeps it clear (the claim stays until ``release``)."""
        config = self._config()
        mine, others = placement.occupancy, self.book.others()
        binding = [o for o in others if o.crane != mine.crane and (precedes(o, mine) or is_hold(o))]
        found = conflicts(mine, binding, config.runway.min_distance, PLAN_MARGIN)
        if not found:
            return None
        soonest = self._clock() + round(config.publish_lead * 1e9)
        shift = max(0, soonest - placement.base.start_ns) * 1e-9
        scheduled = self._scheduled(placement.base.delayed(shift), others)
        again = dataclasses.replace(placement, delay=shift + scheduled.delay, closest=scheduled.closest,
                                    waited_for=scheduled.waited_for or found[0].crane)
        with self._lock:
            if self._claim is None or self._claim[0] is not key:
                return again  # (a newer goal's claim replaced it: this one is being preempted)
            self._change(P.CLAIMED)
            self._claim = (key, again)
            self._out(again.occupancy)
        return again

    def moving(self, key, plan: Plan, state, handover_ns: int, settle: float) -> Occupancy | None:
        """A motion sent from a state (``state``: the ``continuation.MotionState`` at ``handover_ns``; ``plan``
        relative to it, observed ``settle`` s after): a goal during a motion, a goal from a swinging load, a
        cancel's stop, a settle. Its occupancy is published, stamped now, spliced after the motion or hold this
        crane published before (which it follows until the handover), as the motion of ``key`` (``release``).
        Not placed: a handover is due within its lead and cannot wait; the other cranes' planners plan around
        it, and the guards judge it against theirs. None (nothing published) without a runway."""
        if not self.on:
            return None
        config, now = self._config(), self._clock()
        r = config.runway
        start, model = problem_start(state, config.params)
        origin = {name: s.position for name, s in state.axes.items() if name != HOIST_JOINT}
        occupancy = plan_occupancy(r.crane, plan, model, origin, r.offset, handover_ns, now, r.shape, settle,
                                   start=start)
        with self._lock:
            if self.state is P.CLAIMED:  # (a settle while a goal waits to start: that goal's claim stands)
                return None
            if self.last is not None and self._follows_last and (self.state is not P.RELEASED
                                                                 or self.last.end_ns > now):
                occupancy = self.last.since(now).spliced(occupancy)  # (what the crane does until the handover)
            self._change(P.SENT)
            self._claim = (key, Placement(handover_ns, occupancy, 0.0, '', None, now))
            self._out(occupancy, follows=True)
        return occupancy

    def sent(self, key) -> None:
        """The claimed goal's trajectory was sent: the crane moves as published."""
        with self._lock:
            if self._claim is not None and self._claim[0] is key:
                self._change(P.SENT)
                self._follows_last = True

    def release(self, key) -> None:
        """The goal ``key`` ended: if its motion was the one published, a hold is published once the streamer
        holds (``on_stream_state``)."""
        with self._lock:
            if self._claim is not None and self._claim[0] is key:
                self._claim = None
                self._change(P.RELEASED)

    # -- holding ------------------------------------------------------------------------

    def on_stream_state(self, state: str, hold: dict) -> None:
        """The streamer's state: holding with no goal claimed, where it holds is published (once per place)."""
        if not self.on or state != HOLDING:
            return
        r = self._config().runway
        at = (float(hold.get('cart', 0.0)), float(hold.get('bridge', 0.0)))
        with self._lock:
            now = self._clock()
            if self.state is P.SENT and now >= self._claim[1].end_ns:  # (a motion no goal ends: a settle)
                self._claim = None
                self._change(P.RELEASED)
            if self.state in (P.CLAIMED, P.SENT) or (self.state is P.HOLD and self._held == at):
                return
            self._change(P.HOLD)
            self._held = at
            self._out(holding(r.crane, now, Footprint.at_rest(r.offset[1] + at[1], r.offset[0] + at[0]), r.shape),
                      follows=True)


def publish_motion(serving, key, plan: Plan, state, handover_ns: int, settle: float) -> None:
    """``serving.runway.moving`` of a motion already sent (``state``: the state at its handover, or a function
    that predicts it); should the prediction fail, a warning says so: the motion goes on unpublished (off its
    plan, the guards judge it by its stopping envelope), never the goal failed for it."""
    try:
        serving.runway.moving(key, plan, state() if callable(state) else state, handover_ns, settle)
    except (ValueError, ArithmeticError, RuntimeError) as exc:
        serving.log.warn(f'runway: the motion sent from a state is not published ({exc}); the other cranes\' '
                         'guards judge it by its stopping envelope')


def startup_conflict(config: Config, others: list[Occupancy], bridge: float, now_ns: int) -> str | None:
    """At start-up: why ``runway_offset`` is refused (one line naming both cranes), or None. This crane's
    girder (at ``runway_offset`` plus the bridge's position ``bridge``, m) must keep ``runway_min_distance``
    from where every other crane's girder stands now by its occupancy."""
    r = config.runway
    y = r.offset[1] + bridge
    for other in others:
        if other.crane == r.crane:
            continue
        theirs = float(other.at([now_ns]).girder[0])
        gap = abs(y - theirs) - r.shape.girder_half_width - other.shape.girder_half_width
        if gap < r.min_distance:
            return (f'runway_offset {list(r.offset)}: crane {r.crane!r}\'s girder at y {y:g} m would be '
                    f'{max(gap, 0.0):.3f} m from crane {other.crane!r}\'s at y {theirs:g} m, closer than '
                    f'runway_min_distance {r.min_distance:g} m: its girder cannot stand there')
    return None
