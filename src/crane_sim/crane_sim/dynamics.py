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
    and the tangential accelerations u = (L1 theta1'', L2 phi''), Eqs. 18-19
    are a 2x2 linear system:

        [m1+m2    m2 cos th2] [u0]   [(m1+m2)(a cos th1 - g sin th1) + m2 L2 sin th2 phi'^2] = R0
        [cos th2  1         ] [u1] = [(a cos phi - g sin phi)         - L1 sin th2 theta1'^2] = R1

    whose determinant m1 + m2 sin^2 th2 never vanishes for positive masses,
    so Cramer's rule is safe everywhere. Viscous joint damping (torques
    -c1 theta1' and -c2 theta2', theta2' = phi' - theta1') enters as the
    generalized forces of the dissipation function
    D = c1 theta1'^2 / 2 + c2 (phi' - theta1')^2 / 2 in the same coordinates:
    R0 += (-c1 theta1' + c2 theta2') / L1 and R1 += -c2 theta2' / (m2 L2).
    Then

        theta1'' = (R0 - m2 cos th2 R1) / (L1 det),   phi'' = ((m1+m2) R1 - cos th2 R0) / (L2 det).

    Rows are handled as stacked (2, ...) arrays, each right-hand side already
    divided by its own row's length (the factors below), so one evaluation is
    about twenty numpy calls: the simulator makes four per step for a whole
    batch, and at a few dozen plants the cost is the number of calls, not
    their size.

    Args:
        L1, L2, m1, m2, g, c1, c2: plant parameters (SI), scalars or arrays of one shape.
    """

    def __init__(self, L1, L2, m1, m2, g, c1=0.0, c2=0.0):
        L1, L2, m1, m2, g, c1, c2 = np.broadcast_arrays(
            *(np.asarray(v, dtype=float) for v in (L1, L2, m1, m2, g, c1, c2)))
        mt, one = m1 + m2, np.ones_like(L1)
        self.m1, self.m2 = m1, m2
        lengths = np.stack((L1, L2))
        # R / L, row by row: (a cos - g sin) and the centripetal sin th2 (phi'^2, theta1'^2) terms
        self._a_scale = np.stack((mt, one)) / lengths
        self._g_scale = self._a_scale * g
        self._centripetal = np.stack((m2 * L2 / L1, -L1 / L2))
        # Cramer numerators over L: own row - cos th2 * other row (the other row's 1/L swapped for ours)
        self._own = np.stack((one, mt))
        self._other = np.stack((m2 * L2 / L1, L1 / L2))
        # damping over L of each row: theta1' and theta2' coefficients (None: undamped, skipped)
        self._damping = None
        if np.any(c1) or np.any(c2):
            self._damping = (np.stack((-c1 / L1 ** 2, 0.0 * L1)), np.stack((c2 / L1 ** 2, -c2 / (m2 * L2 ** 2))))

    def accelerations(self, angles, rates, a_cart):
        """[theta1'', phi''] (stacked, shape (2, ...)) for angles = [theta1, phi],
        rates = [theta1', phi'] (each (2, ...)) and cart acceleration a_cart."""
        theta2 = angles[1] - angles[0]
        s2, c2 = np.sin(theta2), np.cos(theta2)
        r = self._a_scale * (a_cart * np.cos(angles)) - self._g_scale * np.sin(angles)
        r += self._centripetal * (s2 * (rates * rates)[::-1])
        if self._damping is not None:
            r += self._damping[0] * rates[0] + self._damping[1] * (rates[1] - rates[0])
        numer = self._own * r - c2 * (self._other * r[::-1])
        return numer / (self.m1 + self.m2 * (s2 * s2))


def hoisting_accelerations(angles, rates, a_cart, L1, dL1, ddL1, L2, m1, m2, g, c1=0.0, c2=0.0):
    """[theta1'', phi''] (stacked like ``SwingModel.accelerations``) with the upper cable's length L1(t) moving.

    Derived here by Newton's law projected across the cables, not from the
    Lagrangian (the planner's CasADi model is; the two cross-check). With
    u(q) = (-sin q, -cos q) and u'(q) = (-cos q, sin q), the masses sit at
    p1 = (y, 0) + L1 u(theta1) and p2 = p1 + L2 u(phi), so

        p1'' = y'' e_x + L1'' u1 + (2 L1' theta1' + L1 theta1'') u1' - L1 theta1'^2 u1,
        p2'' = p1'' + L2 phi'' u_phi' - L2 phi'^2 u_phi.

    Across the lower cable m2 feels only gravity: p2'' . u_phi' = -g sin phi.
    Across the upper cable the two masses together feel only gravity (the
    lower cable's tension is internal): (m1 p1'' + m2 p2'') . u1' = -(m1+m2) g sin theta1.
    With u1 . u_phi' = -sin th2, u1' . u_phi' = cos th2, u_phi . u1' = sin th2
    these are the rows of ``SwingModel`` with the hoist's terms added:

        R0 = (m1+m2)(a cos th1 - g sin th1 - 2 L1' theta1') + m2 L2 sin th2 phi'^2
        R1 = a cos phi - g sin phi + L1'' sin th2 - 2 L1' theta1' cos th2 - L1 sin th2 theta1'^2

    and the same joint damping. All arguments broadcast; L1, dL1, ddL1 are
    the length (m) and its rate and acceleration at this instant.
    """
    L1, dL1, ddL1, L2, m1, m2, g, c1, c2 = (np.asarray(v, dtype=float) for v in (L1, dL1, ddL1, L2, m1, m2, g,
                                                                                  c1, c2))
    theta1, phi = angles[0], angles[1]
    d1, dphi = rates[0], rates[1]
    th2, d2 = phi - theta1, dphi - d1
    s2, k2 = np.sin(th2), np.cos(th2)
    mt = m1 + m2
    hoist = 2.0 * dL1 * d1
    r0 = mt * (a_cart * np.cos(theta1) - g * np.sin(theta1) - hoist) + m2 * L2 * s2 * dphi ** 2
    r1 = a_cart * np.cos(phi) - g * np.sin(phi) + ddL1 * s2 - hoist * k2 - L1 * s2 * d1 ** 2
    r0 = r0 + (c2 * d2 - c1 * d1) / L1
    r1 = r1 - c2 * d2 / (m2 * L2)
    det = m1 + m2 * s2 ** 2
    return np.stack(((r0 - m2 * k2 * r1) / (L1 * det), (mt * r1 - k2 * r0) / (L2 * det)))


def swing_accelerations(theta1, theta2, dtheta1, dtheta2, a_cart, L1, L2, m1, m2, g, c1=0.0, c2=0.0):
    """Angular accelerations (theta1'', theta2'') of Eqs. 18-19 (plus joint damping) under cart acceleration a_cart.

    All arguments broadcast against each other; returns two arrays of the
    broadcast shape.
    """
    args = [np.asarray(v, dtype=float) for v in (theta1, theta2, dtheta1, dtheta2, a_cart, L1, L2, m1, m2, g, c1, c2)]
    th1, th2, d1, d2, a, *params = np.broadcast_arrays(*args)
    acc = SwingModel(*params).accelerations(np.stack((th1, th1 + th2)), np.stack((d1, d1 + d2)), a)
    return acc[0], acc[1] - acc[0]


def mass_positions(cart, theta1, theta2, L1, L2):
    """(x1, z1, x2, z2) (m) of the two masses in the rail frame (x along the rail, z up, cart at z = 0).

    Fig. 1: x1 = y - L1 sin(theta1), z1 = -L1 cos(theta1),
    x2 = x1 - L2 sin(theta1 + theta2), z2 = z1 - L2 cos(theta1 + theta2).
    """
    phi = theta1 + theta2
    x1, z1 = cart - L1 * np.sin(theta1), -L1 * np.cos(theta1)
    return x1, z1, x1 - L2 * np.sin(phi), z1 - L2 * np.cos(phi)
