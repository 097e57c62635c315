"""Shaped plans: a rest-to-rest quintic convolved with a cascaded input shaper (paper §4).

The reference is sum_i A_i q(t - t_i), q the quintic of ``profiles`` lasting
T - t_N so that the whole motion ends exactly at the requested T (the paper's
1.789 s base for ZV and 2.192 s for NZV at T = 3 s).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.polynomial.polynomial import polyder, polyval

from .plan import Plan, PlanError
from .profiles import QUINTIC
from .shapers import Shaper, design

#: Taylor coefficients kept per piece: the sum is a quintic between breaks.
_ORDER = 5


@dataclass(kw_only=True)
class ShapedPlan(Plan):
    """Plan of a shaper method; exact (analytic) at any time.

    Attributes:
        shaper: the cascaded impulse train (times in s from the start).
        base_duration: length (s) of the quintic being shaped, T - shaper.duration.
    """

    shaper: Shaper
    base_duration: float
    _breaks: np.ndarray = field(init=False, repr=False, compare=False)
    _coefficients: list = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        # sum_i A_i q(t - t_i) changes form only where a shifted quintic starts or
        # ends; in between it is one quintic, kept as its Taylor coefficients at
        # the piece's start so a sample costs one polynomial, not one per impulse.
        starts, Tb, D = self.shaper.times, self.base_duration, self.displacement
        ends = starts + Tb
        ends[-1] = self.duration  # equal up to rounding; exact so T lands in the resting piece
        breaks = np.unique(np.concatenate((starts, ends)))
        # which quintics move on a piece, judged inside it (never at a rounded edge)
        inside = np.append(0.5 * (breaks[:-1] + breaks[1:]), np.inf)[:, None]
        moving = (starts <= inside) & (inside < ends)
        s = (breaks[:, None] - starts) / Tb
        taylor = np.empty((breaks.size, _ORDER + 1))
        for k in range(_ORDER + 1):
            dk = np.where(moving, polyval(s, QUINTIC[k]) * (D / Tb**k / math.factorial(k)), 0.0)
            if k == 0:
                dk += np.where(inside >= ends, D, 0.0)
            taylor[:, k] = dk @ self.shaper.amplitudes
        self._breaks = breaks
        # position, velocity, acceleration, jerk per piece, in powers of (t - break)
        self._coefficients = [polyder(taylor, n, axis=1) for n in range(4)]

    def breakpoints(self) -> np.ndarray:
        return self._breaks[self._breaks <= self.duration]

    def _evaluate(self, t):
        piece = np.searchsorted(self._breaks, t, side='right') - 1
        x = t - self._breaks[piece]
        return tuple(polyval(x, c[piece].T, tensor=False) for c in self._coefficients)


def shaped_plan(method: str, displacement: float, duration: float, omegas, zeta) -> ShapedPlan:
    """Plan from 0 to ``displacement`` (m) in ``duration`` (s) with ``method``'s shaper.

    One shaper per mode frequency in ``omegas`` (rad/s) with damping ratio
    ``zeta`` (one for all, or one per mode), cascaded. A duration not longer than the shaper cannot
    be met and is a PlanError (contract: never a silently longer motion).
    """
    shaper = design(method, omegas, zeta)
    displacement, duration = float(displacement), float(duration)
    if not shaper.duration < duration < math.inf:
        raise PlanError(f'{method} needs a duration longer than its shaper '
                        f'({shaper.duration:.3f} s), got {duration} s')
    base = duration - shaper.duration
    info = {
        'omegas': [float(w) for w in np.atleast_1d(omegas)],
        'zeta': np.broadcast_to(np.asarray(zeta, dtype=float), np.shape(np.atleast_1d(omegas))).tolist(),
        'impulse_times': shaper.times.tolist(),
        'impulse_amplitudes': shaper.amplitudes.tolist(),
        'shaper_duration': shaper.duration,
        'base_duration': base,
    }
    return ShapedPlan(method=method, displacement=displacement, duration=duration, info=info,
                      shaper=shaper, base_duration=base)
