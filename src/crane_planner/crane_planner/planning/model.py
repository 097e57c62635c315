"""Linear model of the double-pendulum crane about the vertical (paper §3-4).

Conventions (paper Fig. 1, Eqs. 18-19): ``theta1`` is the upper cable's angle
from the vertical, ``theta2`` the lower cable's angle *relative to the upper
one*; the input is the cart acceleration. The nonlinear equations live in
``crane_planner.planning.dynamics`` (CasADi, for planning) and independently in
``crane_sim.dynamics`` (numpy, for simulation).
"""
from __future__ import annotations

import numpy as np

from crane_msgs_py.params import CraneParams


def linearized_matrices(p: CraneParams):
    """Mass, stiffness and input matrices of Eqs. 18-19 linearized at theta = 0.

    ``M q'' + K q = b * a_cart`` with ``q = [theta1, theta2]``:
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


def modal_frequencies(p: CraneParams) -> tuple[float, float]:
    """Undamped natural frequencies (rad/s) of the linearized crane, ascending.

    Table 1 with g = 9.81 gives about 3.642 and 8.990 rad/s (the paper lists
    3.640 and 9.017).
    """
    M, K, _ = linearized_matrices(p)
    lam = np.linalg.eigvals(np.linalg.solve(M, K))
    w = np.sqrt(np.sort(lam.real))
    return float(w[0]), float(w[1])
