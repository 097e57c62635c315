"""Shaped plans: a rest-to-rest base motion convolved with a cascaded input shaper (paper §4).

The reference is sum_i A_i q(t - t_i), q the base motion (``profiles``: the
paper's quintic, or the jerk-limited time-optimal profile under axis limits)
lasting T - t_N so that the whole motion ends exactly at the requested T (the
paper's 1.789 s base for ZV and 2.192 s for NZV at T = 3 s).

With several travel axes (the cart and the bridge, contract "The spatial
crane") the move is straight: every axis's base is the same path scaled by
its displacement (``BaseProfile.along``), convolved with the same shaper
(linearized about rest the swing has the same two modes in x and in y), so
the shaped reference stays on the straight line from start to goal. The
path is planned for the axis moving farthest under limits that keep every
axis within its own (``limits.path_limits``): ``shaped_axes``,
``fastest_shaped_axes``.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from numpy.polynomial.polynomial import polyder, polyval

from crane_msgs_py.crane.axes import AxisLimits

from .limits import check_fastest_request, lead_axis, path_limits, shortest_duration_bound
from .plan import Plan, PlanError
from .profiles import ORDER, BaseProfile, limited_base, quintic_base
from .shapers import Shaper, design

#: Matrices taking position coefficients (powers of t) to those of its 0th..3rd derivatives, (4, 6, 6)
#: (the highest powers of a derivative are zero).
_DERIVATIVES = np.array([[np.pad(polyder(np.eye(ORDER + 1)[i], n), (0, n)) for i in range(ORDER + 1)]
                         for n in range(4)])

#: Samples per piece when looking for a plan's peaks (``ShapedPlan.peaks``), as fractions of the piece.
_PEAK_SAMPLES = 48
_PEAK_GRID = np.linspace(0.0, 1.0, _PEAK_SAMPLES)[None, :]


@dataclass(kw_only=True)
class ShapedPlan(Plan):
    """Plan of a shaper method; exact (analytic) at any time.

    Attributes:
        shaper: the cascaded impulse train (times in s from the start).
        base: the motion being shaped, lasting T - shaper.duration.
    """

    shaper: Shaper
    base: BaseProfile
    _breaks: np.ndarray = field(init=False, repr=False, compare=False)
    _coefficients: list = field(init=False, repr=False, compare=False)

    @property
    def base_duration(self) -> float:
        return self.base.duration

    def __post_init__(self):
        # sum_i A_i q(t - t_i) changes form only where a piece of a shifted base starts
        # or a shifted base ends; in between it is one polynomial, kept as its Taylor
        # coefficients at the piece's start so a sample costs one polynomial, not one
        # per impulse.
        starts, base, D = self.shaper.times, self.base, self.displacement
        Tb = base.duration
        ends = starts + Tb
        ends[-1] = self.duration  # equal up to rounding; exact so T lands in the resting piece
        breaks = np.unique(np.concatenate([starts + b for b in base.breaks] + [ends]))
        # which bases move on a piece, and on which of their pieces, judged inside it
        # (never at a rounded edge)
        inside = np.append(0.5 * (breaks[:-1] + breaks[1:]), np.inf)[:, None]
        moving = (starts <= inside) & (inside < ends)
        local = breaks[:, None] - starts
        piece = base.piece(np.where(moving, inside - starts, 0.0))
        taylor = base.taylor(local.ravel(), piece.ravel()).reshape(*local.shape, ORDER + 1)
        taylor = np.where(moving[:, :, None], taylor, 0.0)
        taylor[:, :, 0] += np.where(inside >= ends, D, 0.0)
        coefficients = np.einsum('bik,i->bk', taylor, self.shaper.amplitudes)
        self._breaks = breaks
        # position, velocity, acceleration, jerk per piece, in powers of (t - break): (4, pieces, 6)
        self._coefficients = coefficients @ _DERIVATIVES

    def peaks(self) -> tuple[float, float, float]:
        """Peak |velocity|, |acceleration|, |jerk| over [0, T], to ~1e-7 relative.

        Each piece is sampled at ``_PEAK_SAMPLES`` points and the largest sample
        refined by the parabola through it and its neighbours: exact to a few
        parts in 1e8 for these degree <= 4 pieces, and far cheaper than dense
        sampling of the whole plan (``fastest`` evaluates it a dozen times).
        """
        breaks = self._breaks[self._breaks < self.duration]
        n = breaks.size
        x = (np.append(breaks[1:], self.duration) - breaks)[:, None] * _PEAK_GRID  # (pieces, samples)
        c = self._coefficients[1:, :n]  # velocity, acceleration, jerk: (3, pieces, 6)
        values = c[:, :, -1:] * x
        for k in range(ORDER - 1, 0, -1):  # Horner, all orders and pieces at once
            values += c[:, :, k:k + 1]
            values *= x
        values += c[:, :, :1]
        values = np.abs(values).reshape(3, -1)
        best = np.argmax(values, axis=1)
        rows = np.arange(3)
        peak = values[rows, best]
        # the parabola through the largest sample and its neighbours in the same piece
        inner = (best % _PEAK_SAMPLES > 0) & (best % _PEAK_SAMPLES < _PEAK_SAMPLES - 1)
        y0 = values[rows, np.where(inner, best - 1, best)]
        y2 = values[rows, np.where(inner, best + 1, best)]
        curvature = y0 - 2.0 * peak + y2
        refine = inner & (curvature < 0.0)
        peak = np.where(refine, peak - 0.125 * (y2 - y0) ** 2 / np.where(refine, curvature, -1.0), peak)
        return tuple(float(p) for p in peak)

    def breakpoints(self) -> np.ndarray:
        return self._breaks[self._breaks <= self.duration]

    @property
    def quintic_pieces(self) -> bool:
        return ORDER <= 5  # shifted copies of the base's pieces, summed

    def _evaluate(self, t):
        piece = np.searchsorted(self._breaks, t, side='right') - 1
        x = t - self._breaks[piece]
        return tuple(polyval(x, c[piece].T, tensor=False) for c in self._coefficients)


def shaped_plan(method: str, displacement: float, duration: float, omegas, zeta, base: str = 'quintic',
                limits: AxisLimits = AxisLimits()) -> ShapedPlan:
    """Plan from 0 to ``displacement`` (m) in ``duration`` (s) with ``method``'s shaper.

    One shaper per mode frequency in ``omegas`` (rad/s) with damping ratio
    ``zeta`` (one for all, or one per mode), cascaded, applied to the ``base``
    motion (``quintic``: the paper's; ``limits``: the jerk-limited time-optimal
    profile under the axis's ``limits``,
    stretched to the base's length). A duration not longer than the shaper
    cannot be met and is a PlanError (contract: never a silently longer motion).
    """
    shaper = design(method, omegas, zeta)
    displacement, duration = float(displacement), float(duration)
    if not shaper.duration < duration < math.inf:
        raise PlanError(f'{method} needs a duration longer than its shaper '
                        f'({shaper.duration:.3f} s), got {duration} s')
    length = duration - shaper.duration
    if base == 'quintic':
        profile = quintic_base(displacement, length)
    elif base == 'limits':
        profile = limited_base(displacement, *limits, duration=length)
    else:
        raise PlanError(f"base must be 'quintic' or 'limits', got {base!r}")
    return _described(ShapedPlan(method=method, displacement=displacement, duration=duration, info={},
                                 shaper=shaper, base=profile), omegas, zeta)


def _described(plan: ShapedPlan, omegas, zeta) -> ShapedPlan:
    """``plan`` with its ``info``: the shaper's design and the base (what a report shows)."""
    plan.info.update({
        'omegas': [float(w) for w in np.atleast_1d(omegas)],
        'zeta': np.broadcast_to(np.asarray(zeta, dtype=float), np.shape(np.atleast_1d(omegas))).tolist(),
        'impulse_times': plan.shaper.times.tolist(),
        'impulse_amplitudes': plan.shaper.amplitudes.tolist(),
        'shaper_duration': plan.shaper.duration,
        'base': plan.base.kind,
        'base_duration': plan.base.duration,
    })
    return plan


def _limit_ratio(plan: ShapedPlan, limits) -> float:
    """The largest of the plan's peak |v|, |a|, |j| over its limit (limits None are skipped)."""
    return max(peak / limit for peak, limit in zip(plan.peaks(), limits) if limit is not None)


#: ``fastest_shaped`` aims this far below the binding limit, so that the plan's
#: peak (known to ~1e-5 relative, ``ShapedPlan.peaks``) never exceeds it.
FASTEST_MARGIN = 1e-4


def fastest_shaped(method: str, displacement: float, omegas, zeta, limits, base: str = 'quintic') -> ShapedPlan:
    """The shortest ``method`` plan of ``displacement`` (m) within ``limits``.

    ``limits``: the axis's ``AxisLimits``, at least one of velocity and acceleration. The shaper's
    own length is fixed, so what is searched is the base motion:

    * quintic base: the shortest base whose *shaped* plan stays within the
      limits. Shaping spreads the base's peaks (ZV halves a short base's), so
      the base may exceed a limit the plan keeps; at T* the plan's binding
      peak meets its limit. The shaped peaks fall as the base lengthens, not
      always monotonically, so the search scans up (``_first_feasible``) from
      below (no rest-to-rest motion is shorter than ``shortest_duration_bound``)
      towards a base that is within the limits on its own.
    * limits base: the jerk-limited time-optimal base under the limits (ruckig),
      the shortest base that is itself within them. Every shaper with positive
      impulses then keeps the plan within the limits by construction; one with
      a negative impulse (NZV) may not, and its base is stretched until it does.
    """

    from .profiles import quintic_duration
    v, a, j = limits
    D = check_fastest_request(displacement, limits)
    shaper = design(method, omegas, zeta)
    Ts = shaper.duration

    fastest_base = limited_base(D, v, a, j) if base == 'limits' else None

    def make(length):  # the plan with a base of this length, not yet described (the search's many)
        profile = quintic_base(D, length) if base == 'quintic' else fastest_base.stretched(length)
        return ShapedPlan(method=method, displacement=D, duration=Ts + length, info={}, shaper=shaper,
                          base=profile)

    target = 1.0 - FASTEST_MARGIN
    ratios = {}  # base length -> limit ratio: Brent starts from the scan's last two lengths

    def ratio(length) -> float:
        if length not in ratios:
            ratios[length] = _limit_ratio(make(length), limits)
        return ratios[length]

    def beyond(length) -> float:  # > 0: the plan with this base length exceeds a limit (log: see Brent)
        return math.log(ratio(length) / target)

    if base == 'quintic':
        # A base shorter than the closest impulse spacing does not overlap itself: the plan's
        # peaks are then the base's times the largest |amplitude|, which bounds the search below.
        spacing = float(np.min(np.diff(shaper.times))) if shaper.times.size > 1 else math.inf
        largest = float(np.max(np.abs(shaper.amplitudes)))
        alone = quintic_duration(largest * D, v, a, j)
        lo = max(shortest_duration_bound(D, limits) - Ts, min(spacing, alone), 1e-9)
        if v is not None and np.all(shaper.amplitudes > 0.0):
            # the base's velocity is >= 0, so with positive impulses the plan's is at least the
            # largest impulse's share of it wherever that one peaks, however the bases overlap
            lo = max(lo, quintic_duration(largest * D, v))
        hi = max(quintic_duration(D, v, a, j), lo)
    elif base == 'limits':
        lo = fastest_base.duration
        if ratio(lo) <= 1.0 + 1e-9:  # the base's own plateaus may meet a limit exactly
            return _described(make(lo), omegas, zeta)
        hi = 1.5 * lo
    else:
        raise PlanError(f"base must be 'quintic' or 'limits', got {base!r}")
    for _ in range(40):  # a negative impulse can push the shaped peaks above the base's
        if beyond(hi) <= 0.0:
            break
        lo, hi = hi, 1.5 * hi
    else:
        raise PlanError(f'{method}: no plan of {D:g} m found within the limits')
    # with a jerk limit the shaped jerk jumps (the quintic's jerk steps at its ends add up
    # where two shifted bases meet): feasible windows are narrow, scan finely throughout;
    # velocity and acceleration are continuous in the base length, their dips wide
    if j is not None:
        found = _first_feasible(beyond, lo, hi, steps=(_FINE_STEP, _FINE_STEP))
    else:
        found = _first_feasible(beyond, lo, hi, steps=(_COARSE_STEP,))
    return _described(make(found if ratio(found) <= 1.0 else found * (1.0 + _FINE_STEP)), omegas, zeta)


def _first_feasible(beyond, lo: float, hi: float, steps) -> float:
    """About the smallest x in [lo, hi] with beyond(x) <= 0, beyond(hi) <= 0 given.

    Scans up in relative ``steps`` (each scan through the step before the
    previous scan's first feasible point), then refines by Brent's method: the
    shaped peaks are not monotonic in the base length (MZV's dip by ~7 % over
    a few per cent), so a plain bracket from lo to hi can land above a shorter
    feasible length.
    """
    from scipy.optimize import brentq
    if hi <= lo or beyond(lo) <= 0.0:
        return lo if beyond(lo) <= 0.0 else hi
    previous, x = lo, lo
    for step in steps:
        x = previous
        while True:
            x = min(x * (1.0 + step), hi)
            if beyond(x) <= 0.0:
                break
            previous = x
        # previous: infeasible, x: feasible, at most one step apart
    if not previous < x:
        return x
    # in log-log coordinates a peak of order k is about linear (c D / Tb^k), so Brent's first
    # secant steps land close, in fewer evaluations than bisection would take
    u = brentq(lambda u: beyond(math.exp(u)), math.log(previous), math.log(x), xtol=1e-6)
    return math.exp(u)


#: Relative steps of ``_first_feasible``'s scans.
_COARSE_STEP, _FINE_STEP = 0.1, 0.005


def along(plan: ShapedPlan, displacements: Mapping[str, float]) -> dict[str, ShapedPlan]:
    """Every axis's plan of a straight move (by axis name, in ``displacements``' order) whose lead axis
    (``limits.lead_axis``) has the plan ``plan``: the same shaper on the same base path, scaled to each axis's
    displacement, sum_i A_i (D / D_lead) q(t - t_i)."""
    lead = lead_axis(displacements)
    return {name: plan if name == lead else
            ShapedPlan(method=plan.method, displacement=float(D), duration=plan.duration, info=dict(plan.info),
                       shaper=plan.shaper, base=plan.base.along(D))
            for name, D in displacements.items()}


def shaped_axes(method: str, displacements: Mapping[str, float], duration: float, omegas, zeta,
                base: str = 'quintic', limits: Mapping[str, AxisLimits] | None = None) -> dict[str, ShapedPlan]:
    """``shaped_plan`` of a straight move of several travel axes: ``displacements`` (m) by axis name.

    The lead axis's plan is ``shaped_plan``'s, its ``limits`` base under
    ``limits.path_limits`` (every axis's ``limits``, by name), the others'
    its shares (``along``).
    """
    lead = lead_axis(displacements)
    lead_limits = path_limits(displacements, limits or {})
    return along(shaped_plan(method, displacements[lead], duration, omegas, zeta, base, lead_limits), displacements)


def fastest_shaped_axes(method: str, displacements: Mapping[str, float], omegas, zeta,
                        limits: Mapping[str, AxisLimits], base: str = 'quintic') -> dict[str, ShapedPlan]:
    """``fastest_shaped`` of a straight move of several travel axes: the shortest plan with every axis within
    its own ``limits`` (by name), all ending together.

    Each axis's peaks are |D_i / D_lead| times the lead's, so the lead's
    fastest plan under ``limits.path_limits`` is the whole move's: the
    binding limit is then the one of the axis (or axes) it came from.
    """
    lead = lead_axis(displacements)
    lead_limits = path_limits(displacements, limits)
    if not lead_limits.bounds_speed:
        names = [n for name in displacements if name in limits for n in limits[name].names[:2]]
        raise PlanError(f'the fastest plan needs a velocity or acceleration limit of a moving axis '
                        f'({", ".join(names)})')
    return along(fastest_shaped(method, displacements[lead], omegas, zeta, lead_limits, base), displacements)
