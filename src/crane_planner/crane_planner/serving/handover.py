"""When a handover is planned and sent: its lead, the slack it may arrive with, and the retries.

A goal during a motion, a stop and a settle each plan from the state the
running motion will be in at the handover, ``lead`` s from now. Planning
that takes longer than the lead (less the transport's share) is planned
again further ahead (``plan_handover``), and the next one of its kind starts
from a lead its recent planning times fit (``PlanningTimes``); a handover
the streamer did not take all the same (it came late on a busy host) is sent
again, further ahead: a multiple of the lead asked for or of the one its planning needed
(``HandoverPolicy``). An executed goal is held until ``publish_lead``
before its start (``send_at``); one whose start passed meanwhile streams
from the streamer's next tick (``streamed_origin``). Every time comes from
the clocks given, so the rules run on a fake clock in the tests. Pure Python, no ROS import.
"""
from __future__ import annotations

import threading
import time
from collections import deque
from dataclasses import dataclass
from enum import Enum
from typing import Any, Callable

from ..planning.continuation import MotionState
from ..planning.plan import Plan
from ..streaming.reference_stream import MAX_HANDOVER_SHIFT
from .execution import STREAM_TIMEOUT, Execution
from .moves import CheckedMove, MoveError
from .transitions import Running, Trajectory

#: A handover's trajectory must be sent at least this long (s) before the handover, for its transport to
#: the streamer and the streamer's check, which a busy machine delays; one that arrives late all the
#: same is refused by the streamer and planned again further ahead (``HandoverPolicy``).
TRANSPORT_MARGIN = 0.008
#: Attempts at a handover whose plan took longer than its lead (the lead at least doubles each time), and at
#: one the streamer did not take (``RETRY_LEAD_SCALE``, ``RETRY_PLANNED_SCALE``).
HANDOVER_ATTEMPTS = 3
#: How much further ahead a handover the streamer did not take is planned again: the further of this many
#: times the lead asked for and ``RETRY_PLANNED_SCALE`` times the lead it was planned with, which re-planning
#: lengthened if planning took longer (a retry shorter than what planning took then would be doomed).
RETRY_LEAD_SCALE = 4.0
RETRY_PLANNED_SCALE = 1.5
#: How many of the latest planning times of each kind of handover ``PlanningTimes`` keeps.
PLANNING_TIMES_KEPT = 5
#: A handover counts as not taken once the streamer's clock is this far (ns) past it without taking it.
NOT_TAKEN_AFTER_NS = 50_000_000


@dataclass(frozen=True)
class Handover:
    """A planned handover: the plan from ``state``, the running motion's state at ``handover_ns``, planned
    ``lead`` s ahead (longer than asked for if planning took longer)."""

    plan: Plan
    handover_ns: int
    state: MotionState
    lead: float


@dataclass(frozen=True)
class HandoverResult:
    """A goal's handover as planned (and sent): the move checked from the handover state, its plan, its
    trajectory, its status values (/diagnostics), the handover (ns), and the lead it was planned with over
    the lead asked for, before a late arrival shortened it (above 1 where re-planning had to lengthen it)."""

    checked: CheckedMove
    plan: Plan
    trajectory: Trajectory
    values: dict
    handover_ns: int
    lead_growth: float = 1.0
    state: Any = None  # the ``continuation.MotionState`` at the handover


@dataclass(frozen=True)
class Sent:
    """A handover sent, and the ``Execution`` that follows it (whether the streamer takes it)."""

    result: HandoverResult
    execution: Execution


class NotSent(Exception):
    """A goal's handover not sent: the goal gave way to a newer one, or was canceled, before it was sent, or
    while a handover the streamer did not take was to be sent again."""


def send_at(start_ns: int, publish_lead: float) -> int:
    """When a goal's trajectory starting at ``start_ns`` (0: as soon as possible) is sent: ``publish_lead``
    before its start, so a cancel before then streams nothing; at once (0) if it starts as soon as possible."""
    return start_ns - round(publish_lead * 1e9) if start_ns else 0


def streamed_origin(start_ns: int, now_ns: int) -> int:
    """The origin a trajectory starting at ``start_ns`` is sent with at ``now_ns``: its start, or 0 if that
    has passed (the goal came late, or planning outlasted its lead). Streamed whole from the streamer's next
    tick, like one as soon as possible, its origin comes from stream_state (``CraneView.origin``), and the
    streamer's time to start it counts from now, not from a start it could never have met."""
    return start_ns if start_ns > now_ns else 0


def arrival_lead(lead: float, arrived_ns: int | None, now_ns: int) -> float:
    """A handover's lead counted from the goal's arrival (``arrived_ns``), as if planned then; at least half
    the lead from now."""
    if arrived_ns is None:
        return lead
    return max(0.5 * lead, lead - (now_ns - arrived_ns) * 1e-9)


class PlanningTimes:
    """How long the latest handovers of each kind (any hashable: e.g. a stop of the cart and the bridge by
    NVF) took to plan, so that the next one of that kind is planned far enough ahead at its first attempt.

    A first lead shorter than planning takes only wastes a plan and the time it took: the spatial crane's
    NVF plans take several times the default ``handover_lead``. The lead ``lead`` gives is the one a retry
    would take after the slowest of the kind's ``kept`` latest plans (``plan_handover``). Thread-safe.
    """

    def __init__(self, kept: int = PLANNING_TIMES_KEPT):
        self._kept = kept
        self._times: dict = {}
        self._lock = threading.Lock()

    def record(self, kind, took: float) -> None:
        """A handover of ``kind`` took ``took`` s to plan (its state and its plan)."""
        with self._lock:
            self._times.setdefault(kind, deque(maxlen=self._kept)).append(took)

    def lead(self, kind, lead: float) -> float:
        """``lead`` (s), or longer where a recent plan of ``kind`` took longer than it leaves time for."""
        with self._lock:
            times = self._times.get(kind)
            return max(lead, _retry_lead(max(times))) if times else lead


def _retry_lead(took: float) -> float:
    """The lead (s) a plan that took ``took`` s needs next time: half as long again, and the transport."""
    return 1.5 * took + TRANSPORT_MARGIN


def plan_handover(clock: Callable[[], int], running: Running, lead: float,
                  make_plan: Callable[[int, MotionState], Plan], state_at: Callable[[int], MotionState],
                  rehearse: bool = False, timer: Callable[[], float] = time.perf_counter,
                  warn: Callable[[str], None] = lambda message: None,
                  attempts: int = HANDOVER_ATTEMPTS, times: PlanningTimes | None = None,
                  kind=None) -> Handover | None:
    """``make_plan(handover_ns, state)`` from the state ``running`` will be in ``lead`` s from now
    (``state_at(handover_ns)``), planned again further ahead if it took longer than that; None if the
    motion ends first. ``rehearse``: planned once, however long it took, for nothing to be sent.
    ``times``: where each plan's time is recorded under ``kind``, and whose recent times of that kind may
    lengthen the first lead. MoveError after ``attempts`` plans too slow for their lead."""
    if times is not None:
        lead = times.lead(kind, lead)
    tried = lead
    for _ in range(attempts):
        handover = max(clock() + round(lead * 1e9), running.origin_ns)
        if handover >= running.end_ns:
            return None
        t0 = timer()
        state = state_at(handover)
        t1 = timer()
        plan = make_plan(handover, state)
        took = timer() - t0
        if times is not None:
            times.record(kind, took)
        # the transport's share of the lead: TRANSPORT_MARGIN, or with a short lead (a shaper's) part of it.
        # A plan ending no earlier than the running motion (a new goal's) may even arrive late: the streamer
        # delays its change to its next tick, up to MAX_HANDOVER_SHIFT (half of it kept for the transport).
        # A handover arriving too late all the same is refused and planned again.
        slack = (0.5 * MAX_HANDOVER_SHIFT if handover + round(plan.duration * 1e9) >= running.end_ns
                 else -min(TRANSPORT_MARGIN, 0.4 * lead))
        if rehearse or clock() < handover + slack * 1e9:
            return Handover(plan, handover, state, lead)
        warn(f'handover: planning took {1e3 * took:.1f} ms (the state {1e3 * (t1 - t0):.1f} ms), beyond the '
             f'lead {1e3 * lead:.1f} ms: planning again further ahead')
        tried, lead = lead, max(2.0 * lead, _retry_lead(took))
    raise MoveError('duration', f'planning took longer than the handover lead {attempts} times '
                                f'(last lead {tried:.3f} s); raise handover_lead')


class Verdict(Enum):
    """What the streamer did with a handover sent (``taken``)."""

    TAKEN = 'taken'  # its stream_state streams the handover's motion
    REFUSED = 'refused'  # its clock passed the handover without streaming it (it came late)
    SILENT = 'silent'  # no stream_state came for a while: what it did is not known


def taken(execution: Execution, handover_ns: int, silence: float = STREAM_TIMEOUT,
          sleep: Callable[[float], None] = time.sleep, timer: Callable[[], float] = time.perf_counter) -> Verdict:
    """What the streamer did with the handover at ``handover_ns``, by its stream_state: wait until it streams
    the handover's motion, or until its clock is ``NOT_TAKEN_AFTER_NS`` past the handover without doing so.
    Judged by the streamer's clock, not this one's: a handover planned far ahead (a retry's) is taken only
    then, and a busy host delays the stream_state that says so. SILENT once no new stream_state has come for
    ``silence`` s."""
    heard, last = timer(), execution.stream_ns
    while True:
        if execution.motion_start_ns is not None:
            return Verdict.TAKEN
        stream_ns = execution.stream_ns
        if stream_ns is not None and stream_ns > handover_ns + NOT_TAKEN_AFTER_NS:
            return Verdict.REFUSED
        if stream_ns != last:
            heard, last = timer(), stream_ns
        elif timer() - heard >= silence:
            return Verdict.SILENT
        sleep(0.002)


class HandoverPolicy:
    """A goal's handover of a running motion, sent until the streamer takes it.

    Args:
        send: ``send(lead_scale, first) -> Sent``: plan the handover ``lead_scale``
            times the configured lead ahead (``first``: the first attempt, whose lead counts from the goal's
            arrival) and send it; ValueError says why it cannot be planned, ``NotSent`` that it may not be.
        sleep, timer: how ``taken`` waits.
        attempts: handovers sent before giving up.
        warn: told of each retry.
        silence: how long (s) the streamer's stream_state may be silent before what it did with a handover
            counts as unknown (the node's ``stream_timeout``).
    """

    def __init__(self, send: Callable[[float, bool], Sent],
                 sleep: Callable[[float], None] = time.sleep, timer: Callable[[], float] = time.perf_counter,
                 attempts: int = HANDOVER_ATTEMPTS, warn: Callable[[str], None] = lambda message: None,
                 silence: float = STREAM_TIMEOUT):
        self._send, self._sleep, self._timer = send, sleep, timer
        self.attempts, self._warn, self.silence = attempts, warn, silence

    def run(self, first: Sent | None = None,
            planned: Callable[[HandoverResult], Any] = lambda result: None,
            canceled: Callable[[], bool] = lambda: False) -> HandoverResult | None:
        """The handover the streamer took (None: it took none of ``attempts``). ``first``: the first one,
        already sent (on the goal's arrival); ``planned`` is told of the first one planned. A cancel
        (``canceled()``) before a handover is sent again raises NotSent: the streamer took none, the running
        motion goes on and nothing of the goal streams. ValueError if the streamer's stream_state falls
        silent meanwhile: whether it took the handover is not known, and sending another could not be judged
        either."""
        lead_scale = 1.0
        for attempt in range(self.attempts):
            if attempt and canceled():
                raise NotSent('canceled while its handover was to be sent again')
            sent = first if attempt == 0 and first is not None else self._send(lead_scale, attempt == 0)
            if attempt == 0:
                planned(sent.result)
            verdict = taken(sent.execution, sent.result.handover_ns, self.silence, self._sleep, self._timer)
            if verdict is Verdict.TAKEN:
                return sent.result
            if verdict is Verdict.SILENT:
                raise ValueError(f'no stream_state for {self.silence:g} s after the handover was sent: whether the '
                                 'streamer took it is not known (is it running?); nothing more is sent')
            lead_scale *= max(RETRY_LEAD_SCALE, RETRY_PLANNED_SCALE * sent.result.lead_growth)
            self._warn(f'execute_move: the streamer refused the handover (it came late): planning it '
                       f'again {lead_scale:g} times further ahead')
        return None
