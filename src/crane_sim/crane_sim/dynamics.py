"""Swing dynamics of the double-pendulum crane (paper Eqs. 18-19), numpy only.

This is the simulator's own implementation, deliberately independent of the
planner's CasADi model so that each cross-checks the other.

Conventions (paper Fig. 1): ``theta1`` is the upper cable's angle from the
vertical, ``theta2`` the lower cable's angle relative to the upper one; both
are positive when the load lags a positive cart acceleration ``a``.
Everything broadcasts, so a batch of plants (arrays of shape ``(n,)``) is one
call.
"""
from __future__ import annotations

import numpy as np


class SwingModel:
    """Eqs. 18-19 for a batch of plants, with the plant constants worked out once.

    Written in the absolute angle of the lower cable, phi = theta1 + theta2,
    Eqs. 18-19 are a 2x2 linear system in (theta1'', phi''):

        [(m1+m2) L1     m2 L2 cos th2] [theta1'']   [(m1+m2)(a cos th1 - g sin th1) + m2 L2 sin th2 phi'^2]
        [L1 cos th2     L2           ] [phi''   ] = [(a cos phi - g sin phi)         - L1 sin th2 theta1'^2]

    whose determinant L1 L2 (m1 + m2 sin^2 th2) never vanishes for positive
    masses and lengths, so Cramer's rule is safe everywhere. Rows of both
    sides are handled as stacked (2, ...) arrays: the simulator calls this
    four times per step for a whole batch, and at a few dozen plants the cost
    is the number of numpy calls, not their size.

    Args:
        L1, L2, m1, m2, g: plant parameters (SI), scalars or arrays of one shape.
    """

    def __init__(self, L1, L2, m1, m2, g):
        L1, L2, m1, m2, g = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (L1, L2, m1, m2, g)))
        mt, one = m1 + m2, np.ones_like(L1)
        self.m1, self.m2, self.g = m1, m2, g
        # row-wise factors of the system above (row 0: Eq. 18, row 1: Eq. 19)
        self._gravity_scale = np.stack((mt, one))      # multiplies (a cos - g sin)
        self._centripetal = np.stack((m2 * L2, -L1))   # multiplies sin th2 (phi'^2, theta1'^2)
        self._cramer_own = np.stack((one, mt))         # Cramer numerators: own - c2 * other
        self._cramer_other = np.stack((m2, one))
        self._lengths = np.stack((L1, L2))

    def accelerations(self, angles, rates, a_cart):
        """[theta1'', phi''] (stacked, shape (2, ...)) for angles = [theta1, phi],
        rates = [theta1', phi'] (each (2, ...)) and cart acceleration a_cart."""
        theta2 = angles[1] - angles[0]
        s2, c2 = np.sin(theta2), np.cos(theta2)
        rhs = self._gravity_scale * (a_cart * np.cos(angles) - self.g * np.sin(angles))
        rhs += self._centripetal * (s2 * (rates * rates)[::-1])
        numer = self._cramer_own * rhs - c2 * (self._cramer_other * rhs[::-1])
        det = self.m1 + self.m2 * (s2 * s2)          # determinant / (L1 L2)
        return numer / (self._lengths * det)


def swing_accelerations(theta1, theta2, dtheta1, dtheta2, a_cart, L1, L2, m1, m2, g):
    """Angular accelerations (theta1'', theta2'') of Eqs. 18-19 under cart acceleration a_cart.

    All arguments broadcast against each other; returns two arrays of the
    broadcast shape.
    """
    args = [np.asarray(v, dtype=float) for v in (theta1, theta2, dtheta1, dtheta2, a_cart, L1, L2, m1, m2, g)]
    th1, th2, d1, d2, a, *params = np.broadcast_arrays(*args)
    acc = SwingModel(*params).accelerations(np.stack((th1, th1 + th2)), np.stack((d1, d1 + d2)), a)
    return acc[0], acc[1] - acc[0]


def load_excursion(theta1, theta2, L1, L2):
    """Horizontal offset (m) of the load m2 from its rest position below the cart.

    x_cart - x_m2 = L1 sin(theta1) + L2 sin(theta1 + theta2) (Fig. 1);
    positive when the load lags behind the cart.
    """
    return L1 * np.sin(theta1) + L2 * np.sin(theta1 + theta2)
