"""A shaper's route past keep-out boxes: its straight move with one axis stepping aside and back, both shaped.

NVF/RVF route with the keep-out path constraints in the NLP (``routing``).
A shaper has no optimizer to ask, so its route is built: the straight
shaped move (``shaped.shaped_axes``, or the cart's alone) stays as it is, and
the route's axis (``routing.Route``: the bridge around a box, the hoist over
it) makes a detour of its own, out to the route's excursion while the
straight move passes the box and back afterwards. Each leg is a rest-to-rest
move shaped by the same shaper (paper §4), so each ends without residual
swing on the linearized model: the load has stopped swinging sideways (or
bouncing from the hoist) before the box is reached, and again at the end.

When the box is passed comes from the straight move itself: the times either
mass of its prediction on the planning model (``mass_path``, made once for
every route the caller tries) is within
``PASSING`` of the box's footprint in the coordinates other than the
detour's. The out leg must end by then and the back leg start after, each
longer than the shaper: a duration too short for that is refused. The
caller checks the whole route on the prediction (``keep_out.KeepOut.check``),
as every plan: a shaped route is not constrained, only built and checked.
Pure Python, no ROS import.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .keep_out import KeepOut
from .mass_path import MassPath
from .plan import AxesPlan, Plan, PlanError
from .routing import ROUTE_EXTRA, Route
from .shaped import ShapedPlan, shaped_plan

#: How near (m) beyond the margin a mass of the straight move must come to a box's footprint for the detour
#: to be out: the route's own clearance (``routing.ROUTE_EXTRA``) and as much again for its legs' swing.
PASSING = 2 * ROUTE_EXTRA
#: The coordinate (x, y, z of ``crane_base``) each route's axis moves the load along.
_DETOUR_COORDINATE = {'bridge': 1, 'hoist': 2}


@dataclass(kw_only=True)
class DetourPlan(Plan):
    """An axis's plan ``along`` with a detour added: ``out`` (a shaped move to the excursion) from 0, and
    ``back`` (the shaped move back) from ``back_at`` (s). Its displacement is ``along``'s."""

    along: Plan
    out: ShapedPlan
    back: ShapedPlan
    back_at: float

    def _evaluate(self, t):
        parts = (self.along.evaluate(t), self.out.evaluate(t), self.back.evaluate(t - self.back_at))
        return tuple(sum(getattr(s, name) for s in parts) for name in ('position', 'velocity', 'acceleration',
                                                                         'jerk'))

    def breakpoints(self) -> np.ndarray:
        b = np.concatenate([self.along.breakpoints(), self.out.breakpoints(), self.back.breakpoints() + self.back_at])
        return np.unique(b[(b >= 0.0) & (b <= self.duration)])

    @property
    def quintic_pieces(self) -> bool:
        return self.along.quintic_pieces and self.out.quintic_pieces and self.back.quintic_pieces


def passing_window(path: MassPath, keep_out: KeepOut, coordinate: int) -> tuple[float, float] | None:
    """When (s: first, last) either mass of the straight move's predicted ``path`` (``mass_path``, over its
    motion) is within the margin and ``PASSING`` of a box's footprint in every coordinate but ``coordinate``;
    None if never."""
    reach = keep_out.margin + PASSING
    near = np.zeros(path.t.shape, dtype=bool)
    others = [k for k in range(3) if k != coordinate]
    for box in keep_out.boxes:
        lo, hi = np.asarray(box.lower)[others] - reach, np.asarray(box.upper)[others] + reach
        for mass in (path.m1, path.m2):
            near |= np.all((mass[:, others] > lo) & (mass[:, others] < hi), axis=1)
    if not near.any():
        return None
    k = np.flatnonzero(near)
    return float(path.t[k[0]]), float(path.t[k[-1]])


def shaped_route(straight: AxesPlan, route: Route, path: MassPath, keep_out: KeepOut, omegas, zeta) -> AxesPlan:
    """``straight`` (a shaper's plan with every served axis, ``route.axis`` among them; ``path`` its masses
    predicted on the planning model, ``mass_path.predict_mass_path``) with ``route.axis`` stepping
    ``route.excursion`` aside while the straight move passes the boxes and back after it, both legs shaped
    for ``omegas``, ``zeta`` (``shaped.shaped_plan``). PlanError if the duration leaves either leg no longer
    than the shaper."""
    window = passing_window(path, keep_out, _DETOUR_COORDINATE[route.axis])
    if window is None:
        return straight
    enter, leave = window
    T = straight.duration
    method = straight.method
    try:
        out = shaped_plan(method, route.excursion, enter, omegas, zeta)
        back = shaped_plan(method, -route.excursion, T - leave, omegas, zeta)
    except PlanError:
        side, time = ('before', enter) if enter < T - leave else ('after', T - leave)
        what = 'lift the load' if route.kind == 'over' else 'step aside'
        raise PlanError(f'the {route.axis} has {time:.2f} s to {what} {side} the box, not more than the '
                        f'{method} shaper lasts: give a longer duration') from None
    axes = dict(straight.axes)
    axes[route.axis] = DetourPlan(method=method, displacement=axes[route.axis].displacement, duration=T,
                                  info={}, along=axes[route.axis], out=out, back=back, back_at=leave)
    info = {**straight.info, 'route': route.kind}
    return AxesPlan(method=method, displacement=straight.displacement, duration=T, info=info, axes=axes,
                    starts=dict(straight.starts))
