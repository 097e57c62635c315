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
t1 - delay (``linear``). Without a sample newer than ``timeout`` the
acceleration falls back to 0 (the stream stopped: never hold an acceleration).

With ``source='position'`` (a controller that only gets positions) the
positions are played out the same way and the step's acceleration is the
second difference of the played-out position over the plant's own last
steps. On the plant's even grid these sum exactly: the reference velocity is
always the last step's position difference over h, so the cart ends at rest
at the last position whatever the stamps' spacing (gaps, a re-anchored
grid). Second differences of the samples themselves held over the next,
different interval would leave a velocity error for good. Without a fresh
sample the last position holds, as an axis holds its last setpoint, and the
acceleration falls to 0 by itself. On an even grid of samples aligned with
the steps both forms are the same: the second difference around the
previous sample, applied from the newest one on. Times are seconds on any
common clock. Pure Python, no ROS import.
"""
from __future__ import annotations

import math
from collections import deque

from crane_msgs_py.params import check_choice

from .simulator import INTERPOLATIONS, SOURCES, SimulationError


class ReferencePlayout:
    """Accelerations for consecutive plant steps from stamped references.

    Args:
        delay: playout delay (s), >= 0.
        timeout: age (s) beyond which the newest sample no longer counts, > 0.
        interpolation: ``zoh`` or ``linear``.
        source: ``acceleration`` (use each sample's acceleration) or ``position``.

    ``timeouts`` counts the times the reference fell back to 0 after having had samples.
    """

    def __init__(self, delay: float, timeout: float, interpolation: str = 'zoh', source: str = 'acceleration'):
        check_choice('interpolation', interpolation, INTERPOLATIONS, SimulationError)
        check_choice('source', source, SOURCES, SimulationError)
        if not (delay >= 0.0 and timeout > 0.0):
            raise SimulationError(f'need delay >= 0 and timeout > 0, got {delay}, {timeout}')
        self.delay, self.timeout = float(delay), float(timeout)
        self.interpolation, self.source = interpolation, source
        self.timeouts = 0
        self.reset()

    def reset(self):
        """Forget every sample (the next position sample starts a motion from rest)."""
        self._queue: deque = deque()   # (t, value) not yet reached by the playout time
        self._last = -math.inf         # stamp of the last sample pushed
        self._current = None           # (t, value): the newest sample at or before the playout time
        self._live = False             # whether _current is recent enough to count
        self._played: list[float] = []  # position source: positions played out at the last two steps

    def push(self, t: float, position: float, acceleration: float):
        """A sample stamped ``t`` (after the previous one's stamp)."""
        if not t > self._last:
            raise SimulationError(f'reference stamps must increase: {t} after {self._last}')
        self._last = float(t)
        self._queue.append((float(t), float(position if self.source == 'position' else acceleration)))

    def _advance(self, tau: float):
        queue = self._queue
        while queue and queue[0][0] <= tau:
            self._current = queue.popleft()
        live = self._current is not None and tau - self._current[0] <= self.timeout
        if self._live and not live:
            self.timeouts += 1
        self._live = live

    def _at(self, tau: float) -> float:
        """The played-out value at ``tau``: an acceleration (0 once stale), or a position (held)."""
        self._advance(tau)
        if self._current is None or not (self._live or self.source == 'position'):
            return 0.0
        t0, a0 = self._current
        if self.interpolation == 'linear' and self._queue:
            t1, a1 = self._queue[0]
            return a0 + (a1 - a0) * (tau - t0) / (t1 - t0)
        return a0

    def step(self, t0: float, t1: float) -> tuple[float, float]:
        """Reference acceleration at the beginning and the end of the plant step [t0, t1]."""
        if self.source == 'position':
            return (self._position_step(t0, t1),) * 2
        a0 = self._at(t0 - self.delay)
        if self.interpolation == 'zoh':
            return a0, a0
        return a0, self._at(t1 - self.delay)

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
