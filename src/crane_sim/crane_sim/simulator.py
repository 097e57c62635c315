"""Fixed-step simulation of the crane: Eqs. 18-19 driven through the axis servo of Eq. 6.

State of one plant: rows by name (``Layout``): the cart's ``y, v, a``
(position, velocity, acceleration), the swing's ``theta1, theta2, dtheta1,
dtheta2``, then each further axis's three (the hoist's ``L1, dL1, ddL1``).
Each axis's acceleration follows its reference through a first-order servo
``tau a' + a = a_ref`` (Eq. 6; ``tau = 0`` means ``a = a_ref``), ``SERVOS``
says which rows and which time constant are whose.

Within one step the reference is linear in time (or constant, ``zoh``), so the
servo and each axis's kinematics have a closed form; it is evaluated at the RK4
stage times and the swing (Eqs. 18-19, ``crane_sim.dynamics``) is integrated
by classic RK4. Each axis is therefore exact for every ``tau >= 0``, including
``tau`` much smaller than the step, where an explicit integrator of Eq. 6
would blow up.

A disturbance ``w`` (m/s^2 per horizontal direction: wind, gusts) is a horizontal
acceleration field acting on both masses (a force ``m w`` on each): in the frame
of the suspension point the masses feel ``-m a`` and ``m w``, so for the swing
it is the same as the suspension point accelerating by ``a - w``. The axes are
servo-driven and the field does not reach them: each axis's rows are unchanged.

Everything is vectorized over a batch of plants (numpy arrays of shape
``(n,)``); the batch path (:func:`simulate`) and the streaming path
(:class:`CraneSimulator`, for the real-time node) share one step function.
No ROS import here.

Why one module: both paths use the private stepper and the
internal state form (``_Stepper``, ``_to_internal``/``_to_public``);
splitting them apart would make those private pieces public API.
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields

import numpy as np

from crane_msgs_py.crane.axes import AXIS_NAMES, axis, check_axes
from crane_msgs_py.crane.geometry import load_swing
from crane_msgs_py.crane.params import (
    PARAMETER_NAMES,
    CraneParams,
    ParameterError,
    check_choice,
    check_count,
    check_parameter,
    check_positive,
)
from crane_msgs_py.messages.names import BRIDGE_JOINT, CART_JOINT, HOIST_JOINT

from .dynamics import SwingModel, hoisting_accelerations
from .spatial import SPATIAL_SWING_NAMES, SpatialPendulum


@dataclass(frozen=True)
class AxisServo:
    """What the simulator knows of an axis: its state rows (position, rate, and acceleration: the output
    of its servo, Eq. 6), the plant parameter of its servo's time constant, and the plant parameter it starts
    at under an acceleration reference (None: 0)."""

    rows: tuple[str, str, str]
    tau: str
    start: str | None = None


#: The simulator's physics of each axis of ``crane_msgs_py.crane.axes``, by axis name.
SERVOS = {CART_JOINT: AxisServo(('y', 'v', 'a'), 'tau'),
          BRIDGE_JOINT: AxisServo(('yb', 'vb', 'ab'), 'tau'),
          HOIST_JOINT: AxisServo(('L1', 'dL1', 'ddL1'), 'tau_hoist', start='L1')}
#: The swing's rows: the cable angles and their rates.
SWING_NAMES = ('theta1', 'theta2', 'dtheta1', 'dtheta2')
#: With a bridge, the out-of-plane angles and their rates, after every axis's rows.
OUT_OF_PLANE_NAMES = ('phi1', 'phi2', 'dphi1', 'dphi2')
#: Names of the state rows of the cart alone, in order (``CraneState``'s).
STATE_NAMES = (*SERVOS[CART_JOINT].rows, *SWING_NAMES)
#: Names of the hoist's state rows, after ``STATE_NAMES`` when hoisting: the upper cable's length,
#: its rate and acceleration.
HOIST_STATE_NAMES = SERVOS[HOIST_JOINT].rows


def joint_names_of(axes) -> tuple:
    """The joints the ROS node publishes for ``axes``: each axis's position, then theta1 and theta2, and with a
    bridge phi1 and phi2 (contract "The spatial crane")."""
    swing = SPATIAL_SWING_NAMES if BRIDGE_JOINT in axes else SPATIAL_SWING_NAMES[:2]
    return (*(axis(a).sim_joint for a in axes), *swing)


#: Joint names the ROS node publishes (positions y, theta1, theta2) ...
JOINT_NAMES = joint_names_of((CART_JOINT,))
#: ... and with a hoist (its position: the upper cable's length L1).
HOIST_JOINT_NAMES = joint_names_of((CART_JOINT, HOIST_JOINT))
INTERPOLATIONS = ('zoh', 'linear')
SOURCES = ('acceleration', 'position')


#: Plant parameters a plant may leave out (those of the hoist), with their defaults.
_OPTIONAL = {'tau_hoist': CraneParams.tau_hoist}


class SimulationError(ValueError):
    """A simulation request is malformed; the message names the argument and why."""


@dataclass(frozen=True)
class Layout:
    """Which row of a state array holds what, for a crane with ``axes`` (names of ``crane_msgs_py.crane.axes``, in
    its order): the first axis's rows, the swing's, then each further axis's."""

    axes: tuple[str, ...] = (CART_JOINT,)
    names: tuple[str, ...] = field(init=False)

    def __post_init__(self):
        axes = check_axes(self.axes, 'axes')
        object.__setattr__(self, 'axes', axes)
        object.__setattr__(self, 'names', (*SERVOS[axes[0]].rows, *SWING_NAMES,
                                           *(name for a in axes[1:] for name in SERVOS[a].rows),
                                           *(OUT_OF_PLANE_NAMES if BRIDGE_JOINT in axes else ())))

    def __len__(self) -> int:
        return len(self.names)

    def index(self, name: str) -> int:
        """The row of the state ``name``."""
        return self.names.index(name)

    def rows(self, axis_name: str) -> tuple[int, int, int]:
        """The rows of the axis's position, rate and acceleration."""
        return tuple(self.index(name) for name in SERVOS[axis_name].rows)

    @property
    def angles(self) -> slice:
        """The rows of (theta1, theta2): of (theta1, phi) in the stepper's internal form."""
        return slice(self.index('theta1'), self.index('theta2') + 1)

    @property
    def rates(self) -> slice:
        """The rows of (dtheta1, dtheta2): of (dtheta1, dphi) in the internal form."""
        return slice(self.index('dtheta1'), self.index('dtheta2') + 1)


# --------------------------------------------------------------------------- plants

@dataclass(frozen=True)
class PlantBatch:
    """Parameters of ``n`` plants as arrays of shape ``(n,)`` (SI units, see CraneParams)."""

    L1: np.ndarray
    L2: np.ndarray
    m1: np.ndarray
    m2: np.ndarray
    g: np.ndarray
    tau: np.ndarray
    c1: np.ndarray
    c2: np.ndarray
    tau_hoist: np.ndarray

    @classmethod
    def of(cls, plants) -> 'PlantBatch':
        """From one params object / mapping, or a sequence of them (validated).

        Anything with attributes (or keys) ``L1 L2 m1 m2 g tau c1 c2`` is accepted,
        e.g. ``crane_msgs_py.crane.params.CraneParams``; ``tau_hoist`` defaults to CraneParams'.
        """
        if isinstance(plants, PlantBatch):
            return plants
        single = isinstance(plants, Mapping) or not isinstance(plants, Sequence)
        members = [plants] if single else list(plants)
        if not members:
            raise ParameterError('plants: need at least one plant')
        columns = {name: [] for name in PARAMETER_NAMES}
        for i, p in enumerate(members):
            for name in PARAMETER_NAMES:
                try:
                    value = p[name] if isinstance(p, Mapping) else getattr(p, name)
                except (KeyError, AttributeError):
                    if name not in _OPTIONAL:
                        raise ParameterError(f'plant {i} has no parameter {name}') from None
                    value = _OPTIONAL[name]
                columns[name].append(check_parameter(name, value))
        return cls(**{name: np.array(v) for name, v in columns.items()})

    def __len__(self) -> int:
        return self.L1.shape[0]

    def repeat(self, n: int) -> 'PlantBatch':
        """A batch of ``n`` copies of this single plant."""
        return PlantBatch(**{f.name: np.repeat(getattr(self, f.name), n) for f in fields(self)})

    def swing_model(self) -> SwingModel:
        return SwingModel(self.L1, self.L2, self.m1, self.m2, self.g, self.c1, self.c2)

    def at(self, i: int) -> 'PlantBatch':
        """Plant ``i`` as a batch of one."""
        return PlantBatch(**{f.name: getattr(self, f.name)[i:i + 1] for f in fields(self)})

    def member(self, i: int) -> dict:
        """Plant ``i`` as a plain dict of floats."""
        return {f.name: float(getattr(self, f.name)[i]) for f in fields(self)}


# --------------------------------------------------------------------------- servo (Eq. 6)

_SERIES_TERMS = 18


def _integrated_exponentials(x):
    """F_k(x) = E_k(x) / x^k for k = 0..4, where E_k is the k-fold integral of e^-u over [0, x].

    E_0 = e^-x, E_1 = 1 - e^-x, E_2 = x - 1 + e^-x, ...; the F_k are bounded
    (F_k(0) = 1/k!). Below x = 1 the closed forms cancel catastrophically, so
    the power series F_k = sum_i (-x)^i / (i+k)! is used there.
    """
    x = np.asarray(x, dtype=float)
    small = x < 1.0
    xs = np.where(small, x, 0.0)
    xl = np.where(small, 1.0, x)
    out = np.empty((5,) + x.shape)
    out[0] = np.exp(-x)
    e = np.exp(-xl)
    for k in range(1, 5):
        e = xl ** (k - 1) / math.factorial(k - 1) - e          # E_k from E_(k-1)
        series = np.zeros_like(xs)
        for i in reversed(range(_SERIES_TERMS)):               # Horner
            series = 1.0 / math.factorial(i + k) - xs * series
        out[k] = np.where(small, series, e / xl ** k)
    return out


def servo_weights(tau, h: float) -> np.ndarray:
    """Exact one-step solution of Eq. 6 and the cart kinematics for a linear reference.

    Over a step of length ``h`` with ``a_ref(s) = r0 + (r1 - r0) s/h`` and the
    cart starting at ``(y0, v0, a0)``, the exact solution is linear in
    ``(a0, r0, r1)``. Returns weights ``W`` of shape ``(3, 5, n)`` such that
    ``W[0] a0 + W[1] r0 + W[2] r1`` gives, per plant, the rows a(0+), a(h/2),
    a(h), v(h) - v0 and y(h) - y0 - h v0. ``tau = 0`` gives the limit a = a_ref
    (then a(0+) = r0, whatever a0 was).
    """
    tau = np.atleast_1d(np.asarray(tau, dtype=float))
    ideal = tau <= 1e-12 * h            # indistinguishable from tau = 0 at this step
    W = np.zeros((5, 3) + tau.shape)   # (output, input), transposed on return
    W[0, 0] = np.where(ideal, 0.0, 1.0)
    W[0, 1] = 1.0 - W[0, 0]
    for row, s in ((1, 0.5 * h), (2, h)):
        x = s / np.where(ideal, 1.0, tau)
        F = _integrated_exponentials(x)
        H1, H2 = x * F[1], x * F[2]     # E_1 and E_2 / x, both O(1) as x -> inf
        rho = s / h
        W[row, 0] = np.where(ideal, 0.0, F[0])
        W[row, 1] = np.where(ideal, 1.0 - rho, H1 - rho * H2)
        W[row, 2] = np.where(ideal, rho, rho * H2)
    # velocity and position over the whole step: integrals of a(s), with x and F of
    # the loop's last pass (s = h)
    H2, H3, H4 = x * F[2], x * F[3], x * F[4]
    W[3, 0] = np.where(ideal, 0.0, h * F[1])
    W[3, 1] = h * np.where(ideal, 0.5, H2 - H3)
    W[3, 2] = h * np.where(ideal, 0.5, H3)
    W[4, 0] = np.where(ideal, 0.0, h * h * F[2])
    W[4, 1] = h * h * np.where(ideal, 1.0 / 3.0, H3 - H4)
    W[4, 2] = h * h * np.where(ideal, 1.0 / 6.0, H4)
    return np.ascontiguousarray(W.transpose(1, 0, 2))


# --------------------------------------------------------------------------- the step

# The step integrates the lower cable's absolute angle phi = theta1 + theta2 (and
# its rate) instead of theta2: that is the form SwingModel evaluates without
# re-stacking, and RK4 commutes with linear changes of variables, so the result
# is the same. Rows of the internal state: y, v, a, theta1, phi, dtheta1, dphi.

def _relative_pairs(layout: Layout) -> list[tuple[int, int]]:
    """(upper, lower) rows of each angle and rate whose lower cable's value is relative to the upper's."""
    pairs = [('theta1', 'theta2'), ('dtheta1', 'dtheta2')]
    if 'phi1' in layout.names:
        pairs += [('phi1', 'phi2'), ('dphi1', 'dphi2')]
    return [(layout.index(a), layout.index(b)) for a, b in pairs]


def _to_internal(x, layout: Layout):
    """The stepper's form of public states ``x``: the lower cable's absolute angles (theta1 + theta2, and
    phi1 + phi2 with a bridge) and their rates in place of the relative ones."""
    x = np.array(x, dtype=float)
    for upper, lower in _relative_pairs(layout):
        x[lower] += x[upper]
    return x


def _to_public(x, layout: Layout):
    x = np.array(x, dtype=float)
    for upper, lower in _relative_pairs(layout):
        x[lower] -= x[upper]
    return x


class _Stepper:
    """The one step shared by :func:`simulate` and :class:`CraneSimulator`, for a batch of plants.

    Each axis (y, v, a; L1, L1', L1'') takes the exact solution of its servo
    (:func:`servo_weights`); the swing takes a classic RK4 step fed with the
    cart's exact acceleration (and with a hoist the rope's exact length and
    its rates) at the stage times 0, h/2, h. RK4 is written for the
    second-order system q'' = f(q, q', a) (angles q, rates v): the stages'
    angle slopes are the stages' rates, so only f is evaluated.
    """

    def __init__(self, plants: PlantBatch, h: float, layout: Layout):
        self.layout = layout
        #: per axis, in ``layout.axes`` order: its rows (position, rate, acceleration) and servo weights
        self._servos = [(layout.rows(a), servo_weights(getattr(plants, SERVOS[a].tau), h)) for a in layout.axes]
        self._cart = layout.axes.index(CART_JOINT)  # the swing's driving acceleration is the cart's
        self._angles, self._rates = layout.angles, layout.rates
        self.model = plants.swing_model()
        # 0-d arrays: numpy multiplies by them faster than by Python floats,
        # which matters at a few dozen plants where every numpy call is pure overhead
        self._h, self._h2, self._h6 = np.array(h), np.array(0.5 * h), np.array(h / 6.0)
        self._hoist = None
        if HOIST_JOINT in layout.axes:
            # the hoist's servo over the step's first half too: the RK4 midpoint needs L1 there
            k = layout.axes.index(HOIST_JOINT)
            self._hoist = (k, layout.rows(HOIST_JOINT), servo_weights(plants.tau_hoist, 0.5 * h))
            self._constants = (plants.L2, plants.m1, plants.m2, plants.g, plants.c1, plants.c2)

    def _hoist_stages(self, x, c, r0, r1):
        """The swing's right-hand side at the RK4 stage times 0, h/2, h with the hoist's exact motion
        (``c``: its servo's rows over the whole step)."""
        k, (L, dL, ddL), Wh = self._hoist
        h, h2 = self._h, self._h2
        r0, r1 = r0[k], r1[k]
        half = Wh[0] * x[ddL] + Wh[1] * r0 + Wh[2] * (0.5 * (r0 + r1))
        lengths = (x[L], x[L] + h2 * x[dL] + half[4], x[L] + h * x[dL] + c[4])
        rates = (x[dL], x[dL] + half[3], x[dL] + c[3])
        constants = self._constants

        def at(j):
            return lambda q, v, a: hoisting_accelerations(q, v, a, lengths[j], rates[j], c[j], *constants)

        return at(0), at(1), at(2)

    def step(self, x, r0, r1, w=None):
        """Internal states ``x`` one step later, each axis's reference acceleration going linearly from
        ``r0[k]`` to ``r1[k]`` (``r0``, ``r1``: one row per axis of the layout, in its order); ``w``: the
        disturbance along x at the stage times 0, h/2, h (3, n), or None (none)."""
        h, h2, h6 = self._h, self._h2, self._h6
        out = np.empty_like(x)
        ends = []
        for k, ((p, v, a), W) in enumerate(self._servos):
            c = W[0] * x[a] + W[1] * r0[k] + W[2] * r1[k]  # a(0+), a(h/2), a(h), v and position increments
            out[p] = x[p] + h * x[v] + c[4]
            out[v] = x[v] + c[3]
            out[a] = c[2]
            ends.append(c)
        c = ends[self._cart]
        if w is not None:  # the swing feels the cart's acceleration less the field's (module docstring)
            c = (c[0] - w[0], c[1] - w[1], c[2] - w[2])
        if self._hoist is not None:
            f_begin, f_mid, f_end = self._hoist_stages(x, ends[self._hoist[0]], r0, r1)
        else:
            f_begin = f_mid = f_end = self.model.accelerations
        q, v = x[self._angles], x[self._rates]
        f1 = f_begin(q, v, c[0])
        v2 = v + h2 * f1
        f2 = f_mid(q + h2 * v, v2, c[1])
        v3 = v + h2 * f2
        f3 = f_mid(q + h2 * v2, v3, c[1])
        v4 = v + h * f3
        f4 = f_end(q + h * v3, v4, c[2])
        v2 += v3  # v + h/6 (f1 + 2 f2 + 2 f3 + f4), and q likewise with the stage rates
        v2 += v2
        v2 += v + v4
        np.add(q, h6 * v2, out=out[self._angles])
        f2 += f3
        f2 += f2
        f2 += f1 + f4
        np.add(v, h6 * f2, out=out[self._rates])
        return out


# --------------------------------------------------------------------------- references

def interpolate(t_ref, values, t, interpolation: str = 'linear'):
    """Reference at times ``t`` as an axis controller sees it; ``values`` has shape (..., len(t_ref)).

    ``zoh`` holds the last sample (t_ref[k] <= t); ``linear`` interpolates
    between samples. Before t_ref[0] the first value, after t_ref[-1] the last
    value holds.
    """
    t_ref = np.asarray(t_ref, dtype=float)
    values = np.asarray(values, dtype=float)
    t = np.asarray(t, dtype=float)
    check_choice('interpolation', interpolation, INTERPOLATIONS, SimulationError)
    k = np.searchsorted(t_ref, t, side='right') - 1
    if interpolation == 'zoh' or t_ref.size == 1:
        return values[..., np.clip(k, 0, t_ref.size - 1)]
    k = np.clip(k, 0, t_ref.size - 2)
    w = np.clip((t - t_ref[k]) / (t_ref[k + 1] - t_ref[k]), 0.0, 1.0)
    return values[..., k] * (1.0 - w) + values[..., k + 1] * w


def second_differences(t, p):
    """Central second differences of positions ``p`` (..., m) at the interior times t[1:-1].

    Exact for quadratics, also on an uneven grid.
    """
    h = np.diff(t)
    slope = np.diff(p, axis=-1) / h
    return 2.0 * np.diff(slope, axis=-1) / (h[:-1] + h[1:])


def acceleration_from_positions(t_ref, positions):
    """Acceleration samples a controller that only receives positions reconstructs.

    The second difference around sample k needs sample k+1, so it is known
    (and applied) from t_ref[k+1] on: the reconstruction is causal and lags
    one sample. The positions are at rest before t_ref[0] and after t_ref[-1]
    (the first and last intervals mirrored), so the reconstructed motion
    starts and ends at rest, and with ``linear`` interpolation on an even grid
    it ends exactly at the last position.

    Returns (times, accelerations) with len(t_ref) + 2 samples: 0 at t_ref[0],
    the second differences at t_ref[1:] and one mirrored interval after the
    end, then 0 one interval later.
    """
    t_ref = np.asarray(t_ref, dtype=float)
    positions = np.asarray(positions, dtype=float)
    h0, hn = t_ref[1] - t_ref[0], t_ref[-1] - t_ref[-2]
    t_pad = np.concatenate(([t_ref[0] - h0], t_ref, [t_ref[-1] + hn]))
    p_pad = np.concatenate((positions[..., :1], positions, positions[..., -1:]), axis=-1)
    zero = np.zeros(positions.shape[:-1] + (1,))
    t_acc = np.concatenate((t_pad[1:], [t_pad[-1] + hn]))
    return t_acc, np.concatenate((zero, second_differences(t_pad, p_pad), zero), axis=-1)


# --------------------------------------------------------------------------- batch simulation

@dataclass(frozen=True, eq=False)
class SimResult:
    """Simulated trajectories: ``t`` (n,) and an (n_batch, n) array per state row (``states``, by the names of
    the simulation's ``Layout``; also as attributes: ``result.theta1``), plus the plants.

    The rows of an axis the simulation did not have read as None (``result.L1`` without a hoist)."""

    t: np.ndarray
    states: dict
    plants: PlantBatch

    def __getattr__(self, name):
        if name != 'states' and name in self.states:
            return self.states[name]
        if any(name in servo.rows for servo in SERVOS.values()):
            return None
        raise AttributeError(name)

    @property
    def load_excursion(self) -> np.ndarray:
        """Horizontal offset (m) of the load from its rest position below the cart, (n_batch, n): signed
        (positive when it lags) for the planar crane, with a bridge its norm (contract)."""
        L1 = self.plants.L1[:, None] if self.L1 is None else self.L1
        return load_swing(self.theta1, self.theta2, L1, self.plants.L2[:, None], self.states.get('phi1'),
                          self.states.get('phi2'))

    def members(self, rows) -> 'SimResult':
        """The batch members ``rows`` (a slice or indices) as a result of their own."""
        plants = PlantBatch(**{f.name: getattr(self.plants, f.name)[rows] for f in fields(PlantBatch)})
        return SimResult(self.t, {name: x[rows] for name, x in self.states.items()}, plants)

    def __len__(self) -> int:
        return len(self.plants)


def _check_reference(t_ref, reference, n_plants):
    t_ref = np.asarray(t_ref, dtype=float)
    reference = np.asarray(reference, dtype=float)
    if t_ref.ndim != 1 or t_ref.size == 0:
        raise SimulationError(f't_ref must be a non-empty 1-D array, got shape {t_ref.shape}')
    if not np.all(np.isfinite(t_ref)):
        raise SimulationError('t_ref must be finite')
    if np.any(np.diff(t_ref) <= 0.0):
        raise SimulationError('t_ref must be strictly increasing')
    if reference.ndim not in (1, 2) or reference.shape[-1] != t_ref.size:
        raise SimulationError(
            f'reference must have shape ({t_ref.size},) or (n_batch, {t_ref.size}), got {reference.shape}')
    if not np.all(np.isfinite(reference)):
        raise SimulationError('reference must be finite')
    rows = 1 if reference.ndim == 1 else reference.shape[0]
    if rows != 1 and n_plants != 1 and rows != n_plants:
        raise SimulationError(f'reference has {rows} rows but there are {n_plants} plants')
    n = max(rows, n_plants)
    return t_ref, np.broadcast_to(reference.reshape(rows, -1), (n, t_ref.size))


def _references(references) -> tuple[tuple, dict]:
    """The axes' names in ``AXES`` order and their checked references, all of one number of rows."""
    refs = dict(references) if isinstance(references, Mapping) else {CART_JOINT: references}
    unknown = [name for name in refs if name not in AXIS_NAMES]
    if unknown:
        raise SimulationError(f'references: no axis {", ".join(map(str, unknown))}; the axes are '
                              f'{", ".join(AXIS_NAMES)}')
    try:
        axes = check_axes([a for a in AXIS_NAMES if a in refs], 'references')
    except ParameterError as exc:
        raise SimulationError(str(exc)) from None
    return axes, refs


def _disturbance_stages(disturbance, t, n: int, spatial: bool):
    """``simulate``'s ``disturbance`` at every step's RK4 stage times 0, h/2, h of the grid ``t``: an array
    (steps, 3, 2, n) of (x, y) per plant, or None."""
    if disturbance is None:
        return None
    times = np.concatenate((t, 0.5 * (t[:-1] + t[1:])))  # the grid, then each step's midpoint
    if callable(disturbance):
        w = np.asarray(disturbance(times), dtype=float)
        if w.shape not in ((2, times.size), (2, n, times.size)):
            raise SimulationError(f'disturbance(t) must return shape (2, {times.size}) or (2, {n}, {times.size}) '
                                  f'for {times.size} times, got {w.shape}')
        w = np.broadcast_to(w.reshape(2, -1, times.size), (2, n, times.size))
    else:
        w = np.asarray(disturbance, dtype=float)
        if w.shape not in ((2,), (2, n)):
            raise SimulationError(f'a constant disturbance must be (ax, ay) or shape (2, {n}), got {w.shape}')
        w = np.broadcast_to(w.reshape(2, -1, 1), (2, n, times.size))
    if not np.all(np.isfinite(w)):
        raise SimulationError('disturbance must be finite')
    if not spatial and np.any(w[1] != 0.0):
        raise SimulationError('disturbance: a y component needs the bridge (the planar crane swings in x-z only)')
    k = t.size
    stages = np.stack((w[..., :k - 1], w[..., k:], w[..., 1:k]))  # (3, 2, n, steps)
    return np.ascontiguousarray(stages.transpose(3, 0, 1, 2))


def simulate(t_ref, references, plants, *, dt: float = 1e-3, t_end: float | None = None,
             interpolation: str = 'linear', source: str = 'acceleration', record_every: int = 1,
             initial_state=None, rest_dt: float | None = None, disturbance=None) -> SimResult:
    """Simulate a batch of plants driven by sampled axis references.

    Args:
        t_ref: sample times (s), strictly increasing; the simulation starts at t_ref[0].
        references: the cart's reference samples, or the references of several axes by axis name
            (``crane_msgs_py.crane.axes``: ``{'cart': ..., 'hoist': ...}``; the cart's is always needed): each an
            acceleration (m/s^2) or position (m) per sample, shape (m,) for all plants or (n_batch, m),
            one row per plant. An axis is simulated if it has a reference (the hoist: the upper cable's
            length L1 follows its reference through the servo ``tau_hoist``; the state then has the rows
            ``HOIST_STATE_NAMES`` too).
        plants: one params object (attributes or keys L1 L2 m1 m2 g tau c1 c2) or a
            sequence; a single plant with an (n_batch, m) reference is repeated.
        dt: integration step (s).
        t_end: last time (default t_ref[-1]); the grid t_ref[0] + k dt runs up to
            the first point >= t_end. After t_ref[-1] the last value holds
            (the last position, or the last acceleration).
        interpolation: ``zoh`` (hold the last sample) or ``linear``.
        source: ``acceleration`` (use the samples) or ``position`` (reconstruct
            the acceleration causally by finite differences,
            :func:`acceleration_from_positions`).
        record_every: keep every k-th step (the last step is always kept).
        initial_state: (r,) or (n_batch, r) state, the rows of ``Layout(axes).names`` at t_ref[0];
            default: at rest at the first reference value (each axis at its first position for
            ``position``, else the cart at 0 and the hoist at each plant's L1; servos settled, no swing).
        rest_dt: step (s) once the grid has passed the last reference sample,
            where the input holds (default ``dt``): a few times ``dt`` keeps
            RK4 as accurate on the free swing (its error grows as (omega h)^5,
            ~1e-9 of the swing per 5 ms step at 9 rad/s) for a fraction of
            the steps; the grid then continues in steps of ``rest_dt``.
        disturbance: a horizontal acceleration (m/s^2) acting on both masses, as wind and gusts do
            (``crane_sim.disturbances``): for the swing the same as the suspension point accelerating by its
            negative, the axes (servo-driven) unaffected. None (none); a constant (ax, ay), or of shape (2,
            n_batch) one per plant; or a callable ``w(t)`` of an array of times ``t`` (s, shape (k,)) returning
            the acceleration there, shape (2, k) or (2, n_batch, k): rows x and y. It is called once, with the
            grid's times and each step's midpoint (RK4 evaluates it at 0, h/2 and h of every step), so a
            sampled path interpolates its samples there (``disturbances.SampledDisturbance``). The y row needs
            a bridge (the planar crane swings in the x-z plane alone): elsewhere it must be 0. The default
            start hangs straight down whatever the disturbance, as a wind rising at t_ref[0].
    """
    check_choice('interpolation', interpolation, INTERPOLATIONS, SimulationError)
    check_choice('source', source, SOURCES, SimulationError)
    p = PlantBatch.of(plants)
    axes, refs = _references(references)
    layout = Layout(axes)
    checked = {}
    for name in axes:
        try:
            t_ref, checked[name] = _check_reference(t_ref, refs[name], len(p))
        except SimulationError as exc:
            raise SimulationError(f'references[{name!r}]: {exc}' if len(axes) > 1 else str(exc)) from None
    rows = max(r.shape[0] for r in checked.values())
    for name, r in checked.items():
        if r.shape[0] not in (1, rows):
            raise SimulationError(f'references[{name!r}] has {r.shape[0]} rows, another axis {rows}')
    ref = np.concatenate([np.broadcast_to(checked[name], (rows, t_ref.size)) for name in axes])  # axis by axis
    if len(p) == 1 and rows > 1:
        p = p.repeat(rows)
    n = len(p)
    dt = check_positive('dt', dt)
    t0 = float(t_ref[0])
    t_end = float(t_ref[-1]) if t_end is None else float(t_end)
    if not math.isfinite(t_end) or t_end < t0:
        raise SimulationError(f't_end must be finite and >= t_ref[0] = {t0}, got {t_end}')
    check_count('record_every', record_every, SimulationError)
    if source == 'position':
        if t_ref.size < 2:
            raise SimulationError('a position reference needs at least 2 samples')
        starts = ref[:, 0]
        t_acc, acc = acceleration_from_positions(t_ref, ref)
    else:
        starts = np.concatenate([np.zeros(n) if SERVOS[name].start is None else getattr(p, SERVOS[name].start)
                                 for name in axes])
        t_acc, acc = t_ref, ref

    rest_dt = dt if rest_dt is None else check_positive('rest_dt', rest_dt)
    n_steps = max(0, math.ceil((t_end - t0) / dt - 1e-9))
    if rest_dt != dt:  # fine steps up to the first grid point at or past the last sample, then rest_dt
        n_fine = min(n_steps, max(0, math.ceil((float(t_acc[-1]) - t0) / dt - 1e-9)))
        t_fine = t0 + dt * n_fine
        n_rest = max(0, math.ceil((t_end - t_fine) / rest_dt - 1e-9))
        t = np.concatenate([t0 + dt * np.arange(n_fine + 1), t_fine + rest_dt * np.arange(1, n_rest + 1)])
        n_steps = n_fine + n_rest
    else:
        n_fine = n_steps
        t = t0 + dt * np.arange(n_steps + 1)
    t_moving = t[:n_fine + 1]
    per_axis = (-1, len(axes), n)  # each step's references: one row per axis
    if interpolation == 'linear':
        r = np.ascontiguousarray(interpolate(t_acc, acc, t_moving, 'linear').T).reshape(per_axis)
        r_begin, r_end = r[:-1], r[1:]
    else:   # the held value at mid-step is robust to rounding of knots that fall on the grid
        r_begin = r_end = np.ascontiguousarray(
            interpolate(t_acc, acc, t_moving[:-1] + 0.5 * dt, 'zoh').T).reshape(per_axis)
    r_rest = np.ascontiguousarray(acc[:, -1]).reshape(per_axis[1:])

    nrows = len(layout)
    if initial_state is None:
        a0 = interpolate(t_acc, acc, t0, interpolation).reshape(per_axis[1:])
        x = np.zeros((nrows, n))
        for k, name in enumerate(axes):
            position, _, acceleration = layout.rows(name)
            x[position], x[acceleration] = starts[k * n:(k + 1) * n], a0[k]
    else:
        s = np.asarray(initial_state, dtype=float)
        if s.shape not in ((nrows,), (n, nrows)) or not np.all(np.isfinite(s)):
            raise SimulationError(f'initial_state must be finite with shape ({nrows},) or ({n}, {nrows}), '
                                  f'got {s.shape}')
        x = np.array(np.broadcast_to(s, (n, nrows)).T)
    x = _to_internal(x, layout)

    keep = [k % record_every == 0 or k == n_steps for k in range(n_steps + 1)]
    out = np.empty((sum(keep), nrows, n))
    out[0] = x
    j = 1
    # the planar crane's numpy batch, or with a bridge each plant's spatial step in plain floats
    spatial = BRIDGE_JOINT in axes
    kind = _PointBatch if spatial else _Stepper
    stepper = kind(p, dt, layout)
    rest = kind(p, rest_dt, layout) if n_steps > n_fine else None
    ws = _disturbance_stages(disturbance, t, n, spatial)
    if ws is not None and not spatial:
        ws = ws[:, :, 0]  # the planar stepper takes x alone
    for k in range(n_steps):
        w = None if ws is None else ws[k]
        x = stepper.step(x, r_begin[k], r_end[k], w) if k < n_fine else rest.step(x, r_rest, r_rest, w)
        if keep[k + 1]:
            out[j] = x
            j += 1
    public = _to_public(out.transpose(1, 2, 0), layout)
    return SimResult(t[np.array(keep)], {name: np.ascontiguousarray(public[i]) for i, name in enumerate(layout.names)},
                     plants=p)


# --------------------------------------------------------------------------- streaming

@dataclass(frozen=True)
class CraneState:
    """State of one plant (SI units); ``theta`` conventions as in Eqs. 18-19."""

    y: float = 0.0
    v: float = 0.0
    a: float = 0.0
    theta1: float = 0.0
    theta2: float = 0.0
    dtheta1: float = 0.0
    dtheta2: float = 0.0

    def as_array(self) -> np.ndarray:
        return np.array([getattr(self, name) for name in STATE_NAMES])


class _PointStepper:
    """One plant's step for the real-time simulator, in plain floats: each axis's servo exactly
    (:func:`servo_weights`), the swing by RK4 on the spatial model (``crane_sim.spatial``) fed with the
    cart's and the bridge's exact accelerations and the hoist's exact length at the stage times 0, h/2, h.

    The same scheme as ``_Stepper`` (whose planar model it reduces to with no bridge: the two
    cross-check to rounding), at a fraction of its cost for one plant."""

    def __init__(self, plants: PlantBatch, h: float, axes: tuple):
        self.h = h
        self.model = SpatialPendulum(*(float(getattr(plants, n)[0]) for n in ('L2', 'm1', 'm2', 'g', 'c1', 'c2')))
        self.L1 = float(plants.L1[0])

        def weights(tau, step):
            return [[float(w) for w in row] for row in servo_weights(tau, step)[:, :, 0]]

        self.servos = [weights(getattr(plants, SERVOS[a].tau), h) for a in axes]
        self.cart = axes.index(CART_JOINT)
        self.bridge = axes.index(BRIDGE_JOINT) if BRIDGE_JOINT in axes else None
        self.hoist = axes.index(HOIST_JOINT) if HOIST_JOINT in axes else None
        if self.hoist is not None:  # the hoist's servo over the first half too: RK4's midpoint needs L1 there
            self.hoist_half = weights(plants.tau_hoist, 0.5 * h)

    def step(self, axes: list, q: list, v: list, r0, r1, w=None) -> None:
        """Advance ``axes`` (per axis [position, rate, acceleration]) and the swing's absolute angles ``q``
        and rates ``v`` in place by one step, each axis's reference acceleration going from r0[k] to r1[k];
        ``w``: the disturbance (x, y) at the stage times 0, h/2, h, or None (none)."""
        h = self.h
        hoisted = tuple(axes[self.hoist]) if self.hoist is not None else None  # (L1, L1', L1'') before the step
        ends = []
        for k, W in enumerate(self.servos):
            x = axes[k]
            a, b, c = x[2], r0[k], r1[k]
            e = [W[0][j] * a + W[1][j] * b + W[2][j] * c for j in range(5)]
            x[0] += h * x[1] + e[4]
            x[1] += e[3]
            x[2] = e[2]
            ends.append(e)
        ax = ends[self.cart]
        ay = ends[self.bridge] if self.bridge is not None else (0.0, 0.0, 0.0)
        if w is not None:  # the swing feels the suspension point's acceleration less the field's
            ax = [ax[j] - w[j][0] for j in range(3)]
            ay = [ay[j] - w[j][1] for j in range(3)]
        if self.hoist is not None:
            k, W = self.hoist, self.hoist_half
            L, dL, ddL = hoisted
            e, mid = ends[k], 0.5 * (r0[k] + r1[k])
            half = [W[0][j] * ddL + W[1][j] * r0[k] + W[2][j] * mid for j in (3, 4)]
            stage = ((L, dL, e[0]), (L + 0.5 * h * dL + half[1], dL + half[0], e[1]),
                     (L + h * dL + e[4], dL + e[3], e[2]))
        else:
            stage = ((self.L1, 0.0, 0.0),) * 3
        f, h2 = self.model.accelerations, 0.5 * h
        k1 = f(q, v, ax[0], ay[0], *stage[0])
        q2 = [q[j] + h2 * v[j] for j in range(4)]
        v2 = [v[j] + h2 * k1[j] for j in range(4)]
        k2 = f(q2, v2, ax[1], ay[1], *stage[1])
        q3 = [q[j] + h2 * v2[j] for j in range(4)]
        v3 = [v[j] + h2 * k2[j] for j in range(4)]
        k3 = f(q3, v3, ax[1], ay[1], *stage[1])
        q4 = [q[j] + h * v3[j] for j in range(4)]
        v4 = [v[j] + h * k3[j] for j in range(4)]
        k4 = f(q4, v4, ax[2], ay[2], *stage[2])
        h6 = h / 6.0
        for j in range(4):
            q[j] += h6 * (v[j] + 2.0 * (v2[j] + v3[j]) + v4[j])
            v[j] += h6 * (k1[j] + 2.0 * (k2[j] + k3[j]) + k4[j])


class _PointBatch:
    """The spatial crane's step (with a bridge) for a batch in :func:`simulate`: each plant by its own
    :class:`_PointStepper`, on the internal state rows of ``layout`` (the lower cable's absolute angles)."""

    def __init__(self, plants: PlantBatch, h: float, layout: Layout):
        self._steppers = [_PointStepper(plants.at(i), h, layout.axes) for i in range(len(plants))]
        self._axes = [layout.rows(a) for a in layout.axes]
        self._angles = [layout.index(n) for n in ('theta1', 'phi1', 'theta2', 'phi2')]
        self._rates = [layout.index(n) for n in ('dtheta1', 'dphi1', 'dtheta2', 'dphi2')]

    def step(self, x, r0, r1, w=None):
        """As ``_Stepper.step``; ``w``: the disturbance (x, y) at the stage times (3, 2, n), or None."""
        out = np.array(x)
        for i, stepper in enumerate(self._steppers):
            axes = [[float(x[row, i]) for row in rows] for rows in self._axes]
            q, v = [float(x[row, i]) for row in self._angles], [float(x[row, i]) for row in self._rates]
            stepper.step(axes, q, v, r0[:, i], r1[:, i], None if w is None else w[:, :, i].tolist())
            for rows, values in zip(self._axes, axes):
                out[list(rows), i] = values
            out[self._angles, i], out[self._rates, i] = q, v
        return out


@dataclass(frozen=True)
class SpatialSwing:
    """The swing of the spatial crane (contract "The spatial crane"): both cables' in-plane angles
    ``theta1``, ``theta2`` (as in Eqs. 18-19) and out-of-plane angles ``phi1``, ``phi2`` (towards +y), the
    lower cable's relative to the upper's, and their rates."""

    theta1: float = 0.0
    theta2: float = 0.0
    phi1: float = 0.0
    phi2: float = 0.0
    dtheta1: float = 0.0
    dtheta2: float = 0.0
    dphi1: float = 0.0
    dphi2: float = 0.0


class CraneSimulator:
    """One plant stepped in real time, with the scheme of :func:`simulate` on the spatial model.

    Args:
        params: plant parameters (attributes or keys L1 L2 m1 m2 g tau c1 c2).
        dt: integration step (s).
        state: initial :class:`CraneState` (default at rest at y = 0).
        axes: the axes driven (names of ``crane_msgs_py.crane.axes``, the cart first); with the bridge the
            suspension point moves along y too and the load swings in both directions (``phi1``, ``phi2``);
            with the hoist the upper cable's length is an axis too, driven through the servo ``tau_hoist``;
            it starts at the plant's L1 (later changes of L1 do not move it; ``reset`` keeps it where it is).
    """

    def __init__(self, params, dt: float = 1e-3, state: CraneState | None = None, axes=(CART_JOINT,)):
        self.dt = check_positive('dt', dt)
        try:
            self.layout = Layout(tuple(axes))
        except ParameterError as exc:
            raise SimulationError(str(exc)) from None
        self.axes = self.layout.axes
        self.hoist = HOIST_JOINT in self.axes
        self.spatial = BRIDGE_JOINT in self.axes
        self._axes = None
        self._disturbance, self._w = (0.0, 0.0), None
        self.set_params(params)
        self.reset(state)

    def set_params(self, params):
        """Change the plant; takes effect from the next step, the state is kept."""
        plants = PlantBatch.of(params)
        if len(plants) != 1:
            raise ParameterError(f'CraneSimulator simulates one plant, got {len(plants)}')
        self._plants = plants
        self._stepper = _PointStepper(plants, self.dt, self.axes)

    @property
    def params(self) -> dict:
        """The current plant parameters as a dict."""
        return self._plants.member(0)

    def reset(self, state: CraneState | None = None, t: float = 0.0, swing: SpatialSwing | None = None):
        """Back to ``state`` (default at rest at y = 0) at time ``t``, the swing ``swing`` if given (else
        ``state``'s, in the x-z plane); every other axis at rest where it is."""
        s = state or CraneState()
        if not np.all(np.isfinite(s.as_array())):
            raise SimulationError(f'state must be finite, got {state}')
        old = self._axes
        axes = []
        for k, name in enumerate(self.axes):
            if name == CART_JOINT:
                axes.append([s.y, s.v, s.a])
            elif old is not None:
                axes.append([old[k][0], 0.0, 0.0])
            else:
                start = SERVOS[name].start
                axes.append([0.0 if start is None else float(getattr(self._plants, start)[0]), 0.0, 0.0])
        self._axes = axes
        w = swing or SpatialSwing(theta1=s.theta1, theta2=s.theta2, dtheta1=s.dtheta1, dtheta2=s.dtheta2)
        if not all(math.isfinite(getattr(w, f.name)) for f in fields(w)):
            raise SimulationError(f'swing must be finite, got {swing}')
        self._set_swing(w)
        self._t0, self._steps = float(t), 0

    def _set_swing(self, w: SpatialSwing) -> None:
        # the stepper's absolute angles: the lower cable's (theta1 + theta2, phi1 + phi2)
        self._q = [w.theta1, w.phi1, w.theta1 + w.theta2, w.phi1 + w.phi2]
        self._v = [w.dtheta1, w.dphi1, w.dtheta1 + w.dtheta2, w.dphi1 + w.dphi2]

    @property
    def t(self) -> float:
        """Simulated time (s): the reset time plus the steps taken times dt."""
        return self._t0 + self._steps * self.dt

    def step(self, begin, end=None) -> None:
        """Advance one ``dt``; each axis's reference acceleration goes linearly from ``begin`` to ``end``
        (held at ``begin`` if None): one value per axis of ``axes`` in its order (a number alone: the cart's).

        Returns nothing: building :attr:`state` costs more than a step's arithmetic, and
        the real-time loop reads it only at its publish rate, a small share of its steps."""
        r0 = [float(v) for v in np.atleast_1d(begin)]
        r1 = r0 if end is None else [float(v) for v in np.atleast_1d(end)]
        if len(r0) != len(self.axes) or len(r1) != len(self.axes):
            raise SimulationError(f'a step needs a reference acceleration per axis ({", ".join(self.axes)}), '
                                  f'got {begin} to {end}')
        if not all(math.isfinite(v) for v in r0 + r1):
            raise SimulationError(f'reference acceleration must be finite, got {begin} to {end}')
        self._stepper.step(self._axes, self._q, self._v, r0, r1, self._w)
        self._steps += 1

    @property
    def disturbance(self) -> tuple[float, float]:
        """The horizontal acceleration (m/s^2) acting on both masses, (x, y): wind and gusts (module docstring;
        ``crane_sim.disturbances``). Set it to change it from the next step on (held over each step); it
        survives ``reset``. The y component needs the bridge: the planar crane swings in x-z alone."""
        return self._disturbance

    @disturbance.setter
    def disturbance(self, w) -> None:
        ax, ay = (float(v) for v in w)
        if not (math.isfinite(ax) and math.isfinite(ay)):
            raise SimulationError(f'the disturbance must be finite, got {w}')
        if ay != 0.0 and not self.spatial:
            raise SimulationError(f'a disturbance along y ({ay:g} m/s^2) needs the bridge: the crane without one '
                                  'swings in the x-z plane alone')
        self._disturbance = (ax, ay)
        # none: the step of a crane without disturbance, not one less zero
        self._w = None if ax == 0.0 and ay == 0.0 else ((ax, ay),) * 3

    @property
    def swing(self) -> SpatialSwing:
        """Both cables' angles (relative, as published) and their rates."""
        (a1, b1, a2, b2), (da1, db1, da2, db2) = self._q, self._v
        return SpatialSwing(a1, a2 - a1, b1, b2 - b1, da1, da2 - da1, db1, db2 - db1)

    @property
    def state(self) -> CraneState:
        """The cart's and the swing's in-plane state."""
        w = self.swing
        y, v, a = self._axes[0]
        return CraneState(y, v, a, w.theta1, w.theta2, w.dtheta1, w.dtheta2)

    def axis_state(self, name: str) -> tuple[float, float, float]:
        """The axis's position, rate and acceleration now."""
        return tuple(self._axes[self.axes.index(name)])

    def push(self, excursion: float, excursion_y: float = 0.0) -> None:
        """Set the load swinging, as a push would: the load displaced horizontally with both cables in line
        (theta2 = phi2 = 0) and released from rest; every axis keeps its state. ``excursion`` (m) along x
        as ``load_excursion`` measures it (positive: the load behind the suspension point, at -x, theta1
        > 0), ``excursion_y`` (m) likewise along y (positive: the load at -y, phi1 < 0); the y push needs the
        bridge."""
        dx, dy = float(excursion), float(excursion_y)
        if dy != 0.0 and not self.spatial:
            raise SimulationError(f'a push along y ({dy:g} m) needs the bridge: the crane without one swings in '
                                  'the x-z plane alone')
        length = self.L1 + float(self._plants.L2[0])
        if not (math.isfinite(dx) and math.isfinite(dy) and math.hypot(dx, dy) < length):
            given = f'({dx}, {dy})' if dy else dx
            raise SimulationError(f'a push must displace the load less than the cables\' length '
                                  f'({length:g} m), got {given} m')
        # the load at -(dx, dy) from the suspension point: L u(theta1, phi1) = (-L sin theta1 cos phi1, L sin phi1)
        phi1 = -math.asin(dy / length) if dy else 0.0
        self._set_swing(SpatialSwing(theta1=math.asin(dx / (length * math.cos(phi1))), phi1=phi1))

    @property
    def L1(self) -> float:
        """The upper cable's length (m) now: the hoist's, or the plant's."""
        return self.axis_state(HOIST_JOINT)[0] if self.hoist else float(self._plants.L1[0])

    @property
    def joint_names(self) -> tuple:
        """The joints of ``joint_state``: each axis's (``axes``), then the swing's."""
        return joint_names_of(self.axes)

    @property
    def suspension(self) -> tuple[float, float, float]:
        """The suspension point (m) in ``crane_base``: (cart, bridge or 0, 0)."""
        return self._axes[0][0], self._axes[self.axes.index(BRIDGE_JOINT)][0] if self.spatial else 0.0, 0.0

    def mass_positions(self, angles=None) -> tuple:
        """(p1, p2): both masses' positions (m) in ``crane_base`` now, or with the swing angles ``angles``
        (theta1, theta2[, phi1, phi2], as ``joint_state`` publishes them: e.g. measured ones)."""
        q = self._q
        if angles is not None:
            theta1, theta2, phi1, phi2 = (*angles, 0.0, 0.0)[:4]
            q = (theta1, phi1, theta1 + theta2, phi1 + phi2)
        return self._stepper.model.positions(self.suspension, q, self.L1)

    @property
    def load_excursion(self) -> float:
        """Horizontal offset (m) of the load from its rest position below the suspension point: in the
        x-z plane signed (positive when it lags), with a bridge its norm (contract)."""
        w = self.swing
        phi = (w.phi1, w.phi2) if self.spatial else ()
        return float(load_swing(w.theta1, w.theta2, self.L1, self._plants.L2[0], *phi))

    def joint_state(self) -> tuple[list[float], list[float]]:
        """Positions and velocities of ``joint_names`` (each axis, then the swing), for sensor_msgs/JointState."""
        w = self.swing
        positions = [x[0] for x in self._axes] + [w.theta1, w.theta2]
        velocities = [x[1] for x in self._axes] + [w.dtheta1, w.dtheta2]
        if self.spatial:
            positions += [w.phi1, w.phi2]
            velocities += [w.dphi1, w.dphi2]
        return positions, velocities
