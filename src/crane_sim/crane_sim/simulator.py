"""Fixed-step simulation of the crane: Eqs. 18-19 driven through the axis servo of Eq. 6.

State of one plant: ``[y, v, a, theta1, theta2, dtheta1, dtheta2]`` (cart
position, velocity, acceleration, cable angles and their rates). The cart
acceleration follows the reference through the first-order servo
``tau a' + a = a_ref`` (Eq. 6; ``tau = 0`` means ``a = a_ref``).

Within one step the reference is linear in time (or constant, ``zoh``), so the
servo and the cart kinematics have a closed form; it is evaluated at the RK4
stage times and the swing (Eqs. 18-19, ``crane_sim.dynamics``) is integrated
by classic RK4. The cart is therefore exact for every ``tau >= 0``, including
``tau`` much smaller than the step, where an explicit integrator of Eq. 6
would blow up.

Everything is vectorized over a batch of plants (numpy arrays of shape
``(n,)``); the batch path (:func:`simulate`) and the streaming path
(:class:`CraneSimulator`, for the real-time node) share one step function.
No ROS import here.

Why one module of ~490 lines: both paths use the private stepper and the
internal state layout (``_Stepper``, ``_to_internal``/``_to_public``);
splitting them apart would make those private pieces public API.
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields

import numpy as np

from crane_msgs_py.params import (
    PARAMETER_NAMES,
    CraneParams,
    ParameterError,
    check_choice,
    check_count,
    check_parameter,
    check_positive,
)

from .dynamics import SwingModel, hoisting_accelerations, load_excursion

#: Names of the state rows, in order.
STATE_NAMES = ('y', 'v', 'a', 'theta1', 'theta2', 'dtheta1', 'dtheta2')
#: Names of the hoist's state rows, after ``STATE_NAMES`` when hoisting: the upper cable's length,
#: its rate and acceleration.
HOIST_STATE_NAMES = ('L1', 'dL1', 'ddL1')
#: Joint names the ROS node publishes (positions y, theta1, theta2).
JOINT_NAMES = ('cart', 'theta1', 'theta2')
#: ... and with a hoist (its position: the upper cable's length L1).
HOIST_JOINT_NAMES = ('cart', 'hoist', 'theta1', 'theta2')
INTERPOLATIONS = ('zoh', 'linear')
SOURCES = ('acceleration', 'position')


#: Plant parameters a plant may leave out (those of the hoist), with their defaults.
_OPTIONAL = {'tau_hoist': CraneParams.tau_hoist}


class SimulationError(ValueError):
    """A simulation request is malformed; the message names the argument and why."""


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
        e.g. ``crane_msgs_py.params.CraneParams``; ``tau_hoist`` defaults to CraneParams'.
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

def _to_internal(x):
    x = np.array(x, dtype=float)
    x[4] += x[3]
    x[6] += x[5]
    return x


def _to_public(x):
    x = np.array(x, dtype=float)
    x[4] -= x[3]
    x[6] -= x[5]
    return x


class _Stepper:
    """The one step shared by :func:`simulate` and :class:`CraneSimulator`, for a batch of plants.

    The cart (y, v, a) takes the exact servo solution (:func:`servo_weights`);
    the swing takes a classic RK4 step fed with that exact cart acceleration
    at the stage times 0, h/2, h. RK4 is written for the second-order system
    q'' = f(q, q', a) (angles q, rates v): the stages' angle slopes are the
    stages' rates, so only f is evaluated.
    """

    def __init__(self, plants: PlantBatch, h: float, hoist: bool = False):
        self.W = servo_weights(plants.tau, h)
        self.model = plants.swing_model()
        # 0-d arrays: numpy multiplies by them about twice as fast as by Python floats,
        # which matters at a few dozen plants where every numpy call is pure overhead
        self._h, self._h2, self._h6 = np.array(h), np.array(0.5 * h), np.array(h / 6.0)
        self.hoist = hoist
        if hoist:
            # the hoist's servo over the step and over its first half (the RK4 midpoint needs L1 there)
            self.W_hoist, self.W_half = servo_weights(plants.tau_hoist, h), servo_weights(plants.tau_hoist, 0.5 * h)
            self._constants = (plants.L2, plants.m1, plants.m2, plants.g, plants.c1, plants.c2)

    def _hoist_stages(self, x, r0, r1):
        """The swing's right-hand side at the RK4 stage times 0, h/2, h with the hoist's exact motion,
        and the hoist rows (L1, L1', L1'') at the step's end."""
        W, Wh, h, h2 = self.W_hoist, self.W_half, self._h, self._h2
        c = W[0] * x[9] + W[1] * r0 + W[2] * r1
        half = Wh[0] * x[9] + Wh[1] * r0 + Wh[2] * (0.5 * (r0 + r1))
        L = (x[7], x[7] + h2 * x[8] + half[4], x[7] + h * x[8] + c[4])
        dL = (x[8], x[8] + half[3], x[8] + c[3])
        constants = self._constants

        def at(k):
            return lambda q, v, a: hoisting_accelerations(q, v, a, L[k], dL[k], c[k], *constants)

        return (at(0), at(1), at(2)), (L[2], dL[2], c[2])

    def step(self, x, r0, r1, hoist0=None, hoist1=None):
        """Internal states ``x`` one step later, the reference going linearly from r0 to r1 (and the
        hoist's reference acceleration from hoist0 to hoist1, rows 7-9 of ``x``, when hoisting)."""
        W, h, h2, h6 = self.W, self._h, self._h2, self._h6
        c = W[0] * x[2] + W[1] * r0 + W[2] * r1  # a(0+), a(h/2), a(h), v and y increments
        if self.hoist:
            (f_begin, f_mid, f_end), hoist_end = self._hoist_stages(x, hoist0, hoist1)
        else:
            f_begin = f_mid = f_end = self.model.accelerations
        q, v = x[3:5], x[5:7]
        f1 = f_begin(q, v, c[0])
        v2 = v + h2 * f1
        f2 = f_mid(q + h2 * v, v2, c[1])
        v3 = v + h2 * f2
        f3 = f_mid(q + h2 * v2, v3, c[1])
        v4 = v + h * f3
        f4 = f_end(q + h * v3, v4, c[2])
        out = np.empty_like(x)
        out[0] = x[0] + h * x[1] + c[4]
        out[1] = x[1] + c[3]
        out[2] = c[2]
        if self.hoist:
            out[7], out[8], out[9] = hoist_end
        v2 += v3  # v + h/6 (f1 + 2 f2 + 2 f3 + f4), and q likewise with the stage rates
        v2 += v2
        v2 += v + v4
        np.add(q, h6 * v2, out=out[3:5])
        f2 += f3
        f2 += f2
        f2 += f1 + f4
        np.add(v, h6 * f2, out=out[5:7])
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
    """Simulated trajectories: ``t`` (n,) and (n_batch, n) arrays per state, plus the plants."""

    t: np.ndarray
    y: np.ndarray
    v: np.ndarray
    a: np.ndarray
    theta1: np.ndarray
    theta2: np.ndarray
    dtheta1: np.ndarray
    dtheta2: np.ndarray
    plants: PlantBatch
    #: the upper cable's length (m), its rate and acceleration, (n_batch, n): hoisting only, else None
    L1: np.ndarray | None = None
    dL1: np.ndarray | None = None
    ddL1: np.ndarray | None = None

    @property
    def load_excursion(self) -> np.ndarray:
        """Horizontal offset (m) of the load from its rest position below the cart, (n_batch, n)."""
        L1 = self.plants.L1[:, None] if self.L1 is None else self.L1
        return load_excursion(self.theta1, self.theta2, L1, self.plants.L2[:, None])

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


def simulate(t_ref, reference, plants, *, dt: float = 1e-3, t_end: float | None = None,
             interpolation: str = 'linear', source: str = 'acceleration', record_every: int = 1,
             initial_state=None, rest_dt: float | None = None, hoist_reference=None) -> SimResult:
    """Simulate a batch of plants driven by a sampled cart reference.

    Args:
        t_ref: sample times (s), strictly increasing; the simulation starts at t_ref[0].
        reference: acceleration (m/s^2) or position (m) samples, shape (m,) for
            all plants or (n_batch, m), one row per plant.
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
        initial_state: (7,) or (n_batch, 7) state ``STATE_NAMES`` at t_ref[0];
            default: at rest at the first reference value (y = first position
            for ``position``, else 0; servo settled, no swing).
        rest_dt: step (s) once the grid has passed the last reference sample,
            where the input holds (default ``dt``): a few times ``dt`` keeps
            RK4 as accurate on the free swing (its error grows as (omega h)^5,
            ~1e-9 of the swing per 5 ms step at 9 rad/s) for a fraction of
            the steps; the grid then continues in steps of ``rest_dt``.
        hoist_reference: with a hoist, its reference acceleration (m/s^2) at
            ``t_ref``, shape (m,) or (n_batch, m), followed through the servo
            ``tau_hoist``; the upper cable's length starts at each plant's L1
            (plus what ``initial_state`` says) and moves with it. The state
            then has the rows ``HOIST_STATE_NAMES`` too, and the result
            ``L1``, ``dL1``, ``ddL1``.
    """
    check_choice('interpolation', interpolation, INTERPOLATIONS, SimulationError)
    check_choice('source', source, SOURCES, SimulationError)
    p = PlantBatch.of(plants)
    t_ref, ref = _check_reference(t_ref, reference, len(p))
    hoisting = hoist_reference is not None
    if hoisting:
        _, hoist = _check_reference(t_ref, hoist_reference, len(p))
        if ref.shape[0] != hoist.shape[0]:
            if ref.shape[0] != 1 and hoist.shape[0] != 1:
                raise SimulationError(f'hoist_reference has {hoist.shape[0]} rows, reference {ref.shape[0]}')
            rows = max(ref.shape[0], hoist.shape[0])
            ref, hoist = np.broadcast_to(ref, (rows, t_ref.size)), np.broadcast_to(hoist, (rows, t_ref.size))
    if len(p) == 1 and ref.shape[0] > 1:
        p = p.repeat(ref.shape[0])
    n = len(p)
    nrows = len(STATE_NAMES) + (len(HOIST_STATE_NAMES) if hoisting else 0)
    dt = check_positive('dt', dt)
    t0 = float(t_ref[0])
    t_end = float(t_ref[-1]) if t_end is None else float(t_end)
    if not math.isfinite(t_end) or t_end < t0:
        raise SimulationError(f't_end must be finite and >= t_ref[0] = {t0}, got {t_end}')
    check_count('record_every', record_every, SimulationError)
    if source == 'position':
        if t_ref.size < 2:
            raise SimulationError('a position reference needs at least 2 samples')
        y0 = ref[:, 0]
        t_acc, acc = acceleration_from_positions(t_ref, ref)
    else:
        y0 = np.zeros(n)
        t_acc, acc = t_ref, ref
    if hoisting:  # rows: the cart's n, then the hoist's n, so the stepping below serves both
        if source != 'acceleration':
            raise SimulationError("hoist_reference needs source='acceleration'")
        acc = np.concatenate([acc, hoist])

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
    if interpolation == 'linear':
        r = np.ascontiguousarray(interpolate(t_acc, acc, t_moving, 'linear').T)
        r_begin, r_end = r[:-1], r[1:]
    else:   # the held value at mid-step is robust to rounding of knots that fall on the grid
        r_begin = r_end = np.ascontiguousarray(interpolate(t_acc, acc, t_moving[:-1] + 0.5 * dt, 'zoh').T)
    r_rest = np.ascontiguousarray(acc[:, -1])

    a0 = interpolate(t_acc, acc, t0, interpolation)
    if initial_state is None:
        x = np.zeros((nrows, n))
        x[0] = y0
        x[2] = a0[:n]
        if hoisting:
            x[7], x[9] = p.L1, a0[n:]
    else:
        s = np.asarray(initial_state, dtype=float)
        if s.shape not in ((nrows,), (n, nrows)) or not np.all(np.isfinite(s)):
            raise SimulationError(f'initial_state must be finite with shape ({nrows},) or ({n}, {nrows}), '
                                  f'got {s.shape}')
        x = np.array(np.broadcast_to(s, (n, nrows)).T)
    x = _to_internal(x)

    keep = [k % record_every == 0 or k == n_steps for k in range(n_steps + 1)]
    out = np.empty((sum(keep), nrows, n))
    out[0] = x
    j = 1
    stepper = _Stepper(p, dt, hoisting)
    rest = _Stepper(p, rest_dt, hoisting) if n_steps > n_fine else None
    for k in range(n_steps):
        if k < n_fine:
            r0, r1 = r_begin[k], r_end[k]
            x = stepper.step(x, r0[:n], r1[:n], r0[n:], r1[n:]) if hoisting else stepper.step(x, r0, r1)
        elif hoisting:
            x = rest.step(x, r_rest[:n], r_rest[:n], r_rest[n:], r_rest[n:])
        else:
            x = rest.step(x, r_rest, r_rest)
        if keep[k + 1]:
            out[j] = x
            j += 1
    rows = [np.ascontiguousarray(r) for r in _to_public(out.transpose(1, 2, 0))]
    return SimResult(t[np.array(keep)], *rows[:7], plants=p, **dict(zip(('L1', 'dL1', 'ddL1'), rows[7:])))


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


class CraneSimulator:
    """One plant stepped in real time, with the same step as :func:`simulate`.

    Args:
        params: plant parameters (attributes or keys L1 L2 m1 m2 g tau c1 c2).
        dt: integration step (s).
        state: initial :class:`CraneState` (default at rest at y = 0).
        hoist: the upper cable's length is an axis too, driven through the
            servo ``tau_hoist``; it starts at the plant's L1 (later changes of
            L1 do not move it; ``reset`` keeps it where it is).
    """

    def __init__(self, params, dt: float = 1e-3, state: CraneState | None = None, hoist: bool = False):
        self.dt = check_positive('dt', dt)
        self.hoist = bool(hoist)
        self.set_params(params)
        self._x = None
        self.reset(state)

    def set_params(self, params):
        """Change the plant; takes effect from the next step, the state is kept."""
        plants = PlantBatch.of(params)
        if len(plants) != 1:
            raise ParameterError(f'CraneSimulator simulates one plant, got {len(plants)}')
        self._plants = plants
        self._stepper = _Stepper(plants, self.dt, self.hoist)

    @property
    def params(self) -> dict:
        """The current plant parameters as a dict."""
        return self._plants.member(0)

    def reset(self, state: CraneState | None = None, t: float = 0.0):
        """Back to ``state`` (default at rest at y = 0) at time ``t``; a hoist at rest where it is."""
        s = (state or CraneState()).as_array()
        if not np.all(np.isfinite(s)):
            raise SimulationError(f'state must be finite, got {state}')
        if self.hoist:
            length = self._plants.L1[0] if self._x is None else self._x[7, 0]
            s = np.concatenate([s, [length, 0.0, 0.0]])
        self._x = _to_internal(s.reshape(-1, 1))
        self._t0, self._steps = float(t), 0

    @property
    def t(self) -> float:
        """Simulated time (s): the reset time plus the steps taken times dt."""
        return self._t0 + self._steps * self.dt

    def step(self, a_ref_begin: float, a_ref_end: float | None = None, hoist_begin: float = 0.0,
             hoist_end: float | None = None) -> None:
        """Advance one ``dt``; the reference acceleration goes linearly from
        ``a_ref_begin`` to ``a_ref_end`` (held at ``a_ref_begin`` if None), and
        with a hoist its reference acceleration from ``hoist_begin`` to ``hoist_end``.

        Returns nothing: building :attr:`state` costs a sixth of a step, and
        the real-time loop reads it only every 20th step."""
        r0 = float(a_ref_begin)
        r1 = r0 if a_ref_end is None else float(a_ref_end)
        h0 = float(hoist_begin)
        h1 = h0 if hoist_end is None else float(hoist_end)
        if not (math.isfinite(r0) and math.isfinite(r1) and math.isfinite(h0) and math.isfinite(h1)):
            raise SimulationError(f'reference acceleration must be finite, got {r0}, {r1} (hoist {h0}, {h1})')
        if self.hoist:
            self._x = self._stepper.step(self._x, np.array([r0]), np.array([r1]), np.array([h0]), np.array([h1]))
        else:
            self._x = self._stepper.step(self._x, np.array([r0]), np.array([r1]))
        self._steps += 1

    @property
    def state(self) -> CraneState:
        return CraneState(*(float(v) for v in _to_public(self._x)[:7, 0]))

    def push(self, excursion: float) -> None:
        """Set the load swinging, as a push would: the load displaced ``excursion`` (m) horizontally with
        both cables in line (theta2 = 0) and released from rest; the cart and the hoist keep their state."""
        excursion = float(excursion)
        length = self.L1 + float(self._plants.L2[0])
        if not (math.isfinite(excursion) and abs(excursion) < length):
            raise SimulationError(f'a push must displace the load less than the cables\' length '
                                  f'({length:g} m), got {excursion} m')
        x = _to_public(self._x)
        x[3:7, 0] = (math.asin(excursion / length), 0.0, 0.0, 0.0)
        self._x = _to_internal(x)

    @property
    def L1(self) -> float:
        """The upper cable's length (m) now: the hoist's, or the plant's."""
        return float(self._x[7, 0]) if self.hoist else float(self._plants.L1[0])

    @property
    def hoist_state(self) -> tuple[float, float, float]:
        """The hoist's length (m), rate (m/s) and acceleration (m/s^2); (L1, 0, 0) without a hoist."""
        return (float(self._x[7, 0]), float(self._x[8, 0]), float(self._x[9, 0])) if self.hoist else (self.L1, 0.0,
                                                                                                        0.0)

    @property
    def joint_names(self) -> tuple:
        """The joints of ``joint_state``: ``JOINT_NAMES``, with a hoist ``HOIST_JOINT_NAMES``."""
        return HOIST_JOINT_NAMES if self.hoist else JOINT_NAMES

    @property
    def load_excursion(self) -> float:
        """Horizontal offset (m) of the load from its rest position below the cart."""
        s = self.state
        return float(load_excursion(s.theta1, s.theta2, self.L1, self._plants.L2[0]))

    def joint_state(self) -> tuple[list[float], list[float]]:
        """Positions and velocities of ``joint_names`` (cart, [hoist,] theta1, theta2), for sensor_msgs/JointState."""
        s = self.state
        if self.hoist:
            length, rate, _ = self.hoist_state
            return [s.y, length, s.theta1, s.theta2], [s.v, rate, s.dtheta1, s.dtheta2]
        return [s.y, s.theta1, s.theta2], [s.v, s.dtheta1, s.dtheta2]
