"""``crane-demo``'s route case, offline: moves past protected areas and through a via point (contract "Routes
and protected areas").

Each move is planned as the planner node serves it (``serving.moves.plan_keeping_out``: checked against the
keep-out boxes on the planning model, routed over or around a box the direct move would enter: NVF/RVF with
the path constraints, a shaper's straight move with a shaped detour, ``planning.shaped_route``) and
replayed in ``crane_sim``'s batch model (``evaluate.simulate_plans``), without nodes: the nodes' path is
covered by the ROS tests. On the Table 1 model (tau 10 ms), margin 0.02 m, every method asked:

- ``route:wall``: the cart's 0.6 m in 4 s past a wall across the runway at x 0.25-0.35 m that stands 0.10 m
  above the hanging load, the rope at 0.47 m at both ends (a crane with a hoist): lifted over it;
- ``route:column``: the same move past a column at x 0.25-0.35 m, y -0.1-0.1 m (a crane with a bridge): taken
  around it;
- ``route:via``: (0, 0) -> (0.6, 0.4) m via (0.5, 0.0) in 4 s (a crane with a bridge).

A method that cannot make a move (a shaper's straight path far from the via point, a shaper too long to
step aside in time) is refused as the planner refuses it, and its reason printed. The figure shows the boxes
and each method's load path in side and top views. No ROS import.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from crane_msgs_py.crane.params import CraneParams

from .evaluate import residual_load_mm, simulate_plans, simulated_masses

#: The table's columns of the route case, in order.
WALL, COLUMN, VIA = 'route:wall', 'route:column', 'route:via'
COLUMNS = (WALL, COLUMN, VIA)
#: The boxes (x0 x1 y0 y1 z0 z1, m) and the margin (m).
WALL_BOX = (0.25, 0.35, -math.inf, math.inf, -2.0, -(CraneParams.L1 + CraneParams.L2) + 0.10)
COLUMN_BOX = (0.25, 0.35, -0.1, 0.1, -2.0, -0.1)
MARGIN = 0.02
#: Each column's joints, goal (per joint, m), boxes and via points; 4 s each, from 0 (the rope at L1).
MOVES = {
    WALL: (('cart', 'hoist'), (0.6, CraneParams.L1), WALL_BOX, ()),
    COLUMN: (('cart', 'bridge'), (0.6, 0.0), COLUMN_BOX, ()),
    VIA: (('cart', 'bridge'), (0.6, 0.4), (), ((0.5, 0.0),)),
}
DURATION = 4.0
#: Seconds of free swing observed after each motion.
SETTLE = 4.0
#: A route takes more than the planner's default budget beside running nodes; offline it has all it needs.
MAX_SOLVE_TIME = 30.0


@dataclass
class RouteRun:
    """One planned and simulated move of the route case (SI; the swing and the clearance in mm)."""

    column: str
    method: str
    plan_time_s: float
    route: str                                   # '' direct, 'over', 'around', 'via'
    clearance_mm: float                          # smallest distance of a mass to a box in crane_sim (inf: none)
    residual_mm: float
    peak_acceleration: float                     # peak norm of the horizontal reference acceleration (m/s^2)
    t: np.ndarray = field(repr=False)
    load_mm: np.ndarray = field(repr=False)      # norm of the load's horizontal offset (mm) at ``t``
    load_xyz: np.ndarray = field(repr=False)     # (3, n) the load in crane_base (m) at ``t``
    point_xyz: np.ndarray = field(repr=False)    # (3, n) the suspension point (cart, bridge, 0) (m) at ``t``


def run_routes(methods, log: Callable[[str], None] | None = None) -> tuple[list[RouteRun], dict]:
    """Plan and simulate every column with every method: (the runs, {(column, method): why refused})."""
    from crane_planner.planning.keep_out import KeepOut
    from crane_planner.serving import Planner
    from crane_planner.serving.config import PARAMETERS, Config
    from crane_planner.serving.moves import Move, check_move, check_rests_keep_out, plan_keeping_out

    planner, model = Planner(), CraneParams()
    defaults = {name: default for name, (default, _, _) in PARAMETERS.items()}
    runs, refused = [], {}
    for column, (joints, goal, box, vias) in MOVES.items():
        config = Config.from_values({**defaults, 'joints': list(joints), 'keep_out': list(box),
                                     'keep_out_margin': MARGIN, 'max_solve_time': MAX_SOLVE_TIME})
        start = tuple(model.L1 if joint == 'hoist' else 0.0 for joint in joints)
        planned = []
        for method in methods:
            checked = check_move(Move(method, joints, start, goal, DURATION, via=vias), config.bounds, None,
                                 model.L1)
            t0 = time.perf_counter()
            try:
                check_rests_keep_out(checked, model, config.keep_out)
                plan = plan_keeping_out(planner, checked, config.bounds, model, config.options, config.keep_out)
            except ValueError as exc:
                refused[(column, method)] = str(exc)
                if log is not None:
                    log(f'{column:<13} {method:<5} refused: {exc}')
                continue
            planned.append((method, plan, time.perf_counter() - t0 - plan.info.get('build_time_s', 0.0)))
        evaluations = simulate_plans([p for _, p, _ in planned], model, SETTLE) if planned else []
        boxes = KeepOut.from_values(box, MARGIN).boxes
        for (method, plan, seconds), ev in zip(planned, evaluations):
            runs.append(_record(column, method, plan, seconds, ev, boxes))
    for r in runs if log is not None else ():
        log(f'{r.column:<13} {r.method:<5} route {r.route or "direct":<7} clearance {r.clearance_mm:6.1f} mm, '
            f'residual {r.residual_mm:8.4f} mm, plan {1e3 * r.plan_time_s:.0f} ms')
    return runs, refused


def _record(column: str, method: str, plan, seconds: float, ev, boxes) -> RouteRun:
    sim = ev.sim
    m1, m2 = simulated_masses(sim)
    clearance = min((min(box.distance(m1.T).min(), box.distance(m2.T).min()) for box in boxes), default=math.inf)
    point = np.stack([sim.y[0], sim.yb[0] if 'yb' in sim.states else 0.0 * sim.t, 0.0 * sim.t])
    offset = np.hypot(*(m2[:2] - point[:2]))
    grid = np.linspace(0.0, plan.duration, int(plan.duration / 1e-3) + 1)
    axes = plan.axes
    acc = np.hypot(axes['cart'].evaluate(grid).acceleration,
                   axes['bridge'].evaluate(grid).acceleration if 'bridge' in axes else 0.0 * grid)
    return RouteRun(column, method, seconds, plan.info.get('route', ''), 1e3 * clearance,
                    float(residual_load_mm(ev)[0]), float(acc.max()), sim.t, 1e3 * offset, m2, point)


def plot_routes(runs: list[RouteRun], path) -> Path:
    """The wall from the side (x-z), the column and the via point from above (x-y): the boxes grown by the
    margin (dashed) and each method's load path."""
    from matplotlib.patches import Rectangle

    from .figures import plt, save_figure  # headless (Agg) matplotlib

    fig, axes = plt.subplots(1, 3, figsize=(16, 5))
    views = ((WALL, (0, 2), 'side view (x-z): over the wall', WALL_BOX),
             (COLUMN, (0, 1), 'top view (x-y): around the column', COLUMN_BOX),
             (VIA, (0, 1), 'top view (x-y): via (0.5, 0.0)', None))
    for ax, (column, (i, j), title, box) in zip(axes, views):
        if box is not None:
            lo, hi = np.array(box[0::2]), np.array(box[1::2])
            lo, hi = np.maximum(lo, -5.0), np.minimum(hi, 5.0)
            ax.add_patch(Rectangle((lo[i], lo[j]), hi[i] - lo[i], hi[j] - lo[j], color='0.6', alpha=0.5))
            ax.add_patch(Rectangle((lo[i] - MARGIN, lo[j] - MARGIN), hi[i] - lo[i] + 2 * MARGIN,
                                   hi[j] - lo[j] + 2 * MARGIN, fill=False, ls='--', color='0.4'))
        else:
            ax.plot([0.5], [0.0], 'kx', ms=10, label='via point')
        for k, r in enumerate(r for r in runs if r.column == column):
            if j != 2:  # (from the side the suspension point runs along z = 0)
                ax.plot(r.point_xyz[i], r.point_xyz[j], color=f'C{k}', lw=0.8, ls=':')
            ax.plot(r.load_xyz[i], r.load_xyz[j], color=f'C{k}', lw=1.2,
                    label=f'{r.method.upper()} {r.route or "direct"}: clearance '
                          f'{"-" if math.isinf(r.clearance_mm) else f"{r.clearance_mm:.1f} mm"}, '
                          f'residual {r.residual_mm:.3g} mm')
        ax.set_title(title, fontsize=10)
        ax.set_xlabel('x, cart (m)')
        ax.set_ylabel('z (m)' if j == 2 else 'y, bridge (m)')
        if j == 2:
            ax.set_ylim(-1.0, -0.5)
        ax.set_xlim(-0.05, 0.7)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle('the load\'s path (m2) per method, dotted: the suspension point\'s (the reference passes the via '
                 'point); grey: the protected area, dashed: grown by the 20 mm margin (crane-demo --cases route)',
                 fontsize=10)
    return save_figure(fig, path)
