"""Time-stamped references played out at a fixed delay: the simulator's jitter buffer.

References arrive with their stamps (the streamer's tick times) but at
uneven moments: transport latency, jitter and the receiving process's own
scheduling hiccups delay some and bunch others. Applying the newest on
arrival would hold a stale value through a hiccup and then skip the bunched
ones, so the integrated velocity drifts by jerk * hiccup^2 / 2. Instead each
step of the plant at time t uses the reference *as stamped* at t - delay:
every sample counts for exactly its own interval, whatever the arrival
pattern, as long as it arrives within ``delay``.

Per step ``[t0, t1]`` the acceleration is the newest stamped <= t0 - delay
(``zoh``), or interpolated between the samples bracketing t0 - delay and
t1 - delay (``linear``). Once the playout time has passed the newest sample
by more than ``DRY`` of the samples' spacing, the buffer has run dry: the
acceleration is 0, so the axis holds its velocity and never runs ahead of
its reference on an acceleration nobody sent (a drive given no new setpoint
does not extrapolate one). Without a sample newer than ``timeout`` the
stream counts as stopped and ``timeouts`` counts it; the sim node's axis
controller (``axis_controller``) then brakes the reference to rest.

An acceleration sample later than that comes after steps that needed it and
held an older one instead. Nothing would ever make up their deficit: the
reference velocity and position would stay off for good. So once it is
known, those steps are worked out again as they would have run with it on
time, and the difference (on time minus applied, the reference velocity e_v
and position e_p now) is corrected deadbeat: each of the next two steps gets
c = e_p / h^2 + 1.5 e_v / h added to both ends of its ramp, which zeroes both
errors on the plant's even grid of steps h. A step is final once a sample
stamped at or after its last playout time is known. A timeout declares the
stream dead: steps that fell back to 0 or are older than ``timeout``, and
samples arriving more than ``timeout`` behind the playout, are not made up.
With every sample on time the output is the same, bit for bit.

With ``source='position'`` (a controller that only gets positions) the
positions are played out the same way and the step's acceleration is the
second difference of the played-out position over the plant's own last
steps. On the plant's even grid these sum exactly: the reference velocity is
always the last step's position difference over h, so the cart ends at rest
at the last position whatever the stamps' spacing (gaps, a re-anchored
grid) or the samples' lateness. Second differences of the samples themselves
held over the next, different interval would leave a velocity error for
good. Without a fresh sample the last position holds, as an axis holds its
last setpoint, and the acceleration falls to 0 by itself. On an even grid of
samples aligned with the steps both forms are the same: the second
difference around the previous sample, applied from the newest one on.
Times are seconds on any common clock. Pure Python, no ROS import.
"""
from __future__ import annotations

import math
from collections import deque

from crane_msgs_py.crane.params import check_choice

from .simulator import INTERPOLATIONS, SOURCES, SimulationError


def _interpolate(before: tuple, after: tuple, tau: float) -> float:
    """The value at ``tau`` on the line through the samples (t, value) ``before`` and ``after``."""
    (t0, a0), (t1, a1) = before, after
    return a0 + (a1 - a0) * (tau - t0) / (t1 - t0)


#: Samples missing between two consecutive ones (a sender that skipped ticks, samples the receive queue
#: dropped, samples that came after their playout time and were made up): the steps in the gap played the
#: last acceleration held, and the reference integrated from it keeps that error, in velocity and then
#: position, for ever. A gap longer than this (s) while the reference moves always loses the stream.
MAX_GAP = 0.25
#: A shorter gap loses it if holding the acceleration across it errs by more than this in velocity (m/s):
#: |a_after - a_before| * gap / 2, the acceleration taken as changing linearly across the gap. Holding is
#: exact where it does not change (at rest, cruising, a constant acceleration).
MAX_VELOCITY_ERROR = 0.005


def moved_across_gap(before: tuple, after: tuple, max_gap: float = MAX_GAP,
                     max_velocity_error: float = MAX_VELOCITY_ERROR) -> bool:
    """Whether the samples missing between consecutive samples ``before``, ``after`` (stamp s, then position
    and acceleration per axis) leave the reference played across them off: while it moves (a position
    changed across the gap, or an acceleration on either side is not 0), a gap over ``max_gap``, or one
    across which holding an axis's acceleration errs by over ``max_velocity_error`` in velocity. Across a gap
    while the reference holds, nothing was missed."""
    gap = after[0] - before[0]
    if gap <= max_gap:  # (every sample at 1 kHz: the cheap test; an acceleration that changed means it moves)
        return max(abs(a1 - a0) for a0, a1 in zip(before[2::2], after[2::2])) * gap / 2.0 > max_velocity_error
    return (any(p0 != p1 for p0, p1 in zip(before[1::2], after[1::2]))
            or any(a != 0.0 for a in (*before[2::2], *after[2::2])))


#: How far (in the spacing of its last two samples) the playout time may pass the newest sample before the
#: buffer counts as dry and the acceleration as 0: one sample late is jitter, and holding its acceleration the
#: better guess (what it turns out to be is made up); past that, the stream has gaps or has stopped.
DRY = 1.5

#: How late (s) a step of the plant's loop must be to count as a stall of its process (``StallAllowance``).
STALL = 0.1
#: How long (s) after a stall of its own the loop waits for the stall's backlog (the samples sent while it stood
#: still, queued in the middleware and its executor) before a silence counts again: the receiving side's
#: catching up, not the drive's watchdog, so not ``reference_timeout``.
BACKLOG = 1.0


class StallAllowance:
    """How late (s) a step of the plant's loop counts as its own stall (``ReferencePlayout.behind``).

    Its lateness now, or, for ``hold`` seconds of the clock after a stall, that stall's length: the samples
    sent while the process stood still (SIGSTOP, a host pause) reach its executor only after it, a
    backlog it works through while the loop has long caught up, so their gap is forgiven until the
    executor has had ``hold`` (``BACKLOG``) to deliver them. A stream that stops within
    ``hold`` of a stall is judged lost that much later, never not at all.
    """

    def __init__(self, hold: float):
        self.hold = float(hold)
        self._stall, self._until = 0.0, -math.inf

    def __call__(self, late: float, now: float) -> float:
        """The allowance for a step ``late`` s after its deadline, at ``now`` (s, the clock of ``hold``): a
        lateness under ``STALL`` is the loop's jitter, allowed for its own step only (held, it would delay
        the judgement of a stream lost just after it)."""
        if now > self._until:
            self._stall = 0.0
        if late >= STALL and late > self._stall:
            self._stall, self._until = float(late), now + self.hold
        return max(self._stall, late)


class ReferencePlayout:
    """Accelerations for consecutive plant steps from stamped references.

    Args:
        delay: playout delay (s), >= 0.
        timeout: age (s) beyond which the newest sample no longer counts, > 0.
        interpolation: ``zoh`` or ``linear``.
        source: ``acceleration`` (use each sample's acceleration) or ``position``.
        period: the samples' expected spacing (s), for the first sample's ``DRY`` (later: their own).

    ``timeouts`` counts the times the reference fell back to 0 after having had samples; ``made_up`` the
    times samples came too late for steps already played and their difference was made up, ``made_up_late``
    the largest such lateness (s past the playout time): the reference ends right, the swing those steps
    caused stays (a longer ``delay`` avoids it).
    """

    def __init__(self, delay: float, timeout: float, interpolation: str = 'zoh', source: str = 'acceleration',
                 period: float = 1e-3):
        check_choice('interpolation', interpolation, INTERPOLATIONS, SimulationError)
        check_choice('source', source, SOURCES, SimulationError)
        if not (delay >= 0.0 and timeout > 0.0):
            raise SimulationError(f'need delay >= 0 and timeout > 0, got {delay}, {timeout}')
        self.delay, self.timeout = float(delay), float(timeout)
        self.interpolation, self.source = interpolation, source
        self.period = float(period)  # the samples' spacing until two have come (``DRY``)
        self.timeouts = self.made_up = 0
        self.made_up_late = 0.0
        self.reset()

    def reset(self):
        """Forget every sample (the next position sample starts a motion from rest), and any error to make up."""
        self._queue: deque = deque()   # (t, value) not yet reached by the playout time
        self._last = -math.inf         # stamp of the last sample pushed
        self._current = None           # (t, value): the newest sample at or before the playout time
        self._dry = 0.0                # how far (s) past _current the playout runs dry if nothing newer is known
        self._live = False             # whether _current is recent enough to count
        self._behind = 0.0             # how late (s) the plant's loop runs this step (``behind``)
        self._played: list[float] = []  # position source: positions played out at the last two steps
        # acceleration source, samples later than the delay:
        # (end, h, tau0, tau1, behind) of the last steps, which a later sample could still change: plant time (s)
        # at the step's end counted over them, its length (s), its first and last playout times (s), and how
        # late the loop ran then (s: it moves where the buffer counts as dry)
        self._pending: deque = deque()
        self._ev = self._ep = 0.0       # reference velocity (m/s), position (m) still to make up: on time - applied
        self._settling = 0              # steps of the deadbeat correction of _ev, _ep still to come: 2 or less

    def push(self, t: float, position: float, acceleration: float):
        """A sample stamped ``t`` (after the previous one's stamp)."""
        if not t > self._last:
            raise SimulationError(f'reference stamps must increase: {t} after {self._last}')
        self._last = float(t)
        self._queue.append((float(t), float(position if self.source == 'position' else acceleration)))

    def behind(self, late: float):
        """The plant's loop runs this step ``late`` s after its time (it stalled: the host paused it, and it
        catches up): samples sent up to then may not have reached it yet, so the newest sample's age counts
        only beyond that. A stream is judged lost over time the simulator was there to receive it, not over
        its own stall. Set before each step (0: on time)."""
        self._behind = max(0.0, float(late))

    def _advance(self, tau: float):
        queue = self._queue
        while queue and queue[0][0] <= tau:
            previous, self._current = self._current, queue.popleft()
            self._dry = DRY * (self._current[0] - previous[0] if previous is not None else self.period)
        live = self._current is not None and tau - self._current[0] <= self.timeout + self._behind
        if self._live and not live:
            self.timeouts += 1
        self._live = live

    def _at(self, tau: float) -> float:
        """The played-out value at ``tau``: an acceleration (0 once stale), or a position (held)."""
        self._advance(tau)
        if self._current is None or not (self._live or self.source == 'position'):
            return 0.0
        t0, a0 = self._current
        if self._queue:
            if self.interpolation == 'linear':  # _interpolate, inline: this runs twice a step
                t1, a1 = self._queue[0]
                return a0 + (a1 - a0) * (tau - t0) / (t1 - t0)
        elif tau - t0 > self._dry + self._behind and self.source == 'acceleration':  # dry: the velocity holds
            return 0.0
        return a0

    def step(self, t0: float, t1: float) -> tuple[float, float]:
        """Reference acceleration at the beginning and the end of the plant step [t0, t1] (with any correction)."""
        if self.source == 'position':
            return (self._position_step(t0, t1),) * 2
        tau0 = t0 - self.delay
        if self._pending:  # steps ran ahead of the samples: make up what the new ones change
            self._revise(tau0)
        a0 = self._at(tau0)
        if self.interpolation == 'zoh':
            a1, tau1 = a0, tau0
        else:
            tau1 = t1 - self.delay
            a1 = self._at(tau1)
        if tau1 > self._last and (self._live or self._current is None):  # ahead of the samples, live or before any
            pending, h = self._pending, t1 - t0
            pending.append(((pending[-1][0] if pending else 0.0) + h, h, tau0, tau1, self._behind))
        elif self._pending:  # final (behind the samples, or timed out: the stream is dead), so are those before
            self._pending.clear()
        if self._settling:
            return self._correct(t1 - t0, a0, a1)
        return a0, a1

    def _revise(self, now: float):
        """Add to the errors what the samples pushed since the last step change in the pending steps.

        ``now`` is this step's playout time (s). The pending steps are the
        last ones, in a row. At playout times after the newest sample known
        so far (stamped t_prev) they held its value (0 before any), and are
        accounted so; their values at earlier ones are final. The errors are
        as of the end of the last step (the start of this one); ``end``
        counts plant time over the pending steps, which the playout times do
        not when the caller skips steps.
        """
        pending, queue, timeout = self._pending, self._queue, self.timeout
        if queue:  # the new samples: the last step played every older one
            if now - queue[-1][0] > timeout:  # too late: the stream is dead now, and so are they
                pending.clear()
                return
            prev, linear = self._current, self.interpolation == 'linear'
            t_prev, held = prev if prev else (-math.inf, 0.0)
            samples = [prev, *queue] if prev else list(queue)
            n, t_new, now_end = len(samples), queue[-1][0], pending[-1][0]
            dry_prev = self._dry  # how far past prev the pending steps ran before they played 0
            dry_new = DRY * (t_new - samples[-2][0] if n > 1 else self.period)
            j = 0  # samples[:j] are stamped at or before the playout time in hand

            def change(tau: float, behind: float) -> float:
                """The value at ``tau`` with every sample now known (as on time) minus the value played then, when
                the loop ran ``behind`` s late."""
                nonlocal j
                if not tau > t_prev:
                    return 0.0  # final when played
                played = held if tau - t_prev <= dry_prev + behind else 0.0
                while j < n and samples[j][0] <= tau:
                    j += 1
                if j == 0 or tau - samples[j - 1][0] > timeout:
                    return -played
                if j < n:
                    return (_interpolate(samples[j - 1], samples[j], tau) if linear else samples[j - 1][1]) - played
                return (samples[-1][1] if tau - t_new <= dry_new + behind else 0.0) - played  # past the newest

            ev = ep = 0.0
            for end, h, tau0, tau1, behind in pending:  # step by step: what each played, against what it would now
                d0 = change(tau0, behind)
                d1 = change(tau1, behind) if linear else d0
                dv = h * (d0 + d1) / 2  # the difference ramps d0 -> d1 over the step
                ev += dv
                ep += dv * (now_end - end) + h * h * (d0 / 3 + d1 / 6)
            if queue[0][0] <= pending[-1][2]:  # (else ahead of the samples by design: no delay, linear)
                self.made_up += 1  # came after the step that should have played it began
                self.made_up_late = max(self.made_up_late, now - queue[0][0])
            while pending and pending[0][3] <= t_new:
                pending.popleft()
            if ev or ep:
                self._ev += ev
                self._ep += ep
                self._settling = 2
        oldest = now - timeout  # final: bounds the memory before any sample (after one, the timeout comes first)
        while pending and pending[0][3] < oldest:
            pending.popleft()

    def _correct(self, h: float, a0: float, a1: float) -> tuple[float, float]:
        """The step's ramp plus the deadbeat correction of the errors; ``h`` is its length (s)."""
        ev, ep = self._ev, self._ep
        c = ep / (h * h) + 1.5 * ev / h  # (m/s^2): two equal steps with it, their own c each, end both at 0
        self._settling -= 1  # after two, what is left is rounding: it goes with the next correction
        self._ev, self._ep = ev - c * h, ep + ev * h - c * h * h / 2
        return a0 + c, a1 + c

    def _position_step(self, t0: float, t1: float) -> float:
        """Backward second difference of the positions played out at this and the last two steps."""
        if self._current is None:
            self._advance(t0 - self.delay)
            if self._current is None:  # nothing to play yet
                return 0.0
            self._played = [self._current[1]] * 2  # at rest at the first position
        played = self._played
        played.append(self._at(t0 - self.delay))
        p2, p1, p0 = played[-3:]
        del played[:-2]
        h = t1 - t0
        return (p0 - 2.0 * p1 + p2) / (h * h)
