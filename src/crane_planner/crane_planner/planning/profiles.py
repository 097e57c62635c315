"""Base motion profiles that input shapers filter (paper §4).

The paper shapes "a fifth-order polynomial trajectory, chosen so that initial
and final acceleration of the cart can be set to zero": the rest-to-rest
quintic, which is also the minimum-jerk point-to-point motion.
"""
from __future__ import annotations

import numpy as np

from numpy.polynomial import polynomial as poly

#: P(s) = 10 s^3 - 15 s^4 + 6 s^5: from P = P' = P'' = 0 at s = 0 to P = 1, P' = P'' = 0 at s = 1.
#: Ascending coefficients of P and of its derivatives, indexed by order.
QUINTIC = tuple(poly.polyder([0.0, 0.0, 0.0, 10.0, -15.0, 6.0], k) for k in range(6))


def quintic(t, displacement: float, duration: float):
    """Rest-to-rest quintic D P(t / T) (paper §4): position, velocity, acceleration, jerk.

    Exact at times ``t`` (any shape). Outside [0, T] the profile is at rest
    at 0 (before) or D (after). Jerk jumps at both ends; it is taken
    right-continuous, i.e. nonzero on [0, T) only, so the instant the motion
    ends is already at rest.
    """
    t = np.asarray(t, dtype=float)
    D, T = float(displacement), float(duration)
    # at the clipped ends P', P'' vanish exactly (integer coefficients), so v, a are at rest too
    s = np.clip(t / T, 0.0, 1.0)
    p, v, a, j = (D / T**k * poly.polyval(s, QUINTIC[k]) for k in range(4))
    return p, v, a, np.where((t >= 0.0) & (t < T), j, 0.0)
