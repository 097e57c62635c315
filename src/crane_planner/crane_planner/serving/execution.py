"""Following one executed move: progress by the streamer's clock, swing from the measured angles.

An ``ExecuteMove`` goal's plan goes to the streamer, whose ``stream_state``
(a ``crane_interfaces/StreamState`` at 50 Hz) says which motion it streams
and at which tick; ``joint_states`` (50 Hz, stamped with the plant's time,
which lines up with the reference's stamps) give the swing angles.
``Execution`` takes both as plain numbers and tells the feedback (progress
0..1 of the plan's duration, time remaining, load excursion now) and, once
the settle window after the end has been observed, the residual swing: the
peak load excursion from ``joint_states`` stamped in the window, [end, end +
settle]. With a correction on the reference (the streamer's sway feedback,
in ``stream_state``) the window starts once the correction has settled back
to zero, the axes at the goal (``AT_GOAL``), and the largest correction is
kept (``correction``). Without ``joint_states`` the swing and the residual
are NaN and the window is timed by the streamer's clock. A ``stream_state``
silent for ``stream_timeout`` while the motion moves fails it: the stream
is lost, and a goal must not wait for it. The silence counts only while the
planner itself looks: of the time between two checks at most ``LOOK_GAP_NS``
counts (after a pause of the planner's own, the stream_state sent meanwhile
may still wait in its queue), so a dead stream is still found however seldom
the checks come. The axes' fault reaction (``axis_status``) during the
motion or its settle window fails it too once the motion has been streamed
to its end: a streamer that ended the motion before the axes held (it
streamed on through a gap they braked at) has nothing left to drop, and the
crane stands elsewhere than the goal. Pure Python, no ROS import.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from crane_msgs_py.crane.drive import FAULT_STATE_VALUES
from crane_msgs_py.crane.geometry import load_swing
from crane_msgs_py.messages.names import STREAM_STATE_TOPIC

#: ``axis_status`` states of the axes' fault reaction.

#: A streamer holding this long (ns) before the motion's end has dropped it (its last ticks are sampled at or
#: past the end: a stream_state just before it may say holding by a tick).
DROPPED_BEFORE_END_NS = 5_000_000

#: How long (s) stream_state may be silent while a motion moves before the stream counts as lost (the planner's
#: ``stream_timeout`` default): longer than the ticks a stalled streamer catches up on
#: (``streaming.reference_stream.CATCH_UP``), so a stall it makes up for is not a loss.
STREAM_TIMEOUT = 2.0
#: The most (ns) of the time between two checks of the phase (they come every ``following.FEEDBACK_PERIOD``)
#: that counts as silence: a longer gap is a pause of the planner's own.
LOOK_GAP_NS = 250_000_000
#: With a correction on the reference (the streamer's sway feedback), the settle window starts once the correction
#: is back within AT_GOAL (m) of zero and still (its speed since the previous stream_state at most STILL, m/s),
#: MAX_SETTLING s after the end at the latest: the goal ends when the axes are at its goal and the swing has
#: settled. Without a correction the reference holds the goal exactly from the end on.
AT_GOAL = 5e-4
STILL = 2.5e-4
MAX_SETTLING = 10.0
#: A correction this small (m) or smaller is none: the window starts at the motion's end.
CORRECTED = 1e-6
#: ``Execution.phase`` values.
WAITING, MOVING, SETTLING, DONE, FAILED = 'waiting', 'moving', 'settling', 'done', 'failed'


@dataclass
class Execution:
    """One executed plan, followed; fed from the node's callbacks (one thread at a time).

    Args:
        duration: the plan's duration (s).
        settle: seconds observed after the end for the residual, > 0.
        start_ns: the motion's start stamp (ns of ROS time) as sent, or the
            time it was sent when it starts as soon as possible.
        L1, L2: cable lengths (m) of the model, for the load excursion.
        start_timeout: how long (s, stream clock) past ``start_ns`` the
            streamer may take to start the motion before it counts as refused.
        late_joint_states: how long (s) past the window's end the node waits
            for the ``joint_states`` that close it (the sim stamps plant time,
            which runs its playout delay behind the clock).
        stream_timeout: how long (s) ``stream_state`` may be silent while the
            motion moves before the stream counts as lost: the streamer died or
            stopped, the axes run their fault reaction, and the goal fails
            saying so instead of waiting for a motion that no longer streams.
            Longer than the streamer's catch-up (``streaming.reference_stream.CATCH_UP``) by default:
            a stall it makes up for is not a loss.
    """

    duration: float
    settle: float
    start_ns: int
    L1: float
    L2: float
    start_timeout: float = 1.0
    late_joint_states: float = 1.0
    stream_timeout: float = STREAM_TIMEOUT

    def __post_init__(self):
        self.motion_start_ns: int | None = None  # the streamer's first tick of this motion
        self.motion_origin_ns: int | None = None  # when the streamer streams its first knot
        self.stream_ns: int | None = None  # the newest stream_state stamp
        self.stream_reason = ''  # the newest stream_state's reason: why the streamer stopped or refused a motion
        self.swing = math.nan  # m, the newest load excursion
        self._state_ns: int | None = None  # the newest joint_states stamp
        self._failure = ''
        self.cut_ns: int | None = None  # a next motion's start: the settle window ends there at the latest
        self._looked_ns: int | None = None  # the newest phase check's time since the newest stream_state
        self._silent_ns = 0  # the silence of stream_state looked at since then
        self._axis_fault = ''  # the axes' fault reaction heard during the motion or its settle window
        self.correction = 0.0  # m: the largest |correction| of the streamer's sway feedback heard, over the joints
        self.settled_ns: int | None = None  # when the correction came to rest at zero after the end
        self._last_correction: dict | None = None
        self._last_ns = 0
        self._swings: list = []  # (stamp ns, |load excursion| m) of joint_states past the end

    # -- inputs -------------------------------------------------------------------

    def on_stream_state(self, stamp_ns: int, motion_start_ns: int, motion_duration: float,
                        motion_origin_ns: int | None = None, streaming: bool = True,
                        correction: dict | None = None, reason: str = '') -> None:
        """A ``stream_state``: its tick's stamp and the current (or last) motion's start, duration and origin
        (when its first knot is streamed; default its start), and whether it streams a motion: one that holds
        before this motion's end has dropped it (its ~/stop, its runway guard, or the axes' fault reaction);
        ``correction``: what its sway feedback added to the reference then, by joint (m); ``reason``: why the
        streamer itself stopped or refused the newest motion (its runway guard, naming the crane)."""
        if self.stream_ns is None or stamp_ns > self.stream_ns:  # the silence counts from the next check
            self._silent_ns, self._looked_ns = 0, None
        self.stream_ns = stamp_ns
        self.stream_reason = reason
        end = self.end_ns
        if end is not None and not streaming and stamp_ns < end - DROPPED_BEFORE_END_NS and not self._failure:
            self._failure = (f'the streamer stopped streaming the motion at {100 * self.progress:.0f} %: it holds ('
                             + (reason or 'a ~/stop, or the axes braked to rest by their fault reaction: see its log')
                             + ')')
        if (self.motion_start_ns is None and motion_start_ns >= self.start_ns - 1_000_000
                and abs(motion_duration - self.duration) < 1e-6):
            self.motion_start_ns = motion_start_ns  # ours: started at or after its start, as long as planned
            self.motion_origin_ns = motion_start_ns if motion_origin_ns is None else motion_origin_ns
        if correction and self.motion_start_ns is not None and stamp_ns >= self.motion_start_ns:
            self._corrected(stamp_ns, correction)

    def _corrected(self, stamp_ns: int, correction: dict) -> None:
        """The sway feedback's correction at ``stamp_ns`` (kept at its largest), and past the end whether it has
        settled: within ``AT_GOAL`` and slower than ``STILL``, and staying within ``AT_GOAL`` over the window
        (else the window starts again once it has settled again)."""
        largest = max(abs(c) for c in correction.values())
        self.correction = max(self.correction, largest)
        last, span = self._last_correction, (stamp_ns - self._last_ns) * 1e-9 if self._last_ns else 0.0
        if self.settled_ns is not None and largest > AT_GOAL and stamp_ns <= self.window_end_ns:
            self.settled_ns = None  # it left the goal during the window: the axes are not there yet
        if self.settled_ns is None and stamp_ns >= self.end_ns and largest <= AT_GOAL:
            if largest == 0.0 or (last is not None and span > 0.0 and all(
                    abs(c - last.get(name, math.inf)) <= STILL * span for name, c in correction.items())):
                self.settled_ns = stamp_ns
        self._last_correction, self._last_ns = dict(correction), stamp_ns

    def on_joint_state(self, stamp_ns: int, theta1: float, theta2: float, L1: float | None = None,
                       phi: tuple[float, float] | None = None) -> None:
        """A ``joint_states`` sample (plant time): the swing now, and the residual once past the end
        (``L1``: the rope length measured with it, with a hoist; else the model's; ``phi``: (phi1, phi2) of a
        crane with a bridge, whose swing is the norm of the load's horizontal offset)."""
        self.swing = float(load_swing(theta1, theta2, self.L1 if L1 is None else L1, self.L2, *(phi or ())))
        self._state_ns = stamp_ns
        end = self.end_ns
        if end is not None and stamp_ns >= end:
            self._swings.append((stamp_ns, abs(self.swing)))

    def on_axis_status(self, stamp_ns: int, state: str, message: str) -> None:
        """An ``axis_status`` (stamped with the plant's time, which lines up with the reference's stamps): a
        fault reaction from the motion's start to its settle window's end is kept, to fail the goal once the
        motion has been streamed (``phase``; while it streams, the streamer drops it on the axes' hold)."""
        end = self.window_end_ns
        if state in FAULT_STATE_VALUES and end is not None and self.motion_start_ns <= stamp_ns <= end:
            self._axis_fault = self._axis_fault or message

    # -- what the goal reports -------------------------------------------------------

    @property
    def end_ns(self) -> int | None:
        """The motion's end on the streamer's clock, once it has started."""
        if self.motion_start_ns is None:
            return None
        return self.motion_start_ns + round(self.duration * 1e9)

    @property
    def window_start_ns(self) -> int | None:
        """The settle window's start: the motion's end, or with a correction on the reference (``AT_GOAL``) once
        it has settled at the goal; None while it is not known yet."""
        end = self.end_ns
        if end is None or self.correction <= CORRECTED:
            return end
        if self.settled_ns is not None:
            return self.settled_ns
        latest = end + round(MAX_SETTLING * 1e9)
        if self.cut_ns is not None and self.cut_ns <= latest:
            return self.cut_ns
        return latest if (self.stream_ns or 0) >= latest else None

    @property
    def window_end_ns(self) -> int | None:
        """The settle window's end: ``settle`` after its start, or a next motion's start if earlier (at the
        latest ``settle`` after the latest start it may have, while that is not known)."""
        end = self.end_ns
        if end is None:
            return None
        start = self.window_start_ns
        window_end = (start if start is not None else end + round(MAX_SETTLING * 1e9)) + round(self.settle * 1e9)
        return window_end if self.cut_ns is None else max(end, min(window_end, self.cut_ns))

    def cut(self, next_start_ns: int) -> None:
        """A next motion starts at ``next_start_ns``: the settle window ends there at the latest."""
        self.cut_ns = next_start_ns if self.cut_ns is None else min(self.cut_ns, next_start_ns)

    @property
    def progress(self) -> float:
        """0..1 of the plan's duration, by the streamer's clock."""
        if self.motion_start_ns is None or self.stream_ns is None:
            return 0.0
        return min(max((self.stream_ns - self.motion_start_ns) * 1e-9 / self.duration, 0.0), 1.0)

    @property
    def time_remaining(self) -> float:
        """Seconds of the motion still to stream (the settle window not counted)."""
        return (1.0 - self.progress) * self.duration

    @property
    def residual(self) -> float:
        """Peak |load excursion| (m) over the settle window so far; NaN without joint_states in it."""
        start, end = self.window_start_ns, self.window_end_ns
        if start is None:
            return math.nan
        inside = [x for stamp, x in self._swings if start <= stamp <= end]
        return max(inside) if inside else math.nan

    @property
    def failure(self) -> str:
        return self._failure

    @property
    def in_motion(self) -> bool:
        """Whether the motion is still to start or streams (not failed), by what was heard: no clock read."""
        return not self._failure and (self.motion_start_ns is None or self.progress < 1.0)

    def phase(self, now_ns: int) -> str:
        """Where the execution is, checked at ROS time ``now_ns`` (for the timeouts; the checks count the
        stream's silence, ``LOOK_GAP_NS``)."""
        if self._looked_ns is not None and now_ns > self._looked_ns:
            self._silent_ns += min(now_ns - self._looked_ns, LOOK_GAP_NS)
        self._looked_ns = now_ns if self._looked_ns is None else max(self._looked_ns, now_ns)
        if self._failure:
            return FAILED
        clock = max(now_ns, self.stream_ns or 0)
        if self.motion_start_ns is None:
            if clock > self.start_ns + round(self.start_timeout * 1e9):
                self._failure = ('the streamer did not stream the motion within '
                                 f'{self.start_timeout:g} s of its start'
                                 + (' (no stream_state: is the streamer running?)' if self.stream_ns is None else
                                    f' (refused: {self.stream_reason})' if self.stream_reason else
                                    ' (refused: see its /diagnostics, e.g. not at the hold position or busy)'))
                return FAILED
            return WAITING
        if self.progress < 1.0:
            if self._silent_ns > round(self.stream_timeout * 1e9):
                self._failure = (f'lost the reference stream at {100 * self.progress:.0f} % of the motion: no '
                                 f'{STREAM_STATE_TOPIC} for {(now_ns - self.stream_ns) * 1e-9:.1f} s (the streamer '
                                 'stopped or died; the axes brake to rest by their fault reaction, the next goal '
                                 'starts where they stand)')
                return FAILED
            return MOVING
        if self._axis_fault:
            self._failure = f'the axes ran their fault reaction ({self._axis_fault}): they stand where they braked'
            return FAILED
        if self.window_start_ns is None:  # the reference still corrected: the axes not yet at the goal
            return SETTLING
        window_end = self.window_end_ns
        if self._state_ns is not None and self._state_ns >= window_end:
            return DONE
        timeout = window_end + (round(self.late_joint_states * 1e9) if self._state_ns is not None else 0)
        return DONE if clock >= timeout else SETTLING
