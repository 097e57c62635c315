"""Knots of a plan: as few samples as let the streamer reproduce it exactly enough.

The streamer rebuilds the reference between a plan's knots by quintic
Hermite interpolation of position, velocity and acceleration (``hermite``),
which is exact on polynomial pieces of degree <= 5. So the knots are every
breakpoint of the plan (``Plan.breakpoints``: shaper impulse times and the
ends of the shifted base profiles, collocation interval ends), plus, on a
piece that is not such a polynomial, as few more as keep the interpolation
within ``position_tol`` in position and ``acceleration_tol`` times the
plan's peak in acceleration. A shaped plan needs its breakpoints only
(8 knots for ZV at 3 s), and says so (``Plan.quintic_pieces``: it is not
checked then, which a shaper's handover, due in milliseconds, needs);
NVF/RVF, of degree 6 in position per collocation interval, about one knot
per interval. Messages stay short (rclpy turns every knot into Python
objects) and the stream is the plan itself, not a 10 ms approximation of it.

Knot times are multiples of ``resolution`` (1 ns, the resolution of ROS
stamps), and the plan is sampled at exactly those times: on a 1 ms segment,
sampling at t but stamping t rounded to the nanosecond would put the
interpolated acceleration off by 0.3 % of its peak. Pure numpy, no ROS import.
"""
from __future__ import annotations

import numpy as np

from .hermite import QuinticHermite

#: Position tolerance (m) and acceleration tolerance (fraction of the plan's peak |a|).
POSITION_TOL = 1e-6
ACCELERATION_TOL = 1e-3
#: The interpolation error is checked at this many points inside each segment and
#: held to half the tolerance there: between checks it may be a little larger. Odd,
#: so the middle, where the error of a smooth piece peaks, is one of them.
_CHECKS = 5
_MARGIN = 0.5
#: Segments are not split below this length (s); smooth plans never get there.
MIN_SPACING = 1e-4
#: Knot times are multiples of this (s): ROS stamps count nanoseconds.
RESOLUTION = 1e-9


def knot_times(plan, position_tol: float = POSITION_TOL, acceleration_tol: float = ACCELERATION_TOL,
               min_spacing: float = MIN_SPACING, resolution: float = RESOLUTION) -> np.ndarray:
    """Knot times (s) of ``plan``, 0 and its duration included, increasing, multiples of ``resolution``.

    A plan of several joints (``AxesPlan``) gets the union of its joints' knots.
    Starts from the plan's breakpoints and halves every segment on which the
    quintic Hermite interpolant of the plan's own samples at the knots
    strays from ``plan.evaluate`` by more than the tolerances (checked at
    ``_CHECKS`` interior points per segment, with margin ``_MARGIN``).
    """
    def grid(x):
        return np.rint(np.asarray(x, dtype=float) / resolution) * resolution

    axes = getattr(plan, 'axes', None)
    if axes:  # several joints: every knot any of them needs (more knots only bring each closer)
        every = np.concatenate([knot_times(axis, position_tol, acceleration_tol, min_spacing, resolution)
                                for axis in axes.values()])
        # each axis's own end is off the grid (its duration): an axis held after the others' motion ends where
        # one of their knots lies, to within a stamp's resolution, and would carry its stamp twice
        inner = np.unique(grid(every))
        return np.union1d(inner[(inner >= resolution) & (inner <= plan.duration - resolution)], [0.0, plan.duration])

    t = np.unique(grid(np.clip(plan.breakpoints(), 0.0, plan.duration)))
    # a breakpoint at the end rounds to the grid up to half a step below T: it is the end knot
    # (two knots closer than a stamp's resolution would carry the same stamp)
    t = np.union1d(t[(t >= resolution) & (t <= plan.duration - resolution)], [0.0, plan.duration])
    if plan.quintic_pieces:  # the breakpoints reproduce it exactly: nothing to check (a shaped plan)
        return t
    inner = (np.arange(_CHECKS) + 0.5) / _CHECKS
    a_peak = 0.0
    while True:
        knots = plan.evaluate(t)
        h = np.diff(t)
        tc = (t[:-1, None] + h[:, None] * inner).ravel()
        exact = plan.evaluate(tc)
        a_peak = max(a_peak, float(np.max(np.abs(knots.acceleration))), float(np.max(np.abs(exact.acceleration))))
        p, _, a = QuinticHermite(t, knots.position, knots.velocity, knots.acceleration)(tc)
        bad = ((np.abs(p - exact.position) > _MARGIN * position_tol)
               | (np.abs(a - exact.acceleration) > _MARGIN * acceleration_tol * a_peak))
        bad = bad.reshape(h.size, _CHECKS).any(axis=1) & (h >= 2.0 * min_spacing)
        if not bad.any():
            return t
        t = np.sort(np.concatenate([t, grid(t[:-1][bad] + 0.5 * h[bad])]))


def knot_columns(plan, times, starts) -> tuple:
    """(position, velocity, acceleration) of ``plan`` at ``times``, each (len(times), joints): a column per
    joint (an ``AxesPlan``'s axes in order, the cart first; else the plan alone), positions absolute from the
    joints' ``starts`` (m), as a trajectory and ``ReferenceStream.accept`` take them."""
    axes = list((getattr(plan, 'axes', None) or {'': plan}).values())
    if len(axes) != len(starts):
        raise ValueError(f'a plan of {len(axes)} joint(s) needs as many starts, not {len(starts)}')
    samples = [axis.evaluate(times) for axis in axes]
    return (np.column_stack([s0 + s.position for s, s0 in zip(samples, starts)]),
            np.column_stack([s.velocity for s in samples]), np.column_stack([s.acceleration for s in samples]))

