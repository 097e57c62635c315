"""Input shapers: impulse trains that cancel the residual swing of a mode (paper §4).

Each design function takes the mode's undamped natural frequency ``omega``
(rad/s) and damping ratio ``zeta`` (0 <= zeta < 1) and returns a ``Shaper``
whose amplitudes sum to 1 (the shaped motion reaches the same place).
Multi-mode systems cascade one shaper per mode (paper ref. [13]), see
``design``. Layout after Klipper's ``shaper_defs.py``.

Residual vibration (Singer & Seering) of a damped 2nd-order mode after the
last impulse t_N, relative to a single unit impulse:

    V(omega, zeta) = exp(-zeta omega t_N) |sum_i A_i exp(zeta omega t_i) exp(i omega_d t_i)|,
    omega_d = omega sqrt(1 - zeta^2).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.optimize import root

from crane_msgs_py.crane.params import ParameterError, check_nonnegative, check_positive

#: Default EI tolerance: the residual vibration V allowed at the design frequency.
EI_TOLERANCE = 0.05


@dataclass(frozen=True, eq=False)
class Shaper:
    """Impulse train: ``amplitudes[i]`` at ``times[i]`` (s), times ascending from 0."""

    amplitudes: np.ndarray
    times: np.ndarray

    def __post_init__(self):
        A = np.array(self.amplitudes, dtype=float)
        t = np.array(self.times, dtype=float)
        if A.ndim != 1 or A.shape != t.shape or A.size == 0:
            raise ParameterError('a shaper needs as many amplitudes as times, at least one')
        if not (np.all(np.isfinite(A)) and np.all(np.isfinite(t))):
            raise ParameterError('shaper amplitudes and times must be finite')
        if t[0] != 0.0 or np.any(np.diff(t) <= 0.0):
            raise ParameterError(f'shaper times must start at 0 and ascend strictly, got {t.tolist()}')
        A.setflags(write=False)
        t.setflags(write=False)
        object.__setattr__(self, 'amplitudes', A)
        object.__setattr__(self, 'times', t)

    @property
    def duration(self) -> float:
        """Time of the last impulse (s): the delay the shaper adds to a motion."""
        return float(self.times[-1])


def _check_zeta(zeta) -> float:
    zeta = check_nonnegative('zeta', zeta)
    if zeta >= 1.0:
        raise ParameterError(f'zeta must be < 1, got {zeta}')
    return zeta


def _check_mode(omega, zeta) -> tuple[float, float]:
    return check_positive('omega', omega), _check_zeta(zeta)


def _phasor(amplitudes, times, omega, zeta, derivative=False):
    """sum_i A_i exp(zeta omega (t_i - t_N)) exp(i omega_d t_i), whose modulus is V.

    Vectorized over ``omega``. With ``derivative`` also d/domega of it (for
    EI's flat top). Shifting by t_N keeps the exponentials bounded.
    """
    A = np.asarray(amplitudes, dtype=float)
    t = np.asarray(times, dtype=float)
    w = np.asarray(omega, dtype=float)[..., None]
    rate = zeta * (t - t[-1]) + 1j * math.sqrt(1.0 - zeta * zeta) * t
    terms = A * np.exp(w * rate)
    P = terms.sum(axis=-1)
    if derivative:
        return P, (terms * rate).sum(axis=-1)
    return P


def residual_vibration(shaper: Shaper, omega, zeta: float = 0.0):
    """Percentage residual vibration V of a mode (omega, zeta), see the module doc.

    1 means as much as an unshaped unit impulse leaves, 0 none. Vectorized
    over ``omega``.
    """
    zeta = _check_zeta(zeta)
    V = np.abs(_phasor(shaper.amplitudes, shaper.times, omega, zeta))
    return float(V) if V.ndim == 0 else V


def _half_period(omega: float, zeta: float) -> tuple[float, float]:
    """Half the damped period pi / omega_d and K = exp(-zeta pi / sqrt(1 - zeta^2)).

    K is how much the mode decays over half a damped period.
    """
    root_ = math.sqrt(1.0 - zeta * zeta)
    return math.pi / (omega * root_), math.exp(-zeta * math.pi / root_)


def _zv_power(omega, zeta, n: int) -> Shaper:
    """ZV cascaded n times with itself: binomial(n, k) K^k / (1 + K)^n at k pi / omega_d.

    n = 1, 2, 3 are ZV, ZVD and ZVDD: each cascade zeroes one more derivative
    of V with respect to omega at the design point.
    """
    omega, zeta = _check_mode(omega, zeta)
    half, K = _half_period(omega, zeta)
    k = np.arange(n + 1)
    A = np.array([math.comb(n, i) for i in k]) * K**k / (1.0 + K) ** n
    return Shaper(A, k * half)


def zv(omega, zeta=0.0) -> Shaper:
    """Zero Vibration: [1, K] / (1 + K) at [0, T_d / 2] (paper §4, ref. [13])."""
    return _zv_power(omega, zeta, 1)


def zvd(omega, zeta=0.0) -> Shaper:
    """Zero Vibration and Derivative: [1, 2K, K^2] / (1 + K)^2 at [0, T_d / 2, T_d] (paper §4)."""
    return _zv_power(omega, zeta, 2)


def zvdd(omega, zeta=0.0) -> Shaper:
    """ZVD with the second derivative zeroed too: [1, 3K, 3K^2, K^3] / (1 + K)^3, spacing T_d / 2."""
    return _zv_power(omega, zeta, 3)


def mzv(omega, zeta=0.0) -> Shaper:
    """Singhose's modified ZV: impulses at 0, 3/8, 3/4 of the damped period.

    As Klipper's ``get_mzv_shaper``: K is the decay over 3/8 of the period,
    so the damped phasors 1 - 1/sqrt2, sqrt2 - 1, 1 - 1/sqrt2 at 0, 135 and
    270 degrees close exactly (zero residual at the design point).
    """
    omega, zeta = _check_mode(omega, zeta)
    half, K = _half_period(omega, zeta)
    K = K**0.75
    a1 = 1.0 - 1.0 / math.sqrt(2.0)
    A = np.array([a1, (math.sqrt(2.0) - 1.0) * K, a1 * K * K])
    return Shaper(A / A.sum(), np.array([0.0, 0.75, 1.5]) * half)


def _solve(equations, guess, zeta, valid):
    """A root x of ``equations(x, zeta)``, starting from ``guess(zeta)``.

    When the direct start misses (or lands on an invalid branch), follow the
    solution from zeta = 0 in small steps instead. None if no valid root.
    """
    def newton(x0, z):
        # wild iterates may overflow; they then fail the residual test
        with np.errstate(over='ignore', invalid='ignore'):
            x = root(equations, x0, args=(z,), method='hybr', options={'xtol': 1e-15}).x
            if not np.max(np.abs(equations(x, z))) < 1e-13:
                return None
        x.setflags(write=False)  # cached by the callers
        return x

    x = newton(guess(zeta), zeta)
    if x is not None and valid(x):
        return x
    x = guess(0.0)
    for z in np.linspace(0.0, zeta, math.ceil(zeta / 0.02) + 1)[1:]:
        x = newton(x, z)
        if x is None:
            return None
    return x if valid(x) else None


# The numerical designs are solved once per (zeta, ...) with omega = 1 and
# scaled: times by 1 / omega, frequencies by omega.

def _nzv_equations(x, zeta):
    P = _phasor([1.0, -1.0, 1.0], [0.0, x[0], x[1]], 1.0, zeta)
    return [P.real, P.imag]


def _nzv_guess(zeta):
    # Singhose et al. 2004 curve fit, in undamped periods 2 pi / omega
    z = zeta
    return 2.0 * math.pi * np.array([0.16658 + 0.29277 * z + 0.07544 * z**2 + 0.21335 * z**3,
                                     0.33323 + 0.0053 * z + 0.17914 * z**2 + 0.20125 * z**3])


@lru_cache(maxsize=256)
def _nzv_unit(zeta: float) -> np.ndarray:
    x = _solve(_nzv_equations, _nzv_guess, zeta, lambda x: 0.0 < x[0] < x[1])
    if x is None:
        raise ParameterError(f'nzv: no negative unity-magnitude ZV shaper found for zeta {zeta}')
    return x


def nzv(omega, zeta=0.0) -> Shaper:
    """Negative unity-magnitude ZV shaper (Singhose et al. 2004, paper ref. [50], P = 1).

    Amplitudes [1, -1, 1]; for zeta = 0 at 0, T/6, T/3 (T = 2 pi / omega),
    one third of a period instead of ZV's half. With damping the two times
    solve V(omega, zeta) = 0 exactly.
    """
    omega, zeta = _check_mode(omega, zeta)
    t2, t3 = _nzv_unit(zeta) / omega
    return Shaper(np.array([1.0, -1.0, 1.0]), np.array([0.0, t2, t3]))


def _ei_equations(x, zeta, V):
    """Residual zero (Re, Im) at omega_lo and omega_hi; V at omega = 1 with a flat top."""
    a1, a2, t2, t3, w_lo, w_hi = x
    A, t = [a1, a2, 1.0 - a1 - a2], [0.0, t2, t3]
    P_lo, P_hi = _phasor(A, t, [w_lo, w_hi], zeta)
    P, dP = _phasor(A, t, 1.0, zeta, derivative=True)
    # d|P|/domega = Re(conj(P) dP) / |P|: zero where Re(conj(P) dP) is
    return [P_lo.real, P_lo.imag, P_hi.real, P_hi.imag, abs(P) - V, (P.conjugate() * dP).real]


@lru_cache(maxsize=256)
def _ei_unit(zeta: float, V: float) -> np.ndarray:
    def guess(_zeta):
        # exact for zeta = 0: |(1 - V)/2 + (1 + V)/2 cos(pi omega / omega0)| vanishes at phi
        phi = math.acos(-(1.0 - V) / (1.0 + V))
        return np.array([(1 + V) / 4, (1 - V) / 2, math.pi, 2 * math.pi, phi / math.pi, 2 - phi / math.pi])

    def valid(x):
        a1, a2, t2, t3, w_lo, w_hi = x
        return 0.0 < t2 < t3 and 0.0 < w_lo < 1.0 < w_hi and min(a1, a2, 1.0 - a1 - a2) > 0.0

    x = _solve(lambda x, z: _ei_equations(x, z, V), guess, zeta, valid)
    if x is None:
        raise ParameterError(f'ei: no extra-insensitive shaper with two zero-vibration frequencies '
                             f'for zeta {zeta} and V {V}')
    return x


def _check_tolerance(V) -> float:
    V = check_positive('V', V)
    if V >= 1.0:
        raise ParameterError(f'V must be < 1, got {V}')
    return V


def ei(omega, zeta=0.0, V=EI_TOLERANCE) -> Shaper:
    """Extra-Insensitive shaper (Singhose, Seering & Singer 1994), tolerance V.

    Residual exactly V at the design frequency, flat there (dV/domega = 0)
    and zero at two flanking frequencies (``ei_flanking_frequencies``), which
    widens the band of low residual beyond ZVD's at the same length. For
    zeta = 0: [(1+V)/4, (1-V)/2, (1+V)/4] at [0, T/2, T]. With damping the
    conditions are solved numerically; for V = 0.05 such a shaper exists up
    to zeta of about 0.6, beyond that this is a ParameterError.
    """
    omega, zeta = _check_mode(omega, zeta)
    a1, a2, t2, t3, _, _ = _ei_unit(zeta, _check_tolerance(V))
    return Shaper(np.array([a1, a2, 1.0 - a1 - a2]), np.array([0.0, t2, t3]) / omega)


def ei_flanking_frequencies(omega, zeta=0.0, V=EI_TOLERANCE) -> tuple[float, float]:
    """The frequencies (rad/s) below and above ``omega`` where ``ei(omega, zeta, V)`` leaves no vibration."""
    omega, zeta = _check_mode(omega, zeta)
    w_lo, w_hi = _ei_unit(zeta, _check_tolerance(V))[4:]
    return float(w_lo * omega), float(w_hi * omega)


def cascade(*shapers: Shaper) -> Shaper:
    """Convolution of impulse trains: A_i A_j at t_i + t_j, coinciding times merged."""
    if not shapers:
        raise ParameterError('cascade needs at least one shaper')
    A, t = shapers[0].amplitudes, shapers[0].times
    for s in shapers[1:]:
        A = np.multiply.outer(A, s.amplitudes).ravel()
        t = np.add.outer(t, s.times).ravel()
    order = np.argsort(t, kind='stable')
    A, t = A[order], t[order]
    # times equal up to rounding (e.g. two identical modes) are one impulse
    new = np.concatenate(([True], np.diff(t) > 1e-12 * max(1.0, t[-1])))
    groups = np.cumsum(new) - 1
    return Shaper(np.bincount(groups, weights=A), t[new])


#: Shaper design functions by name; a method's entry in ``methods.REGISTRY`` serves one (its ``design``).
SHAPERS = {'zv': zv, 'nzv': nzv, 'zvd': zvd, 'ei': ei, 'mzv': mzv, 'zvdd': zvdd}


def design(method: str, omegas, zeta=0.0) -> Shaper:
    """One ``method`` shaper per mode frequency in ``omegas`` (rad/s), cascaded (paper §4, ref. [13]).

    ``zeta``: the design damping ratio, one for all modes or one per mode.
    """
    try:
        make = SHAPERS[method]
    except KeyError:
        raise ParameterError(f'unknown shaper {method!r}; choose from {", ".join(SHAPERS)}') from None
    omegas = np.atleast_1d(np.asarray(omegas, dtype=float))
    if omegas.ndim != 1 or omegas.size == 0:
        raise ParameterError('omegas needs at least one frequency')
    zetas = np.broadcast_to(np.asarray(zeta, dtype=float), omegas.shape)
    return _designed(make, tuple(omegas.tolist()), tuple(zetas.tolist()))


@lru_cache(maxsize=256)
def _designed(make, omegas: tuple, zetas: tuple) -> Shaper:
    # kept: a Shaper is immutable, and a handover designs the running motion's shaper again, in milliseconds
    return cascade(*(make(w, z) for w, z in zip(omegas, zetas)))
