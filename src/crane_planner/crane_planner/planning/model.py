"""Linear model of the double-pendulum crane about the vertical (paper §3-4).

Conventions (paper Fig. 1, Eqs. 18-19): ``theta1`` is the upper cable's angle
from the vertical, ``theta2`` the lower cable's angle *relative to the upper
one*; the input is the cart acceleration. The nonlinear equations live in
``crane_planner.planning.dynamics`` (CasADi, for planning) and independently in
``crane_sim.dynamics`` (numpy, for simulation).
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from crane_msgs_py.crane.params import CraneParams


def linearized_matrices(p: CraneParams):
    """Mass, stiffness and input matrices of Eqs. 18-19 linearized at theta = 0.

    ``M q'' + C q' + K q = b * a_cart`` with ``q = [theta1, theta2]`` (``C`` from
    ``damping_matrix``):
    Eq. 18 -> (m1+m2)(L1 th1'' + g th1) + m2 L2 (th1'' + th2'') = (m1+m2) a,
    Eq. 19 -> L2 (th1'' + th2'') + g (th1 + th2) + L1 th1'' = a.
    """
    mt = p.m1 + p.m2
    M = np.array([[mt * p.L1 + p.m2 * p.L2, p.m2 * p.L2],
                  [p.L1 + p.L2, p.L2]])
    K = np.array([[mt * p.g, 0.0],
                  [p.g, p.g]])
    b = np.array([mt, 1.0])
    return M, K, b


def damping_matrix(p: CraneParams) -> np.ndarray:
    """``C`` of the linearized crane, in the rows of ``linearized_matrices``.

    The joint torques -c1 th1' and -c2 th2' as generalized forces
    (``planning.dynamics.swing_accelerations``): Eq. 18's row gains
    (c1 th1' - c2 th2') / L1, Eq. 19's c2 th2' / (m2 L2).
    """
    return np.array([[p.c1 / p.L1, -p.c2 / p.L1],
                     [0.0, p.c2 / (p.m2 * p.L2)]])


@lru_cache(maxsize=64)  # (CraneParams is frozen; the result tuples)
def modal_properties(p: CraneParams) -> tuple[tuple[float, float], tuple[float, float]]:
    """Natural frequencies (rad/s) and damping ratios of the linearized crane's two modes, slow mode first.

    From the eigenvalues lambda = -zeta omega +- i omega sqrt(1 - zeta^2) of
    the state matrix [[0, I], [-M^-1 K, -M^-1 C]]: omega = |lambda|,
    zeta = -Re(lambda) / |lambda|. Without damping, omega are the undamped
    frequencies and zeta = 0.
    """
    M, K, _ = linearized_matrices(p)
    if p.c1 == 0.0 and p.c2 == 0.0:  # exactly the undamped frequencies, zeta exactly 0
        w = np.sqrt(np.sort(np.linalg.eigvals(np.linalg.solve(M, K)).real))
        return (float(w[0]), float(w[1])), (0.0, 0.0)
    A = np.block([[np.zeros((2, 2)), np.eye(2)],
                  [-np.linalg.solve(M, K), -np.linalg.solve(M, damping_matrix(p))]])
    lam = np.linalg.eigvals(A)
    lam = lam[lam.imag > 0]  # one of each underdamped pair
    if lam.size != 2:
        raise ValueError('a mode of the linearized crane is overdamped: joint damping too large')
    lam = lam[np.argsort(np.abs(lam))]
    omega = np.abs(lam)
    zeta = np.maximum(-lam.real / omega, 0.0)
    return (float(omega[0]), float(omega[1])), (float(zeta[0]), float(zeta[1]))


def modal_frequencies(p: CraneParams) -> tuple[float, float]:
    """Natural frequencies (rad/s) of the linearized crane, ascending (``modal_properties``).

    Table 1 with g = 9.81 gives about 3.642 and 8.990 rad/s (the paper lists
    3.640 and 9.017).
    """
    return modal_properties(p)[0]
