"""Estimate the crane from one recorded move: L1, L2, the mass ratio, both joint dampings, tau.

The swing model is the planner's own (``planning.dynamics.swing_accelerations``:
Eqs. 18-19 plus joint damping), driven by the recorded cart's acceleration
(the second derivative of a quintic spline through the cart samples), so the
servo does not enter the swing fit. It is integrated by RK4, ``SUBSTEPS``
steps per sample interval, as one CasADi function whose Jacobian comes from
automatic differentiation; scipy's ``least_squares`` fits the simulated
angles to the measured ones over

    z = [L1, L2, mu, d1, d2, theta1(0), theta2(0), theta1'(0), theta2'(0)]

with mu = m2 / (m1 + m2) (with the joint dampings, the swing depends on the
masses only through mu, c1 / (m1 + m2) and c2 / m2; the total mass is taken
from the nominal model) and the damping rates d1 = c1 / ((m1 + m2) L1^2),
d2 = c2 / (m2 L2^2) (1/s, of order 2 zeta omega, so all unknowns are O(1)).
The initial state is fitted too, so a recording may start mid-swing.

Converging from far: the fit starts from the two modal frequencies of an
FFT of the free swing (after the cart stops). For a given mu the linearized
crane's frequencies fix L1 + L2 and L1 L2 (``_lengths_from_frequencies``),
which leaves which cable is the longer one: both are tried and the better
fit is kept.

tau comes separately, when the reference is recorded beside the measured
cart: Eq. 6 from rest gives tau y' + y = y_ref, linear in tau.

Standard errors are those of the linearized least-squares problem
(s^2 (J^T J)^-1, s^2 the residual variance); derived quantities (c1, c2, the
modal frequencies and damping ratios) get theirs by the delta method.
Pure Python (numpy, scipy, CasADi), no ROS import.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from functools import lru_cache

import casadi as ca
import numpy as np
from scipy.interpolate import make_interp_spline
from scipy.optimize import least_squares
from scipy.signal import find_peaks

from crane_msgs_py.crane.params import CraneParams

from ..planning.dynamics import swing_accelerations
from ..planning.model import modal_properties
from .recording import Recording, RecordingError

#: RK4 steps per sample interval (at 50 Hz 10 ms: omega h <= 0.1 for the fast mode, a phase
#: error of ~1e-7 per step, far below what 1 mrad noise can resolve).
SUBSTEPS = 2
#: Fewest free-swing periods of the slow mode a recording must hold after the cart stops.
MIN_SLOW_PERIODS = 1.0
#: Relative standard error above which a length or the mass ratio is reported as not determined.
WARN_RELATIVE_STD = 0.05
#: Standard error of a damping ratio above which it is reported as not determined.
WARN_ZETA_STD = 0.01
#: Names of the fitted vector z, in order.
UNKNOWNS = ('L1', 'L2', 'mass_ratio', 'd1', 'd2', 'theta1_0', 'theta2_0', 'dtheta1_0', 'dtheta2_0')
#: The estimates reported (JSON keys), each with ``<name>_std``.
REPORTED = ('L1', 'L2', 'mass_ratio', 'c1', 'c2', 'tau', 'omega1', 'omega2', 'zeta1', 'zeta2')


class IdentificationError(RecordingError):
    """The recording cannot determine the crane (too short, too little swing); the message says why."""


@dataclass(frozen=True)
class Identification:
    """The estimates of one fit.

    Attributes:
        params: the nominal model with the estimates in (m1, m2 from the mass
            ratio and the nominal total mass; tau only if estimated).
        values, std: estimate and standard error by name (``REPORTED``);
            None for tau when the recording has no reference.
        rms_residual_rad: RMS of measured minus fitted angles over both angles.
        warnings: what the data could not determine, in words.
        iterations: least-squares iterations of the kept start (Jacobian evaluations).
        fit_time_s: wall time of the whole estimate.
        t, theta1, theta2: the fitted swing at the recording's times (for plots).
    """

    params: CraneParams
    values: dict
    std: dict
    rms_residual_rad: float
    warnings: tuple
    iterations: int
    fit_time_s: float
    t: np.ndarray = field(repr=False)
    theta1: np.ndarray = field(repr=False)
    theta2: np.ndarray = field(repr=False)

    def as_json(self) -> dict:
        """The contract's keys: each estimate, ``<name>_std``, ``rms_residual_rad`` (and warnings)."""
        out = {}
        for name in REPORTED:
            out[name] = self.values[name]
            out[f'{name}_std'] = self.std[name]
        out['rms_residual_rad'] = self.rms_residual_rad
        out['warnings'] = list(self.warnings)
        out['iterations'] = self.iterations
        out['fit_time_s'] = self.fit_time_s
        return out

    def params_yaml(self, node: str = '/**/crane_planner') -> str:
        """A ROS 2 parameters file setting the planner node's model to the estimates."""
        names = ['L1', 'L2', 'm1', 'm2', 'c1', 'c2'] + (['tau'] if self.values['tau'] is not None else [])
        lines = [f'# crane-plan identify: rms residual {self.rms_residual_rad:.3g} rad',
                 f'{node}:', '  ros__parameters:']
        lines += [f'    {name}: {getattr(self.params, name)!r}' for name in names]
        return '\n'.join(lines) + '\n'


# --------------------------------------------------------------------------- the swing simulation

@lru_cache(maxsize=8)
def _residual_functions(intervals: int, substeps: int = SUBSTEPS):
    """(residual, Jacobian) CasADi functions of (z, inputs, measured, [M, g]) for ``intervals`` sample intervals.

    ``inputs`` is (2 substeps + 2) x intervals: each interval's length h and the
    cart acceleration at its RK4 stage times t_k + j h / (2 substeps).
    """
    x = ca.SX.sym('x', 4)
    u = ca.SX.sym('u', 2 * substeps + 2)
    q = ca.SX.sym('q', 7)  # L1 L2 m1 m2 g c1 c2
    L1, L2, m1, m2, g, c1, c2 = ca.vertsplit(q)

    def f(state, a):
        dd1, dd2 = swing_accelerations(state[0], state[1], state[2], state[3], a, L1, L2, m1, m2, g, c1, c2)
        return ca.vertcat(state[2], state[3], dd1, dd2)

    hs = u[0] / substeps
    xk = x
    for j in range(substeps):
        a0, am, a1 = u[1 + 2 * j], u[2 + 2 * j], u[3 + 2 * j]
        k1 = f(xk, a0)
        k2 = f(xk + hs / 2 * k1, am)
        k3 = f(xk + hs / 2 * k2, am)
        k4 = f(xk + hs * k3, a1)
        xk = xk + hs / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    step = ca.Function('step', [x, u, q], [xk])
    sim = step.mapaccum('sim', intervals)

    z = ca.MX.sym('z', len(UNKNOWNS))
    inputs = ca.MX.sym('inputs', 2 * substeps + 2, intervals)
    measured = ca.MX.sym('measured', 2, intervals + 1)
    mg = ca.MX.sym('mg', 2)  # total mass, g
    mu = z[2]
    m1_, m2_ = (1 - mu) * mg[0], mu * mg[0]
    params = ca.vertcat(z[0], z[1], m1_, m2_, mg[1], z[3] * mg[0] * z[0] ** 2, z[4] * m2_ * z[1] ** 2)
    x0 = z[5:9]
    states = ca.horzcat(x0, sim(x0, inputs, ca.repmat(params, 1, intervals)))
    r = ca.vec((states[0:2, :] - measured).T)
    residual = ca.Function('residual', [z, inputs, measured, mg], [r])
    both = ca.Function('residual_jacobian', [z, inputs, measured, mg], [r, ca.jacobian(r, z)])
    return residual, both


def _cart_inputs(rec: Recording, substeps: int = SUBSTEPS) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(inputs, cart velocity at the samples, cart spline) from the cart column (``_residual_functions``)."""
    spline = make_interp_spline(rec.t, rec.cart, k=5)
    acceleration = spline.derivative(2)
    h = np.diff(rec.t)
    frac = np.arange(2 * substeps + 1) / (2 * substeps)
    times = rec.t[:-1, None] + h[:, None] * frac[None, :]
    inputs = np.vstack([h[None, :], acceleration(times).T])
    return inputs, spline.derivative(1)(rec.t), spline


# --------------------------------------------------------------------------- starting point

def _free_swing_start(rec: Recording, velocity: np.ndarray) -> int:
    """Index of the first sample after which the cart no longer moves (0 if it never does)."""
    peak = np.max(np.abs(velocity))
    if peak == 0.0:
        return 0
    moving = np.flatnonzero(np.abs(velocity) > 1e-3 * peak)
    return min(int(moving[-1]) + 1, rec.t.size - 1)


def _spectrum_peaks(t: np.ndarray, signals) -> list[tuple[float, float]]:
    """(frequency rad/s, relative height) of the peaks of the summed normalized amplitude spectra, highest first."""
    n = t.size
    dt = float(np.median(np.diff(t)))
    pad = 1 << int(math.ceil(math.log2(16 * n)))
    window = np.hanning(n)
    total = 0.0
    for s in signals:
        s = np.asarray(s, dtype=float) - np.mean(s)
        spec = np.abs(np.fft.rfft(s * window, pad))
        if spec.max() > 0.0:
            total = total + spec / spec.max()
    if np.isscalar(total):
        return []
    omega = 2.0 * np.pi * np.fft.rfftfreq(pad, dt)
    lo = 2.0 * np.pi / (n * dt)  # below one cycle over the record is not a mode
    peaks, _ = find_peaks(total)
    peaks = [k for k in peaks if omega[k] > lo and omega[k] < 0.8 * omega[-1]]
    found = []
    for k in sorted(peaks, key=lambda k: -total[k]):
        if 0 < k < total.size - 1:  # parabolic interpolation of the peak
            a, b, c = total[k - 1], total[k], total[k + 1]
            shift = 0.5 * (a - c) / (a - 2 * b + c) if (a - 2 * b + c) != 0 else 0.0
        else:
            shift = 0.0
        found.append((float(omega[k] + shift * (omega[1] - omega[0])), float(total[k] / total.max())))
    return found


def _lengths_from_frequencies(omega1: float, omega2: float, mu: float, g: float) -> list[tuple[float, float, float]]:
    """(L1, L2, mu) with the linearized crane's frequencies omega1 < omega2, both orders of the cables.

    The linearized equations (absolute angles, divided by the masses) have the
    mass matrix [[L1, mu L2], [L1, L2]]; its eigenvalues s_i = g / omega_i^2
    satisfy s1 + s2 = L1 + L2 and s1 s2 = L1 L2 (1 - mu). A mu too large for
    the two frequencies (no real lengths) is lowered to the largest that fits.
    """
    s1, s2 = g / omega1 ** 2, g / omega2 ** 2
    total, product = s1 + s2, s1 * s2
    mu = min(mu, 0.95 * (1.0 - 4.0 * product / total ** 2))
    mu = max(mu, 1e-3)
    root = math.sqrt(max(total ** 2 - 4.0 * product / (1.0 - mu), 0.0))
    a, b = (total + root) / 2.0, (total - root) / 2.0
    return [(a, b, mu), (b, a, mu)] if b > 0.0 else [(total / 2, total / 2, mu)]


# --------------------------------------------------------------------------- the fit

def identify(rec: Recording, model: CraneParams | None = None, noise_hint: float | None = None) -> Identification:
    """Estimate the crane from ``rec`` (see the module docstring); ``model`` is the nominal crane.

    The nominal model gives the total mass m1 + m2, g and the fallback frequency
    ratio. Raises IdentificationError when the recording cannot determine the
    crane: too short after the move, or no swing to fit.
    """
    t_start = time.perf_counter()
    model = model or CraneParams()
    inputs, velocity, _ = _cart_inputs(rec)
    free = _free_swing_start(rec, velocity)
    t_free = rec.t[free:]
    free_time = float(t_free[-1] - t_free[0]) if t_free.size > 1 else 0.0
    swing = max(np.ptp(rec.theta1[free:]), np.ptp(rec.theta2[free:])) if t_free.size > 1 else 0.0
    (w1_model, w2_model), _ = modal_properties(model)
    if free_time < MIN_SLOW_PERIODS * 2 * math.pi / w1_model:
        raise IdentificationError(
            f'the recording holds {free_time:.2f} s of free swing after the cart stops, less than one period of '
            f"the slow mode ({2 * math.pi / w1_model:.2f} s for the nominal model); record at least "
            f'{1.5 * 2 * math.pi / w1_model:.1f} s after the move')
    if swing < 1e-4:
        raise IdentificationError(f'too little excitation: the swing after the move spans {swing:.2g} rad; move '
                                  'faster or farther so that the load swings')
    peaks = _spectrum_peaks(t_free, (rec.theta1[free:], rec.theta2[free:]))
    if not peaks:
        raise IdentificationError('no swing frequency found in the free swing after the move')
    w_a = peaks[0][0]
    if free_time < MIN_SLOW_PERIODS * 2 * math.pi / min(w_a, w1_model):
        raise IdentificationError(
            f'the recording holds {free_time:.2f} s of free swing after the cart stops, less than one period of '
            f'the slow mode ({2 * math.pi / w_a:.2f} s measured); record longer after the move')
    # the second mode: the highest other peak well apart from the first, else the nominal ratio
    ratio = w2_model / w1_model
    others = [w for w, height in peaks[1:] if abs(math.log(w / w_a)) > 0.3 and height > 0.05]
    if others:
        w1, w2 = sorted((w_a, others[0]))
    elif w_a > math.sqrt(w1_model * w2_model):
        w1, w2 = w_a / ratio, w_a
    else:
        w1, w2 = w_a, w_a * ratio

    residual, jacobian = _residual_functions(rec.t.size - 1)
    measured = np.vstack([rec.theta1, rec.theta2])
    mg = np.array([model.m1 + model.m2, model.g])
    k = min(3, rec.t.size - 1)
    x0 = [rec.theta1[0], rec.theta2[0], (rec.theta1[k] - rec.theta1[0]) / (rec.t[k] - rec.t[0]),
          (rec.theta2[k] - rec.theta2[0]) / (rec.t[k] - rec.t[0])]

    last = {}  # least_squares asks for the residual, then the Jacobian, at the same z: one evaluation

    def fun(z):
        if last.get('z') is not None and np.array_equal(last['z'], z):
            return last['r']
        return np.asarray(residual(z, inputs, measured, mg)).ravel()

    def jac(z):
        r, J = jacobian(z, inputs, measured, mg)
        last.update(z=np.array(z), r=np.asarray(r).ravel())
        return np.asarray(J)

    lower = [1e-3, 1e-3, 1e-4, 0.0, 0.0, -np.pi, -np.pi, -50.0, -50.0]
    upper = [1e3, 1e3, 0.9999, 50.0, 50.0, np.pi, np.pi, 50.0, 50.0]
    best = None
    mu_model = model.m2 / (model.m1 + model.m2)
    floor = _noise_floor(measured)
    for L1, L2, mu in _lengths_from_frequencies(w1, w2, mu_model, model.g):
        z0 = np.clip([L1, L2, mu, 0.01, 0.01, *x0], lower, upper)
        try:
            sol = least_squares(fun, z0, jac=jac, bounds=(lower, upper), x_scale='jac', method='trf',
                                ftol=1e-10, xtol=1e-10, gtol=1e-10, max_nfev=200)
        except (ValueError, RuntimeError, np.linalg.LinAlgError):
            continue
        if best is None or sol.cost < best.cost:
            best = sol
        if math.sqrt(2.0 * best.cost / measured.size) < 1.5 * floor + 1e-5:
            break  # down to the measurement noise: the other order of the cables cannot do better
    if best is None or not np.isfinite(best.cost):
        raise IdentificationError('the fit did not converge from the free swing\'s frequencies')
    return _report(rec, model, best, fun, jac, time.perf_counter() - t_start)


def _noise_floor(measured: np.ndarray) -> float:
    """Standard deviation (rad) of the measurement noise, from 4th differences of the angles.

    A 4th difference scales a swing at omega by (omega h)^4 (~1e-3 at 9 rad/s,
    50 Hz) but white noise of deviation s to s sqrt(70).
    """
    d4 = np.diff(measured, n=4, axis=1)
    return float(np.sqrt(np.mean(d4 ** 2) / 70.0))


def _derived(z: np.ndarray, model: CraneParams) -> tuple[CraneParams, np.ndarray]:
    """The crane of the unknowns z and [L1, L2, mu, c1, c2, omega1, omega2, zeta1, zeta2]."""
    L1, L2, mu, d1, d2 = z[:5]
    total = model.m1 + model.m2
    m2 = mu * total
    c1, c2 = d1 * total * L1 ** 2, d2 * m2 * L2 ** 2
    params = model.replace(L1=float(L1), L2=float(L2), m1=float(total - m2), m2=float(m2), c1=float(c1), c2=float(c2))
    (w1, w2), (z1, z2) = modal_properties(params)
    return params, np.array([L1, L2, mu, c1, c2, w1, w2, z1, z2])


def _report(rec, model, sol, fun, jac, elapsed) -> Identification:
    z = sol.x
    r = fun(z)
    J = jac(z)
    n, p = r.size, z.size
    variance = float(r @ r) / max(n - p, 1)
    try:
        cov = variance * np.linalg.inv(J.T @ J)
    except np.linalg.LinAlgError:
        cov = np.full((p, p), np.inf)
    params, derived = _derived(z, model)
    # delta method: derivatives of the derived quantities by central differences in z
    G = np.zeros((derived.size, p))
    for j in range(5):
        h = 1e-6 * max(abs(z[j]), 1e-3)
        up, down = z.copy(), z.copy()
        up[j] += h
        down[j] = max(down[j] - h, 0.0)
        G[:, j] = (_derived(up, model)[1] - _derived(down, model)[1]) / (up[j] - down[j])
    std_derived = np.sqrt(np.maximum(np.diag(G @ cov @ G.T), 0.0))
    names = ('L1', 'L2', 'mass_ratio', 'c1', 'c2', 'omega1', 'omega2', 'zeta1', 'zeta2')
    values = {name: float(v) for name, v in zip(names, derived)}
    std = {name: float(s) for name, s in zip(names, std_derived)}
    values['tau'], std['tau'] = _servo_tau(rec)
    if values['tau'] is not None:
        params = params.replace(tau=max(values['tau'], 0.0))
    warnings = []
    for name in ('L1', 'L2', 'mass_ratio'):
        if not std[name] <= WARN_RELATIVE_STD * abs(values[name]):
            warnings.append(f'{name} is not determined by this recording (standard error {std[name]:.2g}, '
                            f'{100 * std[name] / abs(values[name]):.0f} %): excite both modes more, record longer')
    for k in (1, 2):
        if not std[f'zeta{k}'] <= WARN_ZETA_STD:
            warnings.append(f'the damping of mode {k} is not determined (zeta{k} standard error '
                            f'{std[f"zeta{k}"]:.2g}): record more free swing')
    fitted = np.asarray(r).reshape(2, -1) + np.vstack([rec.theta1, rec.theta2])
    return Identification(params=params, values=values, std=std, rms_residual_rad=float(np.sqrt(np.mean(r ** 2))),
                          warnings=tuple(warnings), iterations=int(sol.njev or sol.nfev), fit_time_s=elapsed,
                          t=rec.t, theta1=fitted[0], theta2=fitted[1])


def _servo_tau(rec: Recording) -> tuple[float | None, float | None]:
    """tau and its standard error from tau y' + y = y_ref (Eq. 6 from rest), or (None, None) without a reference.

    y' is the derivative of the cart's quintic spline. The cart may sit at an
    offset from the reference (an axis that integrates its acceleration
    command drifts), so the least squares has two unknowns, tau and a
    constant offset b: y_ref - y = tau y' + b.
    """
    if rec.reference is None:
        return None, None
    v = make_interp_spline(rec.t, rec.cart, k=5).derivative(1)(rec.t)
    if not np.any(np.abs(v) > 1e-9):
        raise IdentificationError('the cart does not move, so tau cannot be estimated; record a move')
    A = np.column_stack([v, np.ones_like(v)])
    e = rec.reference - rec.cart
    coef, *_ = np.linalg.lstsq(A, e, rcond=None)
    res = e - A @ coef
    variance = float(res @ res) / max(rec.t.size - 2, 1)
    cov = variance * np.linalg.inv(A.T @ A)
    return float(coef[0]), math.sqrt(float(cov[0, 0]))
