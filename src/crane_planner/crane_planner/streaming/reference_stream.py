"""The streamer's motion rules: which trajectories become motions, and what each tick publishes.

The stream is a clock of ticks: tick k is due at ``epoch + k * period`` (ns
of ROS time) and publishes one sample (position, velocity, acceleration).
Between motions it publishes the hold position at rest, so the receiver
never sees a jump, and a trajectory is accepted as a ``Motion`` only if it
can be streamed without one:

- the stream must be running (not stopped, and started: ticks have an
  epoch to align the motion to);
- it must start within ``start_tolerance`` (m) of the hold position;
- it must not have ended already (a plan that came too late for all of it);
- while a motion streams (or is queued), only a *handover*: a trajectory
  whose start stamp falls within that motion, at a tick the loop has not
  reached, and whose first knot is that motion's state there (position
  within ``start_tolerance``, velocity and acceleration within
  ``HANDOVER_VELOCITY`` and ``HANDOVER_ACCELERATION``), replaces the rest of
  it from that tick on (contract "Motion from any state": a new goal or a
  stop mid-move). Anything else would be a jump, and is refused.
- a handover ending no earlier than the motion it replaces (a new goal) is
  streamed as that motion plus the handover's change to it, the change
  starting at the first tick at or after the stamp (``hermite.splice``:
  delayed by less than a tick), or, when it arrives after its stamp, at the
  tick after the one the loop had sampled when it arrived (made again a tick
  later should the loop sample past that meanwhile), up to
  ``MAX_HANDOVER_SHIFT`` late: continuous there, and by superposition still
  without swing on the linear crane. A handover ending earlier (a stop) starts at its stamp exactly and
  is refused if late: delayed, it would creep on until the old motion's end.

A motion starts at its start stamp plus its first knot's time (a zero stamp:
at once), from the first tick at or after that moment, and is sampled at
the tick times. A start the loop has already passed (the trajectory came
late) is shifted to the next tick the loop cannot have reached yet and
streamed whole: the receiver gets the planned motion late, never the rest of
it from the middle, which would be a jump.

A motion is sampled once, on acceptance, at every tick it will occupy
(quintic Hermite through the knots, ``hermite.QuinticHermite``), so the loop
calling ``sample`` a thousand times a second only looks samples up: it
allocates nothing beyond the returned ``source.Setpoint`` (at rest not even
that) and takes the lock only to take a motion over and to end one. The
last sample is the first tick at or past the motion's end (the end state);
after it the stream holds the end position.

Several joints (the cart and the hoist) stream in one motion: with a hold
of n positions every position, velocity and acceleration is a tuple of n,
in the hold's order; with one joint, a float.

Threads: ``accept``, ``stop`` and ``resume`` may run on one thread (the
node's executor) while ``start`` and ``sample`` run on another (the loop).
The stream is the trajectory mode's ``source.Source`` (the hold between
motions). Pure Python, no ROS import.
"""
from __future__ import annotations

import threading
from dataclasses import dataclass
from typing import Callable

import numpy as np

from .hermite import QuinticHermite, extends, splice
from .source import Setpoint

# The stream's states: stopped (~/stop; waits for resume), starting (resumed or
# never stopped, waits for the loop's start), running (ticks have an epoch).
STOPPED, STARTING, RUNNING = 'stopped', 'starting', 'running'

#: How far a handover's first knot may be from the running motion's state then: velocity (m/s) and
#: acceleration (m/s^2). The planner evaluates the same interpolant, so they agree to rounding.
HANDOVER_VELOCITY = 1e-6
HANDOVER_ACCELERATION = 1e-5
#: How far behind (s) the 1 kHz loop still sends every tick it missed, back to back, as it catches up after a
#: stall (the host paused it): a receiver that integrates the reference's acceleration (the sim, an axis
#: controller's feedforward) would otherwise end off the goal by what the missing samples carried, and keep the
#: velocity they changed. Further behind than a receiver's reference timeout (the sim's ``reference_timeout``),
#: the stream was judged lost and the axes braked: the loop skips ahead.
CATCH_UP = 1.0
#: Samples a new motion is queued with; the rest are taken right after, while its first ticks wait.
FIRST_SAMPLES = 50
#: How late (s) a handover may reach the stream and still be taken, its change delayed (``hermite.splice``).
#: Exact on the linear crane whatever the delay; bounded because the goal's timing moves with it.
MAX_HANDOVER_SHIFT = 0.02


@dataclass(frozen=True)
class Motion:
    """A trajectory sampled at the ticks it occupies: tick ``first_tick + i`` publishes sample i."""

    first_tick: int
    position: list      # m (per tick: a float, or a tuple per joint)
    velocity: list      # m/s
    acceleration: list  # m/s^2
    duration: float     # s
    late: float         # s the start was shifted: the trajectory came after its start stamp
    start_ns: int = 0   # ROS time (ns) of the first tick
    origin_ns: int = 0  # ROS time (ns) of the first knot (start_ns less the offset into the motion)
    interps: tuple = ()  # the knots' interpolants, one per joint (a handover is checked on them)
    handover: bool = False  # it replaces the running motion from its first tick
    ticks: int = 0  # samples in all (the lists hold its first ones until ``accept`` has sampled the rest)
    several: bool = False  # a tuple per tick (the stream's joints), not a float

    def state_at(self, time_ns: int) -> np.ndarray:
        """(position, velocity, acceleration) rows, a column per joint, of the motion at ROS time ``time_ns``."""
        t = self.interps[0].t[0] + (time_ns - self.origin_ns) * 1e-9
        return np.array([[x[0] for x in interp(t)] for interp in self.interps]).T

    def samples(self, begin: int, end: int, period_ns: int) -> tuple[list, list, list]:
        """Samples ``begin`` to ``end`` (excluded): positions, velocities, accelerations at those ticks."""
        times = self.interps[0].t[0] + (self.start_ns - self.origin_ns + period_ns * np.arange(begin, end)) * 1e-9
        if self.several:  # per tick a tuple per joint
            return tuple(list(zip(*(x.tolist() for x in col))) for col in zip(*(j(times) for j in self.interps)))
        return tuple(x.tolist() for x in self.interps[0](times))

    @property
    def end_position(self):
        """Where it ends (m; a tuple with several joints): its last sample, at or past the last knot."""
        if len(self.position) == self.ticks:
            return self.position[-1]
        ends = tuple(float(i.position[-1]) for i in self.interps)  # (held there past the knots)
        return ends if self.several else ends[0]

    @property
    def summary(self) -> str:
        return (f'{position_text(self.position[0])} -> {position_text(self.end_position)} m in {self.duration:.3f} s, '
                f'{self.ticks} ticks' + (f', started {self.late:.3f} s late' if self.late else ''))


def position_text(position) -> str:
    """A position (m) of one joint or of several, for messages."""
    if isinstance(position, tuple):
        return '(' + ', '.join(f'{x:.6g}' for x in position) + ')'
    return f'{position:.6g}'


class ReferenceStream:
    """The samples due at the stream's ticks: hold positions and accepted motions.

    Args:
        period_ns: tick period (ns), > 0.
        hold: hold position (m) before the first motion; a sequence of
            them streams as many joints.
        start_tolerance: largest distance (m) between a trajectory's first
            position and the hold position; may be changed at any time.
        stopped: start stopped (refusing trajectories until ``resume``).
    """

    def __init__(self, period_ns: int, hold: float = 0.0, start_tolerance: float = 1e-6, stopped: bool = False):
        if not period_ns > 0:
            raise ValueError(f'the tick period must be > 0 ns, got {period_ns}')
        self.period_ns = int(period_ns)
        self.start_tolerance = float(start_tolerance)
        self.joints = 1 if np.ndim(hold) == 0 else len(hold)
        hold = float(hold) if np.ndim(hold) == 0 else tuple(float(x) for x in hold)
        self._rest = (0.0,) * self.joints if isinstance(hold, tuple) else 0.0
        # The loop (sample) owns _hold and _motion; accept hands a motion over
        # through _incoming. The lock guards the hand-over and the state.
        self._lock = threading.Lock()
        self._hold = hold
        self._held = Setpoint(hold, self._rest, self._rest)  # the hold's setpoint, made again once it moves
        self._motion: Motion | None = None
        self._incoming: Motion | None = None
        self._last: Motion | None = None  # the streaming or the last streamed motion (the loop's)
        self._state = STOPPED if stopped else STARTING
        self._epoch_ns = 0  # ROS time (ns) of tick 0 while running
        self._tick: Callable[[], int] | None = None
        # The tick the loop sampled last, and the lock under which it is recorded with the hand-over it saw
        # (sample) or checked before one is handed over (_install): a few bytecodes on either side.
        self._last_tick = -1
        self._sampling = threading.Lock()
        #: Called with each motion accepted (on the accepting thread, once it is sampled whole): the runway
        #: guard tabulates where its stops may go (``runway_guard.RunwayGuard.accepted``).
        self.on_accept: Callable[[Motion], None] | None = None

    @property
    def hold(self):
        """The position (m) published last, or held before the first sample (a tuple per joint with several)."""
        return self._hold

    @property
    def streaming(self) -> bool:
        """Whether a motion is being streamed (taken over and not yet ended)."""
        return self._motion is not None

    @property
    def queued(self) -> bool:
        """Whether a motion (or a handover) is accepted and waits for its first tick."""
        return self._incoming is not None

    # -- as a ``source.Source`` ------------------------------------------------------

    @property
    def at_rest(self) -> bool:
        """No motion streaming nor queued: the stream holds."""
        return self._motion is None and self._incoming is None

    moving = streaming

    @property
    def position(self):
        """Where the stream has left the axes: the hold."""
        return self._hold

    def hold_at(self, position) -> None:
        """Hold ``position`` (m; a tuple with several joints, a float or a tuple of one with one) from now on:
        the axes were moved by something else (the operator mode); ValueError during a motion."""
        with self._lock:
            if self._motion is not None or self._incoming is not None:
                raise ValueError('a motion is streaming: the hold follows it')
            self._hold = (tuple(float(x) for x in position) if self.joints > 1 else
                          float(position[0] if isinstance(position, tuple) else position))

    @property
    def last_tick(self) -> int:
        """The tick the loop sampled last (-1 before its first since ``start``)."""
        return self._last_tick

    @property
    def last_motion(self) -> Motion | None:
        """The motion streaming now, else the last one streamed (None before the first)."""
        return self._last

    @property
    def running(self) -> bool:
        """Whether ticks have an epoch: started and not stopped since."""
        return self._state is RUNNING

    # -- the stream's state -----------------------------------------------------

    def start(self, epoch_ns: int, tick: Callable[[], int]) -> bool:
        """The loop's ticks begin: tick k is due at ``epoch_ns + k * period_ns`` (ROS time).

        ``tick`` returns the tick the loop is at (the one it samples next or
        is sampling); a motion is never given a first tick before ``tick() + 2``,
        which the loop cannot have passed. False, and nothing changes, if the
        stream was stopped meanwhile (a ``stop`` racing the loop's start).
        """
        with self._lock:
            if self._state is STOPPED:
                return False
            self._epoch_ns, self._tick, self._state = int(epoch_ns), tick, RUNNING
            self._last_tick = -1
            return True

    def stop(self) -> Motion | None:
        """Stop: refuse trajectories until ``resume``; drop the streaming and the queued motion.

        The hold stays at the last sample published, so the stream resumes
        there without a jump. Returns the motion that was streaming, if any.
        """
        with self._lock:
            dropped = self._motion
            self._motion = self._incoming = None
            self._state, self._tick = STOPPED, None
            return dropped

    def resume(self) -> None:
        """Undo ``stop``: trajectories are accepted again once the loop calls ``start``."""
        with self._lock:
            if self._state is STOPPED:
                self._state = STARTING

    # -- trajectories -------------------------------------------------------------

    def accept(self, t, position, velocity, acceleration, start_ns: int, now_ns: int,
               sampled: int | None = None) -> Motion:
        """Queue a trajectory as the next motion; ValueError says why not.

        Args:
            t: knot times (s), strictly increasing.
            position, velocity, acceleration: the knots' states (m, m/s, m/s^2),
                one column per joint with several, shape (len(t), joints).
            start_ns: the start stamp (ns of ROS time): knot time t is due at
                ``start_ns + t``; 0 starts the motion at once.
            now_ns: the time (ROS, ns) the trajectory arrived.
            sampled: the tick the loop had sampled last when it arrived (``last_tick`` then; default: now).
                A handover takes over at the tick after it, if made before the loop samples past that.
        """
        sampled = self._last_tick if sampled is None else sampled
        columns = [np.asarray(x, dtype=float) for x in (position, velocity, acceleration)]
        several = isinstance(self._hold, tuple)
        if several and any(c.ndim != 2 or c.shape[1] != self.joints for c in columns):
            raise ValueError(f'every knot needs {self.joints} positions, velocities and accelerations')
        if several:  # one interpolant per joint; ValueError: no points, not increasing, ...
            interps = [QuinticHermite(t, *(c[:, j] for c in columns)) for j in range(self.joints)]
        else:
            interps = [QuinticHermite(t, *columns)]
        t = interps[0].t
        p = np.array([i.position[0] for i in interps])
        duration_ns = round((t[-1] - t[0]) * 1e9)
        start_ns = start_ns + round(t[0] * 1e9) if start_ns else 0
        if start_ns and start_ns + duration_ns < now_ns:
            raise ValueError(f'it ended {(now_ns - start_ns - duration_ns) * 1e-9:.3f} s ago')
        period = self.period_ns
        with self._lock:
            if self._state is STOPPED:
                raise ValueError('the streamer is stopped (call ~/start)')
            if self._state is not RUNNING:
                raise ValueError('the stream has not started yet')
            if self._motion is not None or self._incoming is not None:
                motion = self._filled(self._handover(interps, start_ns, duration_ns, sampled))
            else:
                hold = np.atleast_1d(self._hold)
                if np.max(np.abs(p - hold)) > self.start_tolerance:
                    jump = p - hold
                    raise ValueError(f'it starts at {position_text(tuple(p) if several else p[0])} m, not at the hold '
                                     f'position {position_text(self._hold)} m (a jump of '
                                     f'{position_text(tuple(jump) if several else jump[0])} m)')
                epoch = self._epoch_ns
                first = self._tick() + 2  # a tick the loop cannot have reached yet
                offset = late = 0  # offset: time (ns) into the motion at the first tick
                if start_ns:
                    due = -(-(start_ns - epoch) // period)  # first tick at or after the start
                    if due >= first:
                        first, offset = due, epoch + due * period - start_ns
                    else:
                        late = epoch + first * period - start_ns
                self._incoming = self._sampled(interps, first, offset, duration_ns, late)
                motion = None
        # (told outside the lock: the loop takes the lock at a handover's first tick)
        return self._told(self._filled(self._incoming) if motion is None else motion)

    def _told(self, motion: Motion) -> Motion:
        if self.on_accept is not None:
            self.on_accept(motion)
        return motion

    def _sampled(self, interps, first: int, offset: int, duration_ns: int, late: int,
                 handover: bool = False) -> Motion:
        """The motion of ``interps`` from tick ``first``, ``offset`` ns into it then, to its end: its first
        ``FIRST_SAMPLES`` samples (``_filled`` adds the rest)."""
        period = self.period_ns
        n = max(0, -(-(duration_ns - offset) // period)) + 1  # the last sample at or past the end
        start = self._epoch_ns + first * period
        motion = Motion(first, [], [], [], duration_ns * 1e-9, late * 1e-9, start, start - offset, tuple(interps),
                        handover, n, isinstance(self._hold, tuple))
        for column, values in zip((motion.position, motion.velocity, motion.acceleration),
                                  motion.samples(0, min(n, FIRST_SAMPLES), period)):
            column.extend(values)
        return motion

    def _filled(self, motion: Motion) -> Motion:
        """``motion`` (queued: the loop may be streaming it already) with the rest of its samples, taken
        outside the lock; the loop evaluates a tick itself should it get there first."""
        rest = motion.samples(len(motion.position), motion.ticks, self.period_ns)
        for column, values in zip((motion.position, motion.velocity, motion.acceleration), rest):
            column.extend(values)  # (one list operation: the loop sees a sample whole or not at all)
        return motion

    def _handover(self, interps, start_ns: int, duration_ns: int, sampled: int) -> Motion:
        """A trajectory arriving during a motion: the rest of that motion replaced from ``start_ns`` on
        (see the module docstring); ValueError says why not. ``sampled``: the tick the loop had sampled last
        when it arrived. Called under the lock."""
        if not start_ns:
            raise ValueError('a motion is streaming: a trajectory during it must start at a time within it '
                             '(header stamp), where it continues the motion without a jump')
        period, epoch = self.period_ns, self._epoch_ns
        due = -(-(start_ns - epoch) // period)  # the first tick at or after the handover
        incoming = self._incoming
        # the motion that will be streaming at that tick: a queued one once it has started, else the current
        running = incoming if incoming is not None and due >= incoming.first_tick else self._motion
        if running is None:  # queued, not started by then: the new one would start before it
            raise ValueError('a motion is queued and starts after this trajectory would; it cannot be '
                             'handed over to')
        end_tick = running.first_tick + running.ticks - 1
        if not running.first_tick <= due < end_tick:
            into = (due - running.first_tick) * period * 1e-9
            raise ValueError(f'its start is outside the streaming motion ({into:.3f} s from its start, which lasts '
                             f'{running.duration:.3f} s)')
        here = running.state_at(start_ns)  # rows p, v, a; a column per joint
        new = np.array([[i.position[0] for i in interps], [i.velocity[0] for i in interps],
                        [i.acceleration[0] for i in interps]])
        gaps = np.max(np.abs(new - here), axis=1)
        tolerances = (self.start_tolerance, HANDOVER_VELOCITY, HANDOVER_ACCELERATION)
        for gap, tolerance, what, unit in zip(gaps, tolerances, ('position', 'velocity', 'acceleration'),
                                              ('m', 'm/s', 'm/s^2')):
            if gap > tolerance:
                raise ValueError(f'its first knot is not the streaming motion\'s state at its start: the {what} '
                                 f'differs by {gap:.3g} {unit} (> {tolerance:g}); a handover must continue the '
                                 'motion without a jump')
        delayable = extends(running.interps[0], running.origin_ns, interps[0], start_ns)
        while True:
            # The tick after the one the loop had sampled when the trajectory arrived will do, even should the
            # loop sample it before the hand-over, if the handover's first knot is on that tick (a spliced
            # handover, or a stop stamped on a tick): its first sample is the old motion's state there, so the
            # old motion is streamed there and the handover from its second sample on, on the same smooth
            # path. _install hands it over only if the loop has not sampled past it meanwhile, nor sampled the
            # first tick of one whose first knot lies between ticks; else it is made again from the loop's
            # next tick (a stop then comes too late, and is refused saying so).
            first = sampled + 1
            if not delayable:
                if due < first:
                    raise ValueError(f'it came {(first - due) * period * 1e-9:.3f} s too late for its handover '
                                     '(the stream is past its start), and it ends before the motion it replaces '
                                     'would have (a stop): it is not delayed')
                motion = self._sampled(interps, due, epoch + due * period - start_ns, duration_ns, 0, handover=True)
            else:
                at = max(due, first)
                shift = epoch + at * period - start_ns
                if shift > MAX_HANDOVER_SHIFT * 1e9:
                    raise ValueError(f'it came {shift * 1e-9:.3f} s too late for its handover (the stream is past '
                                     f'its start; at most {MAX_HANDOVER_SHIFT:g} s is made up by delaying its '
                                     'change)')
                if incoming is not None and due < incoming.first_tick <= at:
                    raise ValueError('a handover is queued where this one would start; it cannot be handed over to')
                joined = [splice(old, running.origin_ns, change, start_ns, epoch + at * period)
                          for old, change in zip(running.interps, interps)]
                motion = self._sampled(joined, at, 0, duration_ns, shift if at > due else 0, handover=True)
            if self._install(motion):
                return motion
            sampled = self._last_tick

    def _install(self, handover: Motion) -> bool:
        """Hand ``handover`` to the loop unless it has sampled past the handover's first tick meanwhile, or
        sampled that tick from the old motion and the handover's first sample is not the old motion's state
        there (its first knot between ticks: taken over a tick later, it would step by that fraction)."""
        with self._sampling:
            if self._last_tick > handover.first_tick or (self._last_tick == handover.first_tick
                                                         and handover.origin_ns != handover.start_ns):
                return False
            self._incoming = handover
            return True

    # -- the loop -------------------------------------------------------------------

    def sample(self, tick: int) -> Setpoint:
        """Position (m), velocity (m/s), acceleration (m/s^2) due at ``tick`` (tuples per joint with several).

        Takes the queued motion over at its first tick, ends a motion after
        its last sample and holds its end position at rest.
        """
        with self._sampling:
            self._last_tick = tick
            motion, incoming = self._motion, self._incoming
        if incoming is not None and tick >= incoming.first_tick:  # a new motion, or a handover
            with self._lock:
                if self._incoming is incoming:  # (else dropped by stop() or replaced meanwhile)
                    self._motion, self._incoming, self._last = incoming, None, incoming
                motion = self._motion
        if motion is None:
            if self._held.position is not self._hold:
                self._held = Setpoint(self._hold, self._rest, self._rest)
            return self._held
        i = tick - motion.first_tick
        if i < motion.ticks:
            if i >= len(motion.acceleration):  # not sampled yet (accept is filling it in): evaluated here
                sample = Setpoint(*(x[0] for x in motion.samples(i, i + 1, self.period_ns)))
                self._hold = sample.position
                return sample
            self._hold = motion.position[i]
            return Setpoint(motion.position[i], motion.velocity[i], motion.acceleration[i])
        with self._lock:
            self._hold = motion.end_position
            self._motion = None
        return Setpoint(self._hold, self._rest, self._rest)
