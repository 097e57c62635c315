"""The runway guard as a rule of the streamer's loop: each tick, this crane's stopping envelope against the other
cranes' (contract "Cranes sharing a runway"; the levels and envelopes are ``runway.guard``'s).

The executor hands in the other cranes' states as they arrive (``heard``:
their envelope and the time it came, into one realtime inbox the loop drains,
as the sway feedback's measurements) and the masses' offsets from the newest
``joint_states`` (``measured``). Each tick the loop's ``watch`` (a
``source.Watch``, after the source and its corrections) places this crane in
the runway frame: its girder where the bridge's published reference is (plus
``runway_offset``'s y; at the offset without a bridge joint), its masses by
their measured offsets from below the trolley, and its stopping envelope
widened by how far the stop it would run now travels:

- in operator mode the operator's own stop (the stick's command of the
  bridge held at zero: braked by ruckig within the bridge's operator limits,
  then played out by the shaper), exactly (``OperatorStream.stopping_travel``);
- in trajectory mode the planned stop (``serving.stops`` in the stop worker,
  ``PlannedStop``): the motion goes on as streamed for up to ``GUARD_LEAD``
  (and ``WAKE``), then an NVF stop to rest anywhere travels at most
  ``PlannedStop.stop`` (``STOP_REACH`` and its terms, measured), or the fallback
  braking ramp within ``fault_deceleration`` and ``fault_jerk``, whichever goes
  further: tabulated for each trajectory as the stream accepts it
  (``StopTable``, ``accepted``: ``ReferenceStream.on_accept``), looked up each
  tick; until a trajectory's table is there, extrapolated at constant
  acceleration (``PlannedStop.travel``).

The crane follows its plan (``follows_plan``, said on ``/runway/state``) while
trajectory mode streams its girder within ``PLANNED_TOLERANCE`` of where its
own newest occupancy on ``/runway/occupancy`` puts it now (``own``: the
planner's claim of the motion or its hold); between two such cranes the guard
judges their footprints (``runway.guard``).

Then ``runway.guard.Guard.check``. At ``STOP`` or ``LOST`` it stops what
moves the crane towards that crane and refuses motions towards it until the
way is clear: in operator mode the bridge's command towards it is held at zero
from the next tick (``OperatorStream.refuse``: the operator's own shaped stop,
without swing); in trajectory mode a motion whose bridge moves towards it is
stopped by ``GuardStops`` on a thread of its own: the planned stop without
swing if the stop worker has it taken over within ``GUARD_LEAD`` of the
decision (it is planned there, never in the loop), else the braking ramp
(``braking_stop``: it swings, and stops where the envelope said), and a
trajectory moving the bridge towards it is refused (``refusal``). Motions
away are taken. The streamer keeps streaming (it holds where the stop ends);
``reason`` says which crane and why, for ``stream_state`` (the goal's result)
until the next trajectory is taken.
Pure Python, no ROS import.
"""
from __future__ import annotations

import bisect
import math
import threading
import time
from collections import deque
from typing import Callable

import numpy as np

from crane_msgs_py.crane.braking import stopping_distance
from crane_msgs_py.messages.names import BRIDGE_JOINT, CART_JOINT

from ..planning.model import modal_frequencies
from ..runway.config import RunwayConfig
from ..runway.guard import Guard, Level, Reach, Verdict, envelope, within_reach
from .operator import OperatorStream
from .source import Setpoint, Source
from .stop_request import MotionStop

#: The planned stop's travel (trajectory mode) from a handover at velocity v and acceleration a is at most
#: ``STOP_REACH`` |v| T1 + ``STOP_REACH_ACCELERATION`` |a| T1^2 + ``STOP_REACH_SWING`` (T1 the first mode's
#: period). Measured over 1,225 stops of NVF, RVF, ZV, ZVD and EI motions (0.3-2 m in 2-5 s, peaks up to
#: 2.5 m/s^2) every 0.1 s from start to end: |v| T1 alone bounds it by 0.72 mid-motion, but not where the
#: acceleration is large beside the velocity (RVF's dips: 0.40 m from 0.08 m/s at 1.9 m/s^2, 2.8 times the
#: velocity's term) nor at the end of a motion that leaves a swing (EI: 10 mm with the axes all but at rest);
#: with 0.75 the acceleration's coefficient needed 0.06 and the swing's 12 mm, here with margin.
STOP_REACH = 0.75
STOP_REACH_ACCELERATION = 0.07
STOP_REACH_SWING = 0.015
#: The grid (ns) on which a trajectory's stop reach is tabulated (``StopTable``).
TABLE_STEP_NS = 10_000_000
#: How long (s) the guard's stop takes to be asked after the tick that decided it.
WAKE = 0.01
#: How far ahead (s) of that the guard's stop in trajectory mode takes over at the latest: the planned stop if
#: the stop worker answers in time (its lead, 0.1 s, or 1.5 times as long as its last stop took to plan: a
#: bridge travel's stop is solved on its vertical plane in 0.04-0.07 s on an idle 2-core host, a stop off one
#: plane on the coupled NLP in 0.2-1.3 s; the rest is room for a loaded host), else the braking ramp,
#: ``RAMP_MARGIN`` before it.
GUARD_LEAD = 0.4
RAMP_MARGIN = 0.03
#: How far (m) the streamed girder may be from where its own published occupancy puts it and still follow its
#: plan: the occupancy's linear interpolation between 20 ms samples (a fraction of a millimetre), with room for
#: a small correction of the sway feedback; a stop, a settle or a motion its planner did not place leaves it.
PLANNED_TOLERANCE = 0.002


class PlannedStop:
    """How far (m) trajectory mode's stop may travel (see the module docstring).

    Args:
        first_period: the first mode's period (s) of the streamer's crane model.
        deceleration, jerk: the fallback braking ramp's (``fault_deceleration``, ``fault_jerk``).
    """

    def __init__(self, first_period: float, deceleration: float, jerk: float):
        self.first_period, self.deceleration, self.jerk = first_period, deceleration, jerk

    def stop(self, v: float, a: float) -> float:
        """The signed travel of a stop taking over from a reference at ``v`` (m/s), ``a`` (m/s^2): the planned
        stop's bound (``STOP_REACH``...) or the braking ramp's distance, whichever goes further; 0 at rest (to
        rounding: a motion's end is at rest to 1e-17)."""
        if abs(v) < 1e-9 and abs(a) < 1e-9:
            return 0.0
        T1 = self.first_period
        planned = STOP_REACH * abs(v) * T1 + STOP_REACH_ACCELERATION * abs(a) * T1 * T1 + STOP_REACH_SWING
        ramp = abs(stopping_distance(v, a, self.deceleration, self.jerk))
        return math.copysign(max(planned, ramp), v if v else a)

    def travel(self, v: float, a: float, lead: float) -> float:
        """The signed travel from a reference at ``v`` (m/s), ``a`` (m/s^2) whose stop takes over ``lead`` s
        later, the motion going on meanwhile at that acceleration: the guard's estimate until the motion's
        ``StopTable`` is there (an extrapolation: a jerky motion goes further within the lead)."""
        return v * lead + a * lead * lead / 2.0 + self.stop(v + a * lead, a)

    def table(self, motion, joint: int, lead: float, step_ns: int = TABLE_STEP_NS) -> 'StopTable':
        """The ``StopTable`` of ``motion`` (a ``reference_stream.Motion``) for its joint ``joint`` (the
        bridge's column) with stops taking over up to ``lead`` s after each instant."""
        interp = motion.interps[joint]
        lead_ns = round(lead * 1e9)
        end_ns = motion.start_ns + round(motion.duration * 1e9)
        n = (end_ns + lead_ns - (motion.start_ns - lead_ns)) // step_ns + 3
        stamps = motion.start_ns - lead_ns + step_ns * np.arange(n, dtype=np.int64)
        # the motion's own time at those stamps (its interpolants hold their ends outside their knots)
        p, v, a = interp(motion.interps[0].t[0] + (stamps - motion.origin_ns) * 1e-9)
        reached = p + np.array([self.stop(vi, ai) for vi, ai in zip(v.tolist(), a.tolist(), strict=True)])
        w = lead_ns // step_ns + 2  # (the samples from each one to the first at or past it plus the lead)
        padded = np.concatenate((reached, np.full(w - 1, reached[-1])))
        windows = np.lib.stride_tricks.sliding_window_view(padded, w)
        return StopTable(motion, int(stamps[0]), step_ns, np.minimum(windows.min(axis=1), p),
                         np.maximum(windows.max(axis=1), p))


class StopTable:
    """Where a trajectory's stops may take the girder's reference (the joint's own positions, m): from the
    stamp ``start_ns + k step_ns``, a stop taking over at any instant within the guard's lead after it (the
    motion followed exactly until then, not extrapolated) ends between ``low[k]`` and ``high[k]``
    (``PlannedStop.stop`` of the reference's state at each instant on the grid). Held at its ends outside."""

    def __init__(self, motion, start_ns: int, step_ns: int, low: np.ndarray, high: np.ndarray):
        self.motion, self.start_ns, self.step_ns = motion, start_ns, step_ns
        self._low, self._high = low.tolist(), high.tolist()  # (lists: a tick reads two floats)
        self._last = len(self._low) - 2

    def at(self, stamp_ns: int) -> tuple[float, float]:
        """(lowest, highest) position (m) a stop may reach from ``stamp_ns`` (between two grid stamps: both)."""
        k = min(max((stamp_ns - self.start_ns) // self.step_ns, 0), self._last)
        low, high = self._low, self._high
        return min(low[k], low[k + 1]), max(high[k], high[k + 1])


def first_period(model) -> float:
    """The first mode's period (s) of the crane ``model`` (``planning.model``)."""
    return 2.0 * math.pi / modal_frequencies(model)[0]


class RunwayGuard:
    """The guard in the loop (see the module docstring).

    Args:
        config: the runway parameters.
        joints: the streamed joints (the bridge's column is the girder; without one the girder stands at the
            offset).
        period: the loop's tick (s).
        planned: trajectory mode's stop (``PlannedStop``).
        max_velocity, deceleration, jerk: the bridge's operator limits: how fast a crane is taken to travel and
            brake when judging whether a silent one is within reach (``runway.guard.within_reach``).
        wake: called (in the loop) when a motion towards a crane it stops for must be stopped.
    """

    def __init__(self, config: RunwayConfig, joints, period: float, planned: PlannedStop, max_velocity: float,
                 deceleration: float, jerk: float, wake: Callable[[], None] = lambda: None):
        joints = tuple(joints)
        self.crane, self.period, self.planned, self.wake = config.crane, period, planned, wake
        self.bridge = joints.index(BRIDGE_JOINT) if BRIDGE_JOINT in joints else None
        self.cart = joints.index(CART_JOINT)
        self.limits = (max_velocity, deceleration, jerk)
        self.guard = Guard(config.min_distance, config.timeout, 0.0)
        self.configure(config)
        self._inbox: deque = deque()
        self._measured = (0.0, 0.0, 0.0, 0.0)  # the hook's and the load's offsets (dx1, dy1, dx2, dy2), measured
        self._girder: float | None = None  # the girder's y in runway (m) as last measured (None: not yet)
        self._source: Source | None = None
        self._operator = False
        self.verdict: Verdict = Verdict(Level.CLEAR, '', math.inf, frozenset())
        self.mine = Reach(-math.inf, math.inf)
        self.footprint = Reach(-math.inf, math.inf)  # what it covers now, no travel
        self.follows_plan = False  # it follows its own published occupancy (``own``)
        self._own: tuple | None = None  # (start ns, sample times s, girder y m) of its newest occupancy
        self._tables: tuple = ()  # the two newest trajectories' StopTables (``accepted``): the one streaming, the next
        self.last = (0.0, 0.0, None)  # the girder's y and velocity, and the setpoint, at the last tick
        self.changes = 0  # verdicts that changed level, crane or refusal (the port reports each)
        self.stopping = False  # a stop of a motion towards a crane was asked, and the stream is not at rest yet
        self.reason = ''  # what the guard last stopped or refused, until a trajectory is taken
        self.ignored = 0  # states not taken (non-finite, another frame, this crane's own name)

    def configure(self, config: RunwayConfig) -> None:
        """The parameters that may change while running: the minimum distance, the timeout, the shape."""
        g = self.guard
        g.min_distance, g.timeout_ns = config.min_distance, round(config.timeout * 1e9)
        self.offset, self.shape, self.timeout = config.offset, config.shape, config.timeout
        lag = GUARD_LEAD + WAKE + STOP_REACH * self.planned.first_period  # (longer than any operator shaper's lag)
        max_velocity, deceleration, jerk = self.limits
        g.reach = within_reach(config.min_distance, max_velocity, config.timeout, deceleration, jerk, lag) if all(
            x > 0.0 for x in self.limits) else math.inf

    # -- the executor's side -----------------------------------------------------------------

    def heard(self, crane: str, low: float, high: float, now_ns: int, footprint: tuple | None = None,
              planned: bool = False) -> bool:
        """Another crane's state on the runway, received at ``now_ns`` (this crane's ROS time): its envelope, its
        footprint (low, high) and whether it follows its plan. False (counted in ``ignored``) if it is this crane's
        own or not finite."""
        if crane == self.crane or not (math.isfinite(low) and math.isfinite(high) and low <= high):
            self.ignored += 1
            return False
        if footprint is not None and not (all(math.isfinite(x) for x in footprint) and footprint[0] <= footprint[1]):
            footprint, planned = None, False
        self._inbox.append((crane, Reach(low, high), now_ns, None if footprint is None else Reach(*footprint),
                            bool(planned)))
        return True

    def own(self, start_ns: int, t, girder) -> None:
        """This crane's newest occupancy as its planner published it: its start (ns), sample times (s from it)
        and the girder's y (m, in ``runway``) at them; held at its last sample after."""
        self._own = (int(start_ns), tuple(float(x) for x in t), tuple(float(y) for y in girder))

    def _follows(self, stamp_ns: int, y: float) -> bool:
        """Whether the girder at ``y`` (m) at ``stamp_ns`` is where this crane's own occupancy puts it."""
        own = self._own
        if own is None:
            return False
        start, t, girder = own
        s = (stamp_ns - start) * 1e-9
        if s <= t[0] or len(t) == 1:
            planned = girder[0]
        elif s >= t[-1]:
            planned = girder[-1]
        else:
            k = bisect.bisect_right(t, s)
            w = (s - t[k - 1]) / (t[k] - t[k - 1])
            planned = girder[k - 1] + w * (girder[k] - girder[k - 1])
        return abs(y - planned) <= PLANNED_TOLERANCE

    def accepted(self, motion) -> None:
        """A trajectory the stream accepted (``ReferenceStream.on_accept``, on the accepting thread): its
        ``StopTable``, which the loop uses while that motion is the stream's. A failure leaves the loop's
        extrapolation (``PlannedStop.travel``)."""
        if self.bridge is None:
            return
        try:
            table = self.planned.table(motion, self.bridge, GUARD_LEAD + WAKE)
        except (ValueError, IndexError, ArithmeticError):
            return
        self._tables = (table, *self._tables[:1])

    def measured(self, hook: tuple, load: tuple, girder: float | None = None) -> None:
        """The masses' horizontal offsets (m) from the suspension point, (dx, dy) each, and the girder's y in
        ``runway`` (m; None: no bridge measured), from joint_states."""
        self._measured = (*hook, *load)
        self._girder = girder

    @property
    def masses(self) -> tuple:
        """(dx1, dy1, dx2, dy2): the newest measured offsets of the hook and the load."""
        return self._measured

    def refusal(self, position) -> str:
        """Why a trajectory (``position``: its knots' positions, a row per knot, a column per joint; one joint:
        1-D) is refused: it moves the bridge towards a crane the guard stops for; '' if it is taken."""
        blocked, b = self.verdict.blocked, self.bridge
        if blocked and b is not None:
            y = [row[b] for row in position]
            for direction in blocked:
                towards = max(direction * (p - y[0]) for p in y)
                if towards > 1e-9:
                    why = f'the runway guard refuses motions towards {self.describe(self.verdict)}: this one ' \
                          f'moves the bridge {towards:.3g} m towards it (away is taken)'
                    self.reason = why
                    return why
        self.reason = ''
        return ''

    # -- the loop -----------------------------------------------------------------------------

    def watch(self, stamp_ns: int, setpoint: Setpoint, source: Source) -> None:
        """This tick's check (``source.Watch``): the states heard taken, this crane's envelope from the
        published ``setpoint`` and how ``source`` would stop, the verdict acted upon."""
        inbox, guard = self._inbox, self.guard
        while inbox:
            guard.heard(*inbox.popleft())
        if source is not self._source:
            self._source, self._operator = source, isinstance(source, OperatorStream)
            self._refuse(self.verdict.blocked)
        b = self.bridge
        y0 = self.offset[1]
        behind = 0.0
        if b is None:
            y, v, travel = y0, 0.0, 0.0
        else:
            y, v, a = setpoint.position[b] + y0, setpoint.velocity[b], setpoint.acceleration[b]
            if self._operator:  # (the stick's zero taken from the next tick: one tick more)
                travel = source.stopping_travel(b) + v * self.period
            else:
                motion = getattr(source, 'last_motion', None)
                table = next((t for t in self._tables if t.motion is motion), None)
                if table is not None:
                    low, high = table.at(stamp_ns)
                    streamed = setpoint.position[b]
                    travel, behind = max(0.0, high - streamed), min(0.0, low - streamed)
                else:
                    travel = self.planned.travel(v, a, GUARD_LEAD + WAKE) if (v or a) else 0.0
        _, dy1, _, dy2 = self._measured
        mine = envelope(y, (y + dy1, y + dy2), self.shape, travel)
        if behind < 0.0:  # (a trajectory's stop that may go back as well)
            mine = Reach(mine.low + behind, mine.high)
        self.mine = mine
        # what it covers now, as measured: the axes follow their reference late (the servo, Eq. 6, and the
        # controller's playout), by a tenth of a second and centimetres at speed
        at = y if self._girder is None else self._girder
        footprint = self.footprint = envelope(at, (at + dy1, at + dy2), self.shape, 0.0)
        planned = self.follows_plan = not self._operator and not self.stopping and self._follows(stamp_ns, y)
        self.last = (y, v, setpoint)
        verdict = guard.check(mine, stamp_ns, footprint, planned)
        if verdict is not self.verdict:
            last, self.verdict = self.verdict, verdict
            if (verdict.level, verdict.crane, verdict.blocked) != (last.level, last.crane, last.blocked):
                self.changes += 1
                if verdict.blocked != last.blocked:
                    self._refuse(verdict.blocked)
        if self.stopping:  # (one stop at a time: its own braking moves towards the crane until it is at rest)
            if source.at_rest:
                self.stopping = False
        elif verdict.blocked and v and not self._operator and math.copysign(1.0, v) in verdict.blocked:
            self.stopping = True
            self.reason = f'the runway guard stopped it: {self.describe(verdict)}'
            self.wake()

    def _refuse(self, blocked) -> None:
        if self._operator and self.bridge is not None:
            self._source.refuse(self.bridge, blocked)

    # -- words --------------------------------------------------------------------------------

    def describe(self, verdict: Verdict) -> str:
        """The verdict in words: which crane, and why."""
        min_distance = self.guard.min_distance
        if verdict.level is Level.LOST:
            return (f'{verdict.crane}, not heard for runway_timeout {self.timeout:g} s within reach '
                    f'({verdict.gap:.3f} m)')
        if verdict.level is Level.STOP:
            return (f'{verdict.crane}, {verdict.gap:.3f} m between the stopping envelopes (runway_min_distance '
                    f'{min_distance:g} m; clear again at {2.0 * min_distance:g} m)')
        if verdict.level is Level.CLEAR:
            return 'no crane near'
        return f'{verdict.crane}, {verdict.gap:.3f} m between the stopping envelopes'


class GuardStops:
    """The guard's stops of a motion towards a crane (trajectory mode), run on a thread of their own: the loop
    wakes it; it asks the planned stop (``planned``: the stop worker's stop without swing taken over by the
    stream, on a helper thread) if the stop worker can have it in time (``ready``), and waits for it until
    ``GUARD_LEAD - RAMP_MARGIN`` after it woke; without it by then, the braking ramp (``ramp``) takes over. A
    planned stop answered later is refused by the stream (it no longer continues what streams) or, handed
    over before the ramp, replaces it. ``log(warning, text)`` says what it did; the loop asks no other until
    the stream is at rest.

    Args:
        guard: the loop's guard.
        planned, ramp: each stops the motion streaming now: its ``StopTrajectory`` (None: the motion ends
            first), or ValueError saying why not.
        ready: whether the stop worker can have a stop taken over within ``GUARD_LEAD``.
        log: ``log(warning: bool, text)``.
    """

    def __init__(self, guard: RunwayGuard, planned: Callable, ramp: Callable, ready: Callable[[], bool],
                 log: Callable[[bool, str], None], lead: float = GUARD_LEAD):
        self.guard, self.planned, self.ramp, self.ready, self.log, self.lead = guard, planned, ramp, ready, log, lead
        self._event = threading.Event()
        self._closed = False
        guard.wake = self._event.set
        self._thread = threading.Thread(target=self._run, name='runway-guard-stops', daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while True:
            self._event.wait()
            self._event.clear()
            if self._closed:
                return
            woken, why = time.monotonic(), self.guard.reason
            try:
                stopped = self._stop(woken)
                self.guard.reason = f'{why}: stopping {stopped.text()}'  # (how it stopped, for the goal's result)
                self.log(bool(stopped.warning), self.guard.reason)
            except ValueError as exc:  # (the motion ended meanwhile: at rest, the loop asks no more)
                self.log(False, f'{why}: nothing to stop ({exc})')
            except Exception as exc:  # (a bug: said, and the loop asks again)
                self.log(True, f'{why}: the stop failed: {exc!r}')
                self.guard.stopping = False

    def _stop(self, woken: float) -> MotionStop:
        """The planned stop if it is taken over in time, else the ramp (ValueError: nothing to stop)."""
        if not self.ready():
            late = 'the stop planner cannot have it in time'
        else:
            answer: list = []

            def ask():
                try:
                    answer.append(self.planned())
                except ValueError as exc:
                    answer.append(exc)
            helper = threading.Thread(target=ask, name='runway-guard-planned-stop', daemon=True)
            helper.start()
            helper.join(max(0.0, woken + self.lead - RAMP_MARGIN - time.monotonic()))
            if answer and not isinstance(answer[0], ValueError):
                return MotionStop(answer[0], 'without swing')
            late = str(answer[0]) if answer else f'no stop without swing within {self.lead:g} s'
        how = f'along the axes\' braking ramp ({late})'
        return MotionStop(self.ramp(), how, how)

    def close(self) -> None:
        self._closed = True
        self._event.set()
        self._thread.join(timeout=2.0)
