"""Base motion profiles that input shapers filter (paper §4).

The paper shapes "a fifth-order polynomial trajectory, chosen so that initial
and final acceleration of the cart can be set to zero": the rest-to-rest
quintic, which is also the minimum-jerk point-to-point motion.
"""
from __future__ import annotations

import numpy as np


def quintic(t, displacement: float, duration: float):
    """Rest-to-rest quintic D (10 s^3 - 15 s^4 + 6 s^5), s = t / T (paper §4).

    Exact position, velocity, acceleration and jerk at times ``t`` (any
    shape). Outside [0, T] the profile is at rest at 0 (before) or D (after).
    Jerk jumps at both ends; it is taken right-continuous, i.e. nonzero on
    [0, T) only, so the instant the motion ends is already at rest.
    """
    t = np.asarray(t, dtype=float)
    D, T = float(displacement), float(duration)
    s = np.clip(t / T, 0.0, 1.0)
    r = 1.0 - s
    p = D * s**3 * (10.0 + s * (6.0 * s - 15.0))
    v = (30.0 * D / T) * (s * r) ** 2
    a = (60.0 * D / T**2) * s * r * (r - s)
    j = np.where((t >= 0.0) & (t < T), (60.0 * D / T**3) * (1.0 - 6.0 * s * r), 0.0)
    return p, v, a, j
