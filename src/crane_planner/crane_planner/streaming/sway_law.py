"""The sway feedback's design for one horizontal plane: its state-feedback law and its estimator's gain.

The law is a linear-quadratic regulator of the control model
(``sway_model.control``): the correction's jerk j = -K x minimises
the integral of

    (l / LOAD_SCALE)^2 + (l' / (OMEGA_SCALE LOAD_SCALE))^2 + (e^2 + (e' / omega_2)^2) / SECOND_MODE_SCALE^2
    + (p / POSITION_SCALE)^2 + (v / VELOCITY_SCALE)^2 + (a / ACCELERATION_SCALE)^2 + (j / JERK_SCALE)^2,

l the load's offset from below the suspension point (L1 theta1 + L2 (theta1 +
theta2)), e the second (fast, omega_2) mode's coordinate, which the offset
alone would leave undamped, p, v, a the correction's own position, velocity and
acceleration (a and j weighed so that damping a push of centimetres keeps
within an axis's usual limits, 0.5 m/s^2 and 5 m/s^3: a law that saturates
them swings the load further instead):
the swing is damped within about a period of the first mode, and what the
correction moved the axis returns to zero in a few seconds, so the axis ends
where the plan ends. The swing's scales grow with the camera's noise beyond
``QUIET_CAMERA`` (``gentleness``): the camera's noise, through the estimate,
would otherwise move the axes by millimetres. The weights were chosen on crane_sim's plant with the
playout delay, a camera's latency and noise, and cables 10-20 % off the
model (docs/methods.md has the figures). The estimator (``sway_estimator``) takes each measurement
with the steady-state Kalman gain of the estimation model
(``sway_model.estimation``) sampled at the camera's period, its disturbance a
random walk of ``DISTURBANCE_RATE`` and the angles' noise ``noise``.

Everything is scheduled on the upper cable's length L1: ``Schedule`` designs
the law and the gain for a grid of lengths once, and the streamer takes the
nearest at each tick (a hoist changes L1 while it moves). Pure numpy and scipy,
no ROS import.
"""
from __future__ import annotations

import bisect
import dataclasses
from dataclasses import dataclass

import numpy as np
from scipy.linalg import solve_continuous_are, solve_discrete_are

from crane_msgs_py.crane.params import CraneParams

from . import sway_model

#: The law's weights (see the module docstring): the load's offset (m) and its rate's scale (rad/s) ...
LOAD_SCALE = 0.01
OMEGA_SCALE = 3.0
#: ... the correction's position (m), velocity (m/s), acceleration (m/s^2) and its jerk (m/s^3).
POSITION_SCALE = 0.1
VELOCITY_SCALE = 0.1
ACCELERATION_SCALE = 0.3
JERK_SCALE = 0.5
#: ... and the second (fast) mode's share of the load's offset (m), which the offset alone leaves undamped.
SECOND_MODE_SCALE = 0.001
#: A camera this quiet (angle noise, rad) or quieter gets the law's weights as they are; a noisier one a law
#: as much gentler as it is noisier (``gentleness``).
QUIET_CAMERA = 1e-4
#: The estimator's model of the disturbance: a random walk of this intensity (m/s^2 per sqrt(s)), slow, so that
#: it follows a steady wind but not the camera's noise; and of the swing's own rates (rad/s per sqrt(s)): what
#: the model does not know of the plant (gusts, a cable of another length).
DISTURBANCE_RATE = 0.1
SWING_RATE = 0.3
#: The camera's sample period (s) the estimator's gain is designed for (the sim's joint_states: 50 Hz).
MEASUREMENT_PERIOD = 0.02
#: How long (s) the estimator keeps its past, to take a measurement that comes this much after its stamp.
HISTORY = 1.0
#: Relative spacing of the lengths L1 a ``Schedule`` designs for.
LENGTH_STEP = 0.02


@dataclass(frozen=True)
class PlaneDesign:
    """Everything one plane's feedback needs at one cable length L1: the law's gain ``K`` (over the control
    model's state), the estimator's tick (``Phi``, ``Gamma`` over ``tick`` s), its measurement gain ``L``, the
    powers of ``Phi`` for taking late measurements, and the static swing under a unit disturbance."""

    L1: float
    tick: float
    K: np.ndarray
    Phi: np.ndarray
    Gamma: np.ndarray
    L: np.ndarray
    powers: np.ndarray
    lean: np.ndarray


def gentleness(noise: float) -> float:
    """How much gentler than its weights the law is made for a camera of angle noise ``noise`` (rad): the swing's
    scales grow with the noise beyond ``QUIET_CAMERA``, so that a noisy camera does not move the axes by its noise."""
    return max(1.0, noise / QUIET_CAMERA)


def regulator(p: CraneParams, noise: float = 0.0) -> np.ndarray:
    """The law's gain K (1 x 8) over ``sway_model.control``'s state (see the module docstring), for a camera of
    angle noise ``noise`` (rad, ``gentleness``)."""
    model = sway_model.control(p)
    load_scale, second_scale = LOAD_SCALE * gentleness(noise), SECOND_MODE_SCALE * gentleness(noise)
    offset = np.zeros(8)
    offset[4:6] = sway_model.load_offset_row(p)
    rate = np.zeros(8)
    rate[6:8] = sway_model.load_offset_row(p)
    unit = np.eye(8)
    Q = (np.outer(offset, offset) / load_scale ** 2
         + np.outer(rate, rate) / (OMEGA_SCALE * load_scale) ** 2
         + np.outer(unit[0], unit[0]) / POSITION_SCALE ** 2
         + np.outer(unit[1], unit[1]) / VELOCITY_SCALE ** 2
         + np.outer(unit[2], unit[2]) / ACCELERATION_SCALE ** 2)
    # the second mode's own coordinate: the load's offset hardly sees it, its swing does
    second, omega2 = _second_mode(p)
    modal, modal_rate = np.zeros(8), np.zeros(8)
    modal[4:6], modal_rate[6:8] = second, second / omega2
    Q += (np.outer(modal, modal) + np.outer(modal_rate, modal_rate)) / second_scale ** 2
    R = np.array([[1.0 / JERK_SCALE ** 2]])
    P = solve_continuous_are(model.A, model.B, Q, R)
    return np.linalg.solve(R, model.B.T @ P)


def _second_mode(p: CraneParams) -> tuple[np.ndarray, float]:
    """The row over [theta1, theta2] that gives the fast mode's coordinate (scaled to the load's offset it makes),
    and its frequency (rad/s)."""
    from ..planning.model import linearized_matrices
    M, K, _ = linearized_matrices(p)
    values, vectors = np.linalg.eig(np.linalg.solve(M, K))
    order = np.argsort(values.real)
    vectors = vectors[:, order].real
    rows = np.linalg.inv(vectors)  # q = vectors @ eta: eta = rows @ q
    scale = abs(sway_model.load_offset_row(p) @ vectors[:, 1])
    return rows[1] * scale, float(np.sqrt(values.real[order][1]))


def estimator_gain(p: CraneParams, noise: float, period: float = MEASUREMENT_PERIOD) -> np.ndarray:
    """The steady-state Kalman gain L (6 x 2) of ``sway_model.estimation`` measured every ``period`` s with
    angle noise ``noise`` (rad; a floor of 0.1 mrad keeps it finite)."""
    model = sway_model.estimation(p)
    Phi, _ = model.discretized(period)
    W = np.zeros((6, 6))
    W[3, 3] = W[4, 4] = SWING_RATE ** 2 * period
    W[5, 5] = DISTURBANCE_RATE ** 2 * period
    R = np.eye(2) * max(noise, 1e-4) ** 2
    P = solve_discrete_are(Phi.T, model.C.T, W, R)
    return P @ model.C.T @ np.linalg.inv(model.C @ P @ model.C.T + R)


def design(p: CraneParams, tick: float, noise: float) -> PlaneDesign:
    """One plane's ``PlaneDesign`` for the plant ``p`` (its L1) at the streamer's ``tick`` (s)."""
    Phi, Gamma = sway_model.estimation(p).discretized(tick)
    steps = int(round(HISTORY / tick)) + 1
    powers = np.empty((steps, 6, 6))
    powers[0] = np.eye(6)
    for k in range(1, steps):
        powers[k] = Phi @ powers[k - 1]
    return PlaneDesign(p.L1, tick, regulator(p, noise), Phi, Gamma, estimator_gain(p, noise), powers,
                       sway_model.equilibrium(p, 1.0))


class Schedule:
    """``PlaneDesign``s over the cable lengths from ``shortest`` to ``longest`` (m; one if they are equal), made
    once; ``at(L1)`` the nearest."""

    def __init__(self, p: CraneParams, tick: float, noise: float, shortest: float | None = None,
                 longest: float | None = None):
        shortest, longest = shortest or p.L1, longest or p.L1
        lengths = [shortest]
        while lengths[-1] * (1.0 + LENGTH_STEP) < longest:
            lengths.append(lengths[-1] * (1.0 + LENGTH_STEP))
        if longest > shortest:
            lengths.append(longest)
        self.lengths = lengths
        self.designs = [design(dataclasses.replace(p, L1=L), tick, noise) for L in lengths]

    def at(self, L1: float) -> PlaneDesign:
        k = bisect.bisect_left(self.lengths, L1)
        if k == 0:
            return self.designs[0]
        if k == len(self.lengths):
            return self.designs[-1]
        return self.designs[k] if self.lengths[k] - L1 < L1 - self.lengths[k - 1] else self.designs[k - 1]
