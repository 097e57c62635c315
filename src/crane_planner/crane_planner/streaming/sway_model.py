"""The linear models of one horizontal plane that the sway feedback estimates and controls with.

Both are the crane of Eqs. 18-19 linearized about the vertical
(``planning.model.linearized_matrices``: M q'' + C q' + K q = b a, q = [theta1,
theta2]) behind the axis's first-order servo (Eq. 6: tau a' + a = a_ref), the
input the reference's acceleration a_ref:

- ``estimation``: z = [a, theta1, theta2, theta1', theta2', w], driven by the
  reference acceleration streamed. w is a horizontal acceleration acting on
  both masses (wind, a gust, the load pushed), which for the swing is the cart
  accelerating by -w: M q'' + C q' + K q = b (a - w). It is modelled as a random
  walk (w' = noise) so that a steady wind is estimated, not fought.
- ``control``: x = [p, v, a_r, a, theta1, theta2, theta1', theta2'], the
  correction's own reference (position, velocity, acceleration, integrated
  from its jerk, the input) and what it does to the cart and the swing.

Both come with their zero-order-hold discretizations (``discretized``). A
servo with tau = 0 is modelled as ``MIN_TAU`` (a tick's lag). Pure numpy and
scipy, no ROS import.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm

from crane_msgs_py.crane.params import CraneParams

from ..planning.model import damping_matrix, linearized_matrices

#: The servo time constant (s) modelled when the parameters give tau = 0: the reference's own tick.
MIN_TAU = 1e-3
#: Rows of the estimation model's state.
ESTIMATION_STATES = ('a', 'theta1', 'theta2', 'dtheta1', 'dtheta2', 'w')
#: Rows of the control model's state.
CONTROL_STATES = ('p', 'v', 'a_ref', 'a', 'theta1', 'theta2', 'dtheta1', 'dtheta2')


@dataclass(frozen=True)
class LinearModel:
    """x' = A x + B u, y = C x (continuous time), its states named ``states``."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    states: tuple

    def discretized(self, h: float) -> tuple[np.ndarray, np.ndarray]:
        """(Phi, Gamma) of the zero-order hold over ``h`` s: x[k+1] = Phi x[k] + Gamma u[k]."""
        n, m = self.B.shape
        block = np.zeros((n + m, n + m))
        block[:n, :n], block[:n, n:] = self.A, self.B
        e = expm(block * h)
        return e[:n, :n], e[:n, n:]


def _swing_rows(p: CraneParams) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(-M^-1 K, -M^-1 C, M^-1 b): q'' = Kq q + Cq q' + bq a of the linearized crane."""
    M, K, b = linearized_matrices(p)
    Minv = np.linalg.inv(M)
    return -Minv @ K, -Minv @ damping_matrix(p), Minv @ b


def estimation(p: CraneParams) -> LinearModel:
    """The swing behind the servo with the disturbance w (see the module docstring); measured: theta1, theta2."""
    Kq, Cq, bq = _swing_rows(p)
    tau = max(p.tau, MIN_TAU)
    A = np.zeros((6, 6))
    A[0, 0] = -1.0 / tau
    A[1:3, 3:5] = np.eye(2)
    A[3:5, 1:3], A[3:5, 3:5], A[3:5, 0], A[3:5, 5] = Kq, Cq, bq, -bq
    B = np.zeros((6, 1))
    B[0, 0] = 1.0 / tau
    C = np.zeros((2, 6))
    C[0, 1] = C[1, 2] = 1.0
    return LinearModel(A, B, C, ESTIMATION_STATES)


def control(p: CraneParams) -> LinearModel:
    """The correction's reference (p, v, a_ref from its jerk), the servo's acceleration a and the swing it causes."""
    Kq, Cq, bq = _swing_rows(p)
    tau = max(p.tau, MIN_TAU)
    A = np.zeros((8, 8))
    A[0, 1] = A[1, 2] = 1.0
    A[3, 2], A[3, 3] = 1.0 / tau, -1.0 / tau
    A[4:6, 6:8] = np.eye(2)
    A[6:8, 4:6], A[6:8, 6:8], A[6:8, 3] = Kq, Cq, bq
    B = np.zeros((8, 1))
    B[2, 0] = 1.0
    C = np.zeros((2, 8))
    C[0, 4] = C[1, 5] = 1.0
    return LinearModel(A, B, C, CONTROL_STATES)


def equilibrium(p: CraneParams, w: float) -> np.ndarray:
    """[theta1, theta2] at rest under a steady horizontal acceleration ``w`` on both masses (m/s^2): K q = -b w,
    the cables leaning into it (theta1 = -w / g, theta2 = 0 to first order)."""
    _, K, b = linearized_matrices(p)
    return np.linalg.solve(K, -b * w)


def load_offset_row(p: CraneParams) -> np.ndarray:
    """The load's horizontal offset from below the suspension point, linearized: L1 theta1 + L2 (theta1 + theta2),
    as a row over [theta1, theta2] (the sign of ``crane_msgs_py.crane.geometry.load_offset`` aside)."""
    return np.array([p.L1 + p.L2, p.L2])
