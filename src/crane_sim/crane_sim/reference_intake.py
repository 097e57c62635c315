"""The simulator's reference intake: which received samples reach the playout, on which stamps.

Every reference sample received is counted and checked before the playout
(``playout.ReferencePlayout``) gets it; the playout needs finite samples in
strictly increasing stamp order. A sample is ignored and counted when

- its position or acceleration is not finite (``nonfinite``): integrated, it
  would poison the plant for good;
- it is stamped and older than ``timeout`` on arrival (``stale``): the
  playout has declared the stream dead by then and would not use it;
- it is stamped no later than the newest accepted sample (``out_of_order``):
  a duplicate, or overtaken on the way; its interval has been played or
  decided already;

and a message that is not one sample is counted ``malformed`` by the caller
(``count_malformed``). The rest are ``accepted``.

The stream is measured as it arrives, from the second accepted stamped
sample on (the first has no interval): the latency of each (arrival -
stamp); the sender's period, taken as the shortest interval seen between
consecutive stamps (nothing to configure, and a lost sample only lengthens
an interval); and ``missing`` samples, counted from the longer intervals
(one of n periods misses n - 1).

A single sample lost (``MAX_BRIDGED``; an Ethernet-like link drops frames
independently, mostly one at a time) is bridged, as a drive tolerates a missed cycle of its cyclic
setpoints: the interval is filled with a sample on the sender's grid,
interpolated between the samples on either side (``bridge``), and counted
``bridged``. Held across the gap instead, the acceleration before it would
leave the reference's velocity off for good wherever the acceleration
changes, and on a steep ramp the sim's axis controller would judge the
stream lost (``playout.moved_across_gap``) and stop the crane; interpolated,
only a corner of the acceleration at the lost sample leaves an error. A
longer gap is left as it is, for the controller's judgement.

With only positions counting (``positions_only``: the playout reconstructs
the acceleration from positions, as for a Float64MultiArray, which carries
none) the acceleration is set to 0, so that an absent (NaN) one does not
make the sample non-finite.

Unstamped samples (a Float64MultiArray, or a zero stamp) are timed by their
arrival, and arrivals bunch up behind any delay; second differences of
positions so timed would explode. So each is stamped ``unstamped_period``
after the previous one, as a controller taking commands at a fixed rate
does, and the grid is re-anchored at the arrival when the two part by more
than the playout delay (the sender paused, or runs slower); the playout
differentiates positions over the plant's steps, so such a gap costs a
jerk, not the end position. A lost sample shifts the grid by a period: an
unstamped stream cannot tell. They are never stale or out of order, and
show no latency or gaps.

Parameters are in seconds; stamps and arrival times are integer
nanoseconds of ROS time, as in the messages. Pure Python, no ROS import.
"""
from __future__ import annotations

import math

#: The intake's counts, in the order the diagnostics list them.
COUNTS = ('received', 'accepted', 'nonfinite', 'stale', 'out_of_order', 'malformed', 'missing', 'bridged')

#: The most samples lost in a row that the intake bridges. One lost sample bridged errs, in the reference's
#: velocity, by at most |jump of the jerk| * period^2 / 2 (a corner of the acceleration at the lost sample;
#: nothing where the jerk is constant): 5.1 mm/s at the corners of ZVD's base motion at its lower time bound
#: (1.03e4 m/s^3) at 1 kHz, about what the controller tolerates across a gap held
#: (``playout.MAX_VELOCITY_ERROR``), and micrometres per second for smooth plans. Two in a row can err twice
#: that, which no estimate from the samples at hand bounds: they are left to the controller's judgement.
MAX_BRIDGED = 1


def bridge(before: tuple, after: tuple, n: int) -> list[tuple]:
    """``n`` samples evenly spaced between the consecutive samples ``before`` and ``after`` (stamp ns, then
    position m and acceleration m/s^2 per axis).

    Each axis's acceleration is interpolated linearly, its position by the cubic whose second derivative is
    that line (the cubic spline through both positions with both accelerations as its ends' second
    derivatives): p(s) = (1 - s) p0 + s p1 - T^2 s (1 - s) ((2 - s) a0 + (1 + s) a1) / 6 at s of the gap T.
    Both are exact for a reference whose position is a cubic across the gap (a constant jerk); with the
    accelerations 0 (positions only) the positions lie on the straight line.
    """
    t0, t1 = before[0], after[0]
    span = (t1 - t0) * 1e-9
    samples = []
    for i in range(1, n + 1):
        s = i / (n + 1)
        values = []
        for (p0, a0), (p1, a1) in zip(zip(before[1::2], before[2::2]), zip(after[1::2], after[2::2])):
            values += [(1.0 - s) * p0 + s * p1 - span * span * s * (1.0 - s) * ((2.0 - s) * a0 + (1.0 + s) * a1) / 6.0,
                       (1.0 - s) * a0 + s * a1]
        samples.append((t0 + round(i * (t1 - t0) / (n + 1)), *values))
    return samples


class ReferenceIntake:
    """Checks, stamps and counts received reference samples; not thread-safe (one receiving thread).

    Args:
        timeout: age (s) on arrival beyond which a stamped sample is stale.
        playout_delay: the playout's delay (s): an unstamped sample arriving
            more than this after its place on the grid re-anchors the grid.
        unstamped_period: the grid's period (s) for unstamped samples.
        positions_only: only positions count (accelerations are set to 0).

    ``counts`` maps each of ``COUNTS`` to its number so far.
    """

    def __init__(self, timeout: float, playout_delay: float, unstamped_period: float, positions_only: bool = False):
        self.configure(timeout, playout_delay, unstamped_period, positions_only)
        self.counts = dict.fromkeys(COUNTS, 0)
        self._last_stamp = -math.inf  # ns, of the newest accepted sample
        self._last_sample: tuple | None = None  # the newest accepted sample, if stamped (a bridge's start)
        self._period = math.inf       # ns, the shortest interval seen between stamped samples
        self._latencies: list[int] = []

    def configure(self, timeout: float, playout_delay: float, unstamped_period: float,
                  positions_only: bool = False) -> None:
        """Change the parameters (as in the constructor); the counts and the stream's history stay."""
        self.positions_only = bool(positions_only)
        self._timeout_ns = round(timeout * 1e9)
        self._regrid_ns = playout_delay * 1e9
        self._unstamped_period_ns = round(unstamped_period * 1e9)

    @property
    def sender_period_ns(self) -> float:
        """The sender's period (ns): the shortest interval seen between stamps; inf before two."""
        return self._period

    def take_latencies(self) -> list[int]:
        """The latencies (arrival - stamp, ns) of the stamped samples accepted since the last call."""
        latencies, self._latencies = self._latencies, []
        return latencies

    def count_malformed(self) -> None:
        """Count a received message that is not one sample (it is ignored)."""
        self.counts['received'] += 1
        self.counts['malformed'] += 1

    def receive(self, now_ns: int, stamp_ns: int | None, position: float,
                acceleration: float, others=(), played_ns: int | None = None) -> tuple[tuple, ...]:
        """The samples for the playout, each (stamp ns, position m, acceleration m/s^2[, the others' pairs]): none
        if this one is ignored, else the samples bridging the gap before it (if any), then it.

        Args:
            now_ns: arrival time (ns of ROS time).
            played_ns: the plant's time (ns of ROS time) when the simulator's loop runs behind it (it stalled and
                catches up): a stamped sample is stale only once that far past it, not the arrival time.
            stamp_ns: the sample's stamp (ns); 0 or None if unstamped.
            position, acceleration: the sample of the first axis, the cart (m, m/s^2).
            others: (position, acceleration) of each further axis (the hoist) in the same sample:
                checked the same way and appended to the result, pair after pair.
        """
        counts = self.counts
        counts['received'] += 1
        stamped = bool(stamp_ns)
        stamp = stamp_ns if stamped else self._grid_stamp(now_ns)
        extra = tuple(float(x) for pair in others for x in pair)
        if self.positions_only:
            acceleration = 0.0
            extra = tuple(0.0 if k % 2 else x for k, x in enumerate(extra))
        if not (math.isfinite(position) and math.isfinite(acceleration) and all(map(math.isfinite, extra))):
            counts['nonfinite'] += 1
        elif stamped and (now_ns if played_ns is None else min(now_ns, played_ns)) - stamp > self._timeout_ns:
            counts['stale'] += 1
        elif stamped and stamp <= self._last_stamp:
            counts['out_of_order'] += 1
        else:
            sample = (stamp, position, acceleration, *extra)
            interval = stamp - self._last_stamp
            bridged = []
            if stamped and interval < math.inf:  # unstamped samples have no latency or gaps to see
                self._period = min(self._period, interval)
                missing = max(0, round(interval / self._period) - 1)
                counts['missing'] += missing
                self._latencies.append(now_ns - stamp)
                if 0 < missing <= MAX_BRIDGED and self._last_sample is not None \
                        and abs(interval - (missing + 1) * self._period) <= 0.1 * self._period:  # on the grid
                    bridged = bridge(self._last_sample, sample, missing)
                    counts['bridged'] += missing
            self._last_stamp = stamp
            self._last_sample = sample if stamped else None
            counts['accepted'] += 1
            return (*bridged, sample)
        return ()

    def _grid_stamp(self, now_ns: int) -> int:
        """An unstamped sample's stamp: a period after the newest, or its arrival if that is too far."""
        grid = self._last_stamp + self._unstamped_period_ns
        return grid if now_ns - grid <= self._regrid_ns else now_ns
