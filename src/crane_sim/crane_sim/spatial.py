"""The spatial double-pendulum crane, one plant, in plain floats: the simulator's real-time model.

Contract ("The spatial crane"): the suspension point ``s = (x, y, 0)`` is
moved by the cart (x) and the bridge (y); the upper cable, of length L1 (the
hoist's, moving or not), points along ``u(theta1, phi1)`` and the lower, of
length L2, along ``u(theta1 + theta2, phi1 + phi2)``; m1 sits at the end of
the upper cable and m2 at the end of the lower. ``theta`` is the angle in the
x-z plane, positive when the load lags behind a positive cart acceleration
(the paper's, Eqs. 18-19, so ``u``'s x component is ``-sin a cos b``), and
``phi`` the angle out of that plane, positive towards +y:

    u(a, b) = (-sin a cos b, sin b, -cos a cos b).

With ``phi1 = phi2 = 0`` and no bridge motion this is the planar crane of
Eqs. 18-19 exactly (``phi'' = 0`` there: every term of its rows carries a
``sin phi``).

Derived by Newton's law projected across the cables (the planner's CasADi
model is derived from the Lagrangian; the two cross-check): with the
absolute angles ``(a1, b1) = (theta1, phi1)``, ``(a2, b2) = (theta1 + theta2,
phi1 + phi2)``, the tangent vectors ``A = du/da`` (length cos b) and
``B = du/db`` (unit) of the upper cable and ``C``, ``D`` of the lower (each
pair orthogonal to its cable and to each other), the lower mass feels across
its cable only gravity, the two masses together across the upper cable only
gravity (the lower cable's tension is internal):

    m2 p2'' . C = m2 g . C,          m2 p2'' . D = m2 g . D,
    (m1 p1'' + m2 p2'') . A = (m1 + m2) g . A,   (...) . B = (m1 + m2) g . B,

with ``p1'' = s'' + L1'' u1 + 2 L1' u1' + L1 u1''`` and ``p2'' = p1'' + L2 u2''``.
These rows are Lagrange's equations of the absolute angles divided by
``(m1 + m2) L1`` and ``m2 L2``, so the joint damping (the dissipation function
``D = c1 (theta1'^2 + phi1'^2) / 2 + c2 (theta2'^2 + phi2'^2) / 2`` of the
relative angles, the planar one in each direction) adds its generalized
forces divided the same way. The rows of the upper cable give its angular
accelerations in terms of the lower's; put into the lower's rows they leave
a 2x2 system (a Schur complement of the mass matrix, positive definite for
positive masses and cables off the horizontal), solved by Cramer's rule.

The accelerations in plain ``math`` on floats: one plant stepped in real time costs the number of
operations, and numpy's per-call overhead on arrays of one would cost many
times more (the batch simulator, ``crane_sim.simulator.simulate``, keeps
numpy for many plants).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from crane_msgs_py.crane.geometry import cable_direction

#: The spatial swing coordinates, in the contract's order (joint_states' order after the axes).
SPATIAL_SWING_NAMES = ('theta1', 'theta2', 'phi1', 'phi2')


def mass_paths(x, y, L1, L2, theta1, theta2, phi1=0.0, phi2=0.0) -> tuple[np.ndarray, np.ndarray]:
    """(m1, m2): both masses' positions (3, n) in ``crane_base`` for the suspension point (x, y, 0), the
    upper cable L1 and the swing angles (arrays or floats; phi 0: the planar crane)."""
    x, y, L1, theta1, theta2, phi1, phi2 = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (
        x, y, L1, theta1, theta2, phi1, phi2)))
    u1 = np.array(cable_direction(theta1, phi1))
    u2 = np.array(cable_direction(theta1 + theta2, phi1 + phi2))
    m1 = np.stack([x, y, np.zeros_like(x)]) + L1 * u1
    return m1, m1 + L2 * u2


@dataclass(frozen=True)
class SpatialPendulum:
    """The plant's constants (SI): lower cable L2, masses m1, m2, gravity g, joint damping c1, c2.

    The upper cable's length L1 is an argument of every call: fixed, or the
    hoist's at that instant.
    """

    L2: float
    m1: float
    m2: float
    g: float
    c1: float = 0.0
    c2: float = 0.0

    def accelerations(self, angles, rates, ax: float, ay: float, L1: float, dL1: float = 0.0,
                      ddL1: float = 0.0) -> tuple[float, float, float, float]:
        """(a1'', b1'', a2'', b2''): the absolute angles' accelerations.

        Args:
            angles: absolute angles (a1, b1, a2, b2) = (theta1, phi1, theta1 + theta2, phi1 + phi2).
            rates: their rates.
            ax, ay: the suspension point's acceleration along x (cart) and y (bridge).
            L1, dL1, ddL1: the upper cable's length and its first two derivatives (the hoist's).
        """
        a1, b1, a2, b2 = angles
        da1, db1, da2, db2 = rates
        L2, m1, m2, g = self.L2, self.m1, self.m2, self.g
        sa1, ca1, sb1, cb1 = math.sin(a1), math.cos(a1), math.sin(b1), math.cos(b1)
        sa2, ca2, sb2, cb2 = math.sin(a2), math.cos(a2), math.sin(b2), math.cos(b2)
        # tangents: A = du/da (upper), B = du/db, C and D likewise for the lower; u itself
        A = (-ca1 * cb1, 0.0, sa1 * cb1)
        B = (sa1 * sb1, cb1, ca1 * sb1)
        C = (-ca2 * cb2, 0.0, sa2 * cb2)
        D = (sa2 * sb2, cb2, ca2 * sb2)
        u1 = (-sa1 * cb1, sb1, -ca1 * cb1)
        u2 = (-sa2 * cb2, sb2, -ca2 * cb2)
        # u'' without the angular accelerations: d2u/da2 a'^2 + 2 d2u/dadb a' b' + d2u/db2 b'^2,
        # with d2u/da2 = (sin a cos b, 0, cos a cos b), d2u/dadb = (cos a sin b, 0, -sin a sin b), d2u/db2 = -u
        w1, w2 = 2.0 * da1 * db1, 2.0 * da2 * db2
        q1, q2 = da1 * da1, da2 * da2
        r1, r2 = db1 * db1, db2 * db2
        cen1 = (sa1 * cb1 * q1 + ca1 * sb1 * w1 - u1[0] * r1, -u1[1] * r1,
                ca1 * cb1 * q1 - sa1 * sb1 * w1 - u1[2] * r1)
        cen2 = (sa2 * cb2 * q2 + ca2 * sb2 * w2 - u2[0] * r2, -u2[1] * r2,
                ca2 * cb2 * q2 - sa2 * sb2 * w2 - u2[2] * r2)
        # p1'' less its angular-acceleration part, minus gravity: k1; the lower's own part: k2 = L2 cen2
        two_dL1 = 2.0 * dL1
        k1 = (ax + ddL1 * u1[0] + two_dL1 * (A[0] * da1 + B[0] * db1) + L1 * cen1[0],
              ay + ddL1 * u1[1] + two_dL1 * (B[1] * db1) + L1 * cen1[1],
              g + ddL1 * u1[2] + two_dL1 * (A[2] * da1 + B[2] * db1) + L1 * cen1[2])
        k2 = (L2 * cen2[0], L2 * cen2[1], L2 * cen2[2])
        mt = m1 + m2
        mu = m2 / mt
        kk = (k1[0] + mu * k2[0], k1[1] + mu * k2[1], k1[2] + mu * k2[2])
        kl = (k1[0] + k2[0], k1[1] + k2[1], k1[2] + k2[2])
        # joint damping's generalized forces of the absolute angles (relative rates da2 - da1, db2 - db1)
        t2, p2 = da2 - da1, db2 - db1
        Qa1, Qb1 = -self.c1 * da1 + self.c2 * t2, -self.c1 * db1 + self.c2 * p2
        Qa2, Qb2 = -self.c2 * t2, -self.c2 * p2
        # right-hand sides (g enters k1 as +g in z: g-vector . X = -g X_z moved to the left)
        rA = -(kk[0] * A[0] + kk[2] * A[2]) + Qa1 / (mt * L1)
        rB = -(kk[0] * B[0] + kk[1] * B[1] + kk[2] * B[2]) + Qb1 / (mt * L1)
        rC = -(kl[0] * C[0] + kl[2] * C[2]) + Qa2 / (m2 * L2)
        rD = -(kl[0] * D[0] + kl[1] * D[1] + kl[2] * D[2]) + Qb2 / (m2 * L2)
        # upper rows: L1 cb1^2 a1'' + mu L2 (AC a2'' + AD b2'') = rA; L1 b1'' + mu L2 (BC a2'' + BD b2'') = rB
        AA = cb1 * cb1
        AC = A[0] * C[0] + A[2] * C[2]
        AD = A[0] * D[0] + A[2] * D[2]
        BC = B[0] * C[0] + B[2] * C[2]
        BD = B[0] * D[0] + B[1] * D[1] + B[2] * D[2]
        # lower rows: L1 (AC a1'' + BC b1'') + L2 cb2^2 a2'' = rC;  L1 (AD a1'' + BD b1'') + L2 b2'' = rD
        acA, adA = AC / AA, AD / AA
        m11 = L2 * (cb2 * cb2 - mu * (AC * acA + BC * BC))
        m12 = -mu * L2 * (AC * adA + BC * BD)
        m22 = L2 * (1.0 - mu * (AD * adA + BD * BD))
        s1 = rC - acA * rA - BC * rB
        s2 = rD - adA * rA - BD * rB
        det = m11 * m22 - m12 * m12
        dda2 = (s1 * m22 - m12 * s2) / det
        ddb2 = (m11 * s2 - m12 * s1) / det
        dda1 = (rA - mu * L2 * (AC * dda2 + AD * ddb2)) / (L1 * AA)
        ddb1 = (rB - mu * L2 * (BC * dda2 + BD * ddb2)) / L1
        return dda1, ddb1, dda2, ddb2

    def positions(self, s, angles, L1: float):
        """(p1, p2): both masses' positions in ``crane_base`` for the suspension point ``s`` = (x, y, z)."""
        a1, b1, a2, b2 = angles
        u1, u2 = cable_direction(a1, b1), cable_direction(a2, b2)
        p1 = tuple(float(s[i] + L1 * u1[i]) for i in range(3))
        return p1, tuple(float(p1[i] + self.L2 * u2[i]) for i in range(3))

    def energy(self, angles, rates, L1: float) -> float:
        """Kinetic plus potential energy (J) of both masses, the suspension point and L1 at rest."""
        a1, b1, a2, b2 = angles
        da1, db1, da2, db2 = rates
        v1 = _tangent_velocity(a1, b1, da1, db1, L1)
        v2 = _tangent_velocity(a2, b2, da2, db2, self.L2)
        v2 = tuple(v1[i] + v2[i] for i in range(3))
        p1, p2 = self.positions((0.0, 0.0, 0.0), angles, L1)
        kinetic = 0.5 * (self.m1 * sum(c * c for c in v1) + self.m2 * sum(c * c for c in v2))
        return kinetic + self.g * (self.m1 * p1[2] + self.m2 * p2[2])


def _tangent_velocity(a, b, da, db, length):
    """d/dt (length u(a, b)) at fixed length: length (du/da a' + du/db b')."""
    sa, ca, sb, cb = math.sin(a), math.cos(a), math.sin(b), math.cos(b)
    return (length * (-ca * cb * da + sa * sb * db), length * cb * db, length * (sa * cb * da + ca * sb * db))
