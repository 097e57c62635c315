"""Shaped plans: a rest-to-rest quintic convolved with a cascaded input shaper (paper §4).

The reference is sum_i A_i q(t - t_i), q the quintic of ``profiles`` lasting
T - t_N so that the whole motion ends exactly at the requested T (the paper's
1.789 s base for ZV and 2.192 s for NZV at T = 3 s).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .plan import Plan, PlanError
from .profiles import quintic
from .shapers import Shaper, design


@dataclass(kw_only=True)
class ShapedPlan(Plan):
    """Plan of a shaper method; exact (analytic) at any time.

    Attributes:
        shaper: the cascaded impulse train (times in s from the start).
        base_duration: length (s) of the quintic being shaped, T - shaper.duration.
    """

    shaper: Shaper
    base_duration: float

    def _evaluate(self, t):
        # one shifted quintic per impulse (columns), weighted by the amplitudes
        shifted = quintic(t[:, None] - self.shaper.times, self.displacement, self.base_duration)
        return tuple(x @ self.shaper.amplitudes for x in shifted)


def shaped_plan(method: str, displacement: float, duration: float, omegas, zeta: float) -> ShapedPlan:
    """Plan from 0 to ``displacement`` (m) in ``duration`` (s) with ``method``'s shaper.

    One shaper per mode frequency in ``omegas`` (rad/s, undamped), damping
    ratio ``zeta``, cascaded. A duration not longer than the shaper cannot
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
        'zeta': float(zeta),
        'impulse_times': shaper.times.tolist(),
        'impulse_amplitudes': shaper.amplitudes.tolist(),
        'shaper_duration': shaper.duration,
        'base_duration': base,
    }
    return ShapedPlan(method=method, displacement=displacement, duration=duration, info=info,
                      shaper=shaper, base_duration=base)
