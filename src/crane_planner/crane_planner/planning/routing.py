"""Routes past keep-out boxes (contract "Routes and protected areas"): which ways there are, and where the
optimizer starts from.

When the direct move would bring a mass within the margin of a box, the
load can go **over** it (the hoist shortens the rope while the cart passes
the box and lowers it again) or **around** it (the bridge steps aside and
back). ``route_candidates`` lists the ways the served axes allow, each a
``Route``: the axis that makes the detour, how far (m), and the part of the
motion (fractions of T) the straight path spends over the box's footprint.
``route_guess`` turns a route into the NLP's start point: the problem's
rest-to-rest guess with the detour added as a plateau with smooth ramps on
the route's axis. NVF/RVF then solve the problem with the keep-out path
constraints (``collocation.Transcription`` with boxes), so the optimizer,
not the guess, decides the route's shape; ``direct.DirectSolver.solve_constrained``
runs it. Via points (``via_nodes``) are equality constraints on the reference
at the collocation points where the straight path's timing would pass them.
Pure Python, no ROS import.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.polynomial import polynomial as poly

from .keep_out import KeepOut
from .plan import PlanError
from .problem import AXIS_SCALES, AXIS_STATES, PROBLEM_PARAMETERS
from .profiles import QUINTIC

#: Beyond the margin, how much more (m) a route's detour clears a box by in its start point, and the
#: keep-out constraints of the NLP by (``collocation.keep_out_values``): between collocation points the
#: masses may come a little nearer than at them, and the path is checked at the margin itself afterwards.
ROUTE_EXTRA = 0.03
NLP_EXTRA = 0.005
#: The shortest upper rope (m) a route over a box may hoist to.
MIN_ROPE = 0.1
#: How far (m) around a box's footprint the straight path counts as passing it (the load's swing).
FOOTPRINT_SLACK = 0.1


@dataclass(frozen=True)
class Route:
    """One way past the boxes: ``kind`` ``over`` (the hoist, ``excursion`` < 0: the rope shortened by that
    much) or ``around`` (the bridge, ``excursion`` its sideways step, m), made while the straight path is
    over the boxes' footprints, from ``enter`` to ``leave`` (fractions of the duration)."""

    kind: str
    axis: str
    excursion: float
    enter: float
    leave: float


def _passing(keep_out: KeepOut, origin: dict, moves: dict) -> tuple[list, float, float]:
    """(boxes the straight path's footprint passes, enter, leave): the fractions of T during which the
    suspension point's quintic path is within ``FOOTPRINT_SLACK`` + margin of their x-y footprints."""
    s = np.linspace(0.0, 1.0, 401)
    q = poly.polyval(s, QUINTIC[0])
    x = origin.get('cart', 0.0) + moves.get('cart', 0.0) * q
    y = origin.get('bridge', 0.0) + moves.get('bridge', 0.0) * q
    slack = FOOTPRINT_SLACK + keep_out.margin
    boxes, inside = [], np.zeros_like(s, dtype=bool)
    for box in keep_out.boxes:
        over = ((x > box.lower[0] - slack) & (x < box.upper[0] + slack)
                & (y > box.lower[1] - slack) & (y < box.upper[1] + slack))
        if over.any():
            boxes.append(box)
            inside |= over
    if not boxes:
        return [], 0.0, 1.0
    k = np.flatnonzero(inside)
    return boxes, float(s[k[0]]), float(s[k[-1]])


def route_candidates(keep_out: KeepOut, origin: dict, moves: dict, L1: float, L2: float, axes) -> list[Route]:
    """The routes past ``keep_out``'s boxes that the axes ``axes`` allow, for a move of ``moves`` (m, by
    axis; the hoist's a change of rope length) from ``origin`` (the travel axes' start positions), the rope
    ``L1`` at the start: over (with a hoist, if the rope can be shortened enough), around either side (with
    a bridge, if the boxes end sideways), the smaller detour first."""
    boxes, enter, leave = _passing(keep_out, origin, moves)
    if not boxes:
        return []
    routes = []
    if 'hoist' in axes:
        rope = max(L1, L1 + moves.get('hoist', 0.0))  # the longer of the start's and the goal's
        top = max(box.upper[2] for box in boxes)
        lift = rope + L2 + top + keep_out.margin + ROUTE_EXTRA  # the load's rest height clear of the top
        if lift > 0.0 and math.isfinite(top) and min(L1, rope) - lift >= MIN_ROPE:
            routes.append(Route('over', 'hoist', -lift, enter, leave))
    if 'bridge' in axes:
        y0 = origin.get('bridge', 0.0)
        right = max(box.upper[1] for box in boxes) + keep_out.margin + ROUTE_EXTRA - y0
        left = min(box.lower[1] for box in boxes) - keep_out.margin - ROUTE_EXTRA - y0
        for step in sorted((right, left), key=abs):
            if math.isfinite(step):
                routes.append(Route('around', 'bridge', step, enter, leave))
    return sorted(routes, key=lambda r: abs(r.excursion))


def plateau(s, enter: float, leave: float) -> list[np.ndarray]:
    """A rise from 0 at s = 0 to 1 at ``enter``, 1 until ``leave``, back to 0 at s = 1 (quintic smoothsteps: rest
    at both ends): its value and first three derivatives in s."""
    s = np.asarray(s, dtype=float)
    step = QUINTIC[0]  # 10 u^3 - 15 u^4 + 6 u^5

    def ramp(u, width, k):
        return poly.polyval(np.clip(u, 0.0, 1.0), poly.polyder(step, k)) / width ** k

    enter, leave = max(enter, 1e-3), min(leave, 1.0 - 1e-3)
    out = []
    for k in range(4):
        up = ramp(s / enter, enter, k)
        down = ramp((1.0 - s) / (1.0 - leave), 1.0 - leave, k) * (-1) ** k
        out.append(np.where(s <= enter, up, np.where(s >= leave, down, 1.0 if k == 0 else 0.0)))
    return out


def route_guess(tr, displacement, frac: np.ndarray, route: Route, pvec: np.ndarray) -> np.ndarray:
    """The NLP start point of ``route`` (``tr``: a ``collocation.Transcription`` with boxes; ``pvec`` its
    parameters): ``Problem.initial_guess`` with the detour added on the route's axis (position, velocity,
    acceleration, reference acceleration and input, in scaled units; with the bridge the out-of-plane swing
    quasi-static)."""
    pb = tr.problem
    s = tr.node_times(frac)
    X, U = pb.initial_guess(displacement, s)
    scale = pvec[PROBLEM_PARAMETERS.index(AXIS_SCALES[route.axis])]
    shape = plateau(s, route.enter, route.leave)
    for name, value in zip(AXIS_STATES[route.axis], (shape[0], shape[1], shape[2], shape[2])):
        if name in pb.states:
            X[pb.states.index(name)] += route.excursion / scale * value
    k = pb.axes.index(route.axis)
    U[k] += route.excursion / scale * shape[3]
    if route.axis == 'bridge':  # the load lags the bridge's acceleration: phi1 ~ -ab/g (scaled: -ab)
        X[pb.states.index('phi1')] = -X[pb.states.index('ab')]
        X[pb.states.index('dphi1')] = -U[k]
    return tr.pack(X, U)


def via_nodes(tr, frac: np.ndarray, displacement, vias) -> list[int]:
    """Where the reference passes each via point (indices among the N d collocation points of ``tr``, strictly
    increasing): at the time the quintic timing of the polyline start -> vias -> goal reaches the via's
    share of its length (every axis's positions, m, relative to their starts; ``vias`` as ``displacement``,
    by axis name)."""
    if not vias:
        return []
    axes = tr.problem.axes
    moves = tr.problem.displacements_of(displacement)
    points = np.array([[0.0] * len(axes), *([via.get(a, 0.0) for a in axes] for via in vias),
                       [moves[a] for a in axes]])
    lengths = np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))
    shares = lengths[:-1] / max(lengths[-1], 1e-12)
    s = np.linspace(0.0, 1.0, 2001)
    times = np.interp(shares, poly.polyval(s, QUINTIC[0]), s)  # the quintic is increasing on [0, 1]
    node_s = tr.node_times(frac)[1:]
    nodes = []
    for t in times:
        k = int(np.argmin(np.abs(node_s - t)))
        k = max(k, nodes[-1] + 1 if nodes else 0)
        if k >= len(node_s) - 1:
            raise PlanError('the via points are too many or too near the goal to be passed in order')
        nodes.append(k)
    return nodes
