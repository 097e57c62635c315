"""Protected areas: axis-aligned boxes the masses must keep out of, by a margin (contract "Routes and
protected areas").

A box is six numbers in ``crane_base`` (x along the cart's travel, y along
the bridge's, z up, origin at the suspension point with cart = bridge = 0):
``x0 x1 y0 y1 z0 z1``, each pair min <= max, infinite allowed (a wall across
the whole runway: y from -inf to inf). ``KeepOut`` is the boxes and the margin;
``KeepOut.clearance`` judges a predicted path of both masses
(``mass_path.MassPath``): the smallest distance of a mass to a box over the
path, where, when, and which. A distance is Euclidean outside a box and the
negative depth inside it (the distance to the nearest face), so a path that
enters a box by 3 mm has the clearance -3 mm. Pure Python, no ROS import.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .plan import PlanError

#: The margin (m) the masses keep from every box unless told otherwise (contract ``keep_out_margin``).
DEFAULT_MARGIN = 0.02
#: The masses, as ``MassPath`` holds them: m1 the upper mass (the hook block), m2 the load.
MASSES = ('m1', 'm2')


#: Ternary search steps on each chord (``KeepOut.between_points``): (2/3)^40 of a step, under a micrometre.
CHORD_SEARCH_STEPS = 40


class KeepOutError(PlanError):
    """A keep-out box, a margin or a move that does not keep out: the message names the box or field."""


@dataclass(frozen=True)
class Box:
    """An axis-aligned box in ``crane_base`` (m): ``lower`` = (x0, y0, z0), ``upper`` = (x1, y1, z1).

    ``number`` is its place (1-based) among the boxes it was given with: how messages name it.
    """

    lower: tuple
    upper: tuple
    number: int = 1

    @property
    def name(self) -> str:
        """e.g. ``keep_out box 2 (x 0.25..0.35, y -inf..inf, z -2..-0.76 m)``."""
        spans = ', '.join(f'{axis} {lo:g}..{hi:g}' for axis, lo, hi in zip('xyz', self.lower, self.upper))
        return f'keep_out box {self.number} ({spans} m)'

    def distance(self, points) -> np.ndarray:
        """Signed distance (m) of ``points`` (..., 3) to the box: Euclidean outside, minus the depth inside."""
        p = np.asarray(points, dtype=float)
        lo, hi = np.asarray(self.lower), np.asarray(self.upper)
        outside = np.maximum(np.maximum(lo - p, p - hi), 0.0)  # an unbounded side gives -inf here, inf below
        depth = np.minimum(p - lo, hi - p)
        euclid = np.sqrt(np.sum(outside ** 2, axis=-1))
        return np.where(euclid > 0.0, euclid, -np.min(depth, axis=-1))

    def contains(self, point, margin: float = 0.0) -> bool:
        """Whether ``point`` (3,) is inside the box grown by ``margin``."""
        return bool(self.distance(point) < margin)


def boxes_from_flat(values: Sequence[float], field: str = 'keep_out') -> tuple[Box, ...]:
    """The boxes of a flat array of 6 k numbers (``x0 x1 y0 y1 z0 z1`` each), KeepOutError naming ``field``."""
    values = [float(v) for v in values]
    if len(values) % 6:
        raise KeepOutError(f'{field}: {len(values)} number(s); a box is six (x0 x1 y0 y1 z0 z1), '
                           f'so the length must be a multiple of 6')
    boxes = []
    for k in range(len(values) // 6):
        x0, x1, y0, y1, z0, z1 = values[6 * k:6 * k + 6]
        lower, upper = (x0, y0, z0), (x1, y1, z1)
        for axis, lo, hi in zip('xyz', lower, upper):
            if math.isnan(lo) or math.isnan(hi):
                raise KeepOutError(f'{field}: box {k + 1}: {axis} is NaN')
            if not lo <= hi:
                raise KeepOutError(f'{field}: box {k + 1}: {axis} min {lo:g} > max {hi:g}')
            if lo == math.inf or hi == -math.inf:
                raise KeepOutError(f'{field}: box {k + 1}: {axis} span {lo:g}..{hi:g} holds no point')
        boxes.append(Box(lower, upper, k + 1))
    return tuple(boxes)


@dataclass(frozen=True)
class Clearance:
    """The smallest distance (m) of a mass to a box over a path: which mass, which box, when (s of the path's
    time). ``distance`` is inf (and ``box`` None) without boxes."""

    distance: float
    box: Box | None = None
    mass: str = ''
    time: float = math.nan
    point: tuple = ()

    def describe(self) -> str:
        """e.g. ``the load (m2) comes 3.1 mm into keep_out box 1 (...) at t = 1.24 s``."""
        if self.box is None:
            return 'no keep_out box'
        who = 'the load (m2)' if self.mass == 'm2' else 'the upper mass (m1)'
        if self.distance < 0.0:
            how = f'comes {-self.distance * 1e3:.1f} mm into'
        else:
            how = f'passes {self.distance * 1e3:.1f} mm from'
        return f'{who} {how} {self.box.name} at t = {self.time:.2f} s'


@dataclass(frozen=True)
class KeepOut:
    """The protected areas of a planner: its boxes and the margin (m) both masses keep from them."""

    boxes: tuple = ()
    margin: float = DEFAULT_MARGIN

    def __post_init__(self):
        if not (math.isfinite(self.margin) and self.margin >= 0.0):
            raise KeepOutError(f'keep_out_margin: must be finite and >= 0 m, got {self.margin:g}')

    @classmethod
    def from_values(cls, flat: Sequence[float] = (), margin: float = DEFAULT_MARGIN) -> 'KeepOut':
        """From the ``keep_out`` parameter's flat array and ``keep_out_margin``."""
        return cls(boxes_from_flat(flat), float(margin))

    def __bool__(self) -> bool:
        return bool(self.boxes)

    def clearance(self, path) -> Clearance:
        """The smallest distance of either mass of ``path`` (a ``mass_path.MassPath``) to any box."""
        best = Clearance(math.inf)
        for box in self.boxes:
            for mass in MASSES:
                points = getattr(path, mass)
                d = box.distance(points)
                k = int(np.argmin(d))
                if d[k] < best.distance:
                    best = Clearance(float(d[k]), box, mass, float(path.t[k]), tuple(float(v) for v in points[k]))
        return best

    def between_points(self, path) -> Clearance:
        """The smallest distance of either mass of ``path`` (a ``mass_path.MassPath``) to any box along the
        straight steps between its points (at the points too).

        A box's signed distance is a convex function of the point, so along one step it has one minimum,
        found by ternary search on all steps at once. The steps are chords of the path: between two points a
        mass may bulge toward a box by the chord's sagitta (the caller allows for it).
        """
        if len(path.t) < 2:
            return self.clearance(path)
        best = Clearance(math.inf)
        for box in self.boxes:
            for mass in MASSES:
                points = getattr(path, mass)
                start, step = points[:-1], np.diff(points, axis=0)
                lo, hi = np.zeros(len(step)), np.ones(len(step))
                for _ in range(CHORD_SEARCH_STEPS):
                    a, b = lo + (hi - lo) / 3.0, hi - (hi - lo) / 3.0
                    nearer_a = box.distance(start + a[:, None] * step) < box.distance(start + b[:, None] * step)
                    hi, lo = np.where(nearer_a, b, hi), np.where(nearer_a, lo, a)
                s = (lo + hi) / 2.0
                nearest = start + s[:, None] * step
                d = box.distance(nearest)
                k = int(np.argmin(d))
                if d[k] < best.distance:
                    t = path.t[k] + s[k] * (path.t[k + 1] - path.t[k])
                    best = Clearance(float(d[k]), box, mass, float(t), tuple(float(v) for v in nearest[k]))
        return best

    def rest_violation(self, points: dict) -> str | None:
        """Why a mass at rest (``points``: {mass: (3,)}) does not keep out (within the margin of a box), or
        None if it does."""
        for box in self.boxes:
            for mass, point in points.items():
                d = float(box.distance(point))
                if d < self.margin:
                    who = 'the load (m2)' if mass == 'm2' else 'the upper mass (m1)'
                    inside = 'inside' if d < 0.0 else f'{d * 1e3:.1f} mm from (margin {self.margin * 1e3:g} mm)'
                    return (f'{who} at rest there, at ({", ".join(f"{v:.3f}" for v in point)}) m, is {inside} '
                            f'{box.name}')
        return None

    def check(self, path, what: str = 'the plan') -> Clearance:
        """The clearance of ``path``; KeepOutError naming the box and the mass if it is below the margin."""
        clearance = self.clearance(path)
        if clearance.distance < self.margin:
            raise KeepOutError(f'{what} does not keep out: {clearance.describe()} (margin '
                               f'{self.margin * 1e3:g} mm)')
        return clearance
