"""Swing figures of the contract: peak and RMS during the motion, residual after it.

For a motion of duration T observed for S more seconds: peak |theta1|,
|theta2| and their RMS over [0, T]; over [T, T + S] the residual peak
|theta1|, |theta2| and the peak horizontal excursion of the load m2 from its
rest position below the cart, in millimetres (the paper's residual load
swing, §4 and Fig. 4). Pure numpy, no ROS import.
"""
from __future__ import annotations

import numpy as np

from crane_msgs_py.crane.geometry import load_excursion

from .simulator import PlantBatch, SimResult, SimulationError

#: Relative slack on window ends, so grid times t0 + k dt that round to just
#: beside T or T + S are still counted in.
_WINDOW_TOL = 1e-9


def peak(x, axis=-1):
    """max |x| along ``axis`` (a float for 1-D input)."""
    out = np.max(np.abs(np.asarray(x, dtype=float)), axis=axis)
    return float(out) if np.ndim(out) == 0 else out


def rms(x, t=None, axis=-1):
    """Root mean square of ``x`` along ``axis``; time-weighted (trapezoidal) if sample times ``t`` are given.

    The time-weighted form does not depend on how densely a stretch is
    sampled, and is exact for a sinusoid over whole periods.
    """
    x = np.asarray(x, dtype=float)
    if t is None or np.size(t) < 2:
        out = np.sqrt(np.mean(x * x, axis=axis))
    else:
        t = np.asarray(t, dtype=float)
        out = np.sqrt(np.trapezoid(x * x, t, axis=axis) / (t[-1] - t[0]))
    return float(out) if np.ndim(out) == 0 else out


def window(t, start: float, end: float):
    """Boolean mask of the times ``t`` in [start, end] (ends included up to rounding).

    Raises SimulationError when the samples do not cover the window.
    """
    t = np.asarray(t, dtype=float)
    tol = _WINDOW_TOL * max(1.0, abs(start), abs(end))
    if t.size == 0 or t[0] > start + tol or t[-1] < end - tol:
        span = f'[{t[0]}, {t[-1]}]' if t.size else 'nothing'
        raise SimulationError(f'samples cover {span}, not the window [{start}, {end}]')
    return (t >= start - tol) & (t <= end + tol)


def residual_load_mm(t, theta1, theta2, L1, L2, after: float, until: float | None = None):
    """Peak |load excursion| (mm) of a sampled swing record over [after, until].

    ``t``, ``theta1``, ``theta2`` are a measurement (e.g. joint_states at
    50 Hz) or a simulation; ``L1`` a length or one per sample (a hoist);
    ``until`` defaults to the last sample. A sampled
    record sees the excursion only at its samples, as a measurement does.
    """
    t = np.asarray(t, dtype=float)
    until = float(t[-1]) if until is None else until
    mask = window(t, after, until)
    if np.ndim(L1) and np.shape(L1)[-1] == t.size:  # a length per sample (hoisting)
        L1 = np.asarray(L1)[..., mask]
    x = load_excursion(np.asarray(theta1, dtype=float)[..., mask],
                       np.asarray(theta2, dtype=float)[..., mask], L1, L2)
    return 1e3 * peak(x)


def swing_metrics(result: SimResult, plants, duration: float, settle: float) -> list[dict]:
    """The contract's swing figures, one dict per batch member of ``result``.

    Args:
        result: a simulation covering [0, duration + settle].
        plants: the simulated plants (for L1, L2); None means ``result.plants``. With a hoist the
            result's own L1(t) counts.
        duration: T (s), the end of the motion.
        settle: S (s), how long the residual swing is observed after T.

    Returns:
        ``[{'peak': {'theta1', 'theta2'}, 'rms': {'theta1', 'theta2'},
        'residual': {'theta1', 'theta2', 'load_mm'}}, ...]`` in rad and mm.
    """
    if not duration > 0.0 or not settle >= 0.0:
        raise SimulationError(f'duration must be > 0 and settle >= 0, got {duration}, {settle}')
    p = result.plants if plants is None else PlantBatch.of(plants)
    if len(p) != len(result):
        raise SimulationError(f'{len(p)} plants for a batch of {len(result)}')
    t = result.t
    motion = window(t, 0.0, duration)
    after = window(t, duration, duration + settle)
    th1, th2 = result.theta1, result.theta2
    figures = {
        'peak': (peak(th1[:, motion]), peak(th2[:, motion])),
        'rms': (rms(th1[:, motion], t[motion]), rms(th2[:, motion], t[motion])),
        'residual': (peak(th1[:, after]), peak(th2[:, after])),
    }
    L1 = p.L1[:, None] if result.L1 is None else result.L1  # with a hoist, the length at each instant
    load_mm = residual_load_mm(t, th1, th2, L1, p.L2[:, None], duration, duration + settle)
    return [{
        'peak': {'theta1': float(figures['peak'][0][i]), 'theta2': float(figures['peak'][1][i])},
        'rms': {'theta1': float(figures['rms'][0][i]), 'theta2': float(figures['rms'][1][i])},
        'residual': {'theta1': float(figures['residual'][0][i]), 'theta2': float(figures['residual'][1][i]),
                     'load_mm': float(load_mm[i])},
    } for i in range(len(p))]
