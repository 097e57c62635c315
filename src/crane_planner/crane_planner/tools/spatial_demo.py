"""``crane-demo``'s spatial case, offline: the cart and the bridge moving together (contract "The spatial crane").

Planned with ``dispatch.plan`` and replayed in ``crane_sim``'s batch spatial
model (``evaluate.simulate_plans``), without nodes: the nodes' bridge path is
covered by the ROS tests, and the demo stays short. Three table columns:

- ``spatial``: 0.3 m along x (cart) and 0.2 m along y (bridge) in 3 s, every
  method asked, planned on the Table 1 model and replayed on it;
- ``spatial:L1-10%``: the same plans on a plant whose upper cable is 10 %
  shorter than the model's (RVF is robust to L1);
- ``spatial:diagonal``: a fast long diagonal, 1.0 m x 0.8 m in 2.2 s with
  ideal servos (tau 0, the swing up to ~0.3 rad unshaped): NVF on the
  coupled spatial model, ZV, and ``nvf/plane``, two planar NVF plans (one
  per axis, as if the planes were apart) played together: what planning the
  coupled model buys. Its NVF is solved on the coupled NLP itself, not on the
  vertical plane of the move that serves straight moves (``planning.straight``,
  the same optimum at the planar crane's cost), so the row shows the coupled NLP.

The residual is the peak norm of the load's horizontal offset from below
the suspension point over ``SETTLE`` s after the motion; the figure shows
the diagonal from above and its swing over time. No ROS import: the demo
turns the records into its table's rows.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from crane_msgs_py.crane.params import CraneParams
from crane_msgs_py.messages.names import BRIDGE_JOINT, CART_JOINT
from crane_planner.planning.dispatch import PlanOptions, SolverCache, plan, travel_plan
from crane_planner.planning.plan import AxesPlan, time_grid

from .evaluate import EVAL_STEP, Evaluation, residual_load_mm, simulate_plans

#: The table's columns of the spatial case, in order: the move on the model's plant, on L1 -10 %, the diagonal.
NOMINAL, PERTURBED, DIAGONAL = 'spatial', 'spatial:L1-10%', 'spatial:diagonal'
COLUMNS = (NOMINAL, PERTURBED, DIAGONAL)
#: The move: cart (m), bridge (m), duration (s).
MOVE = (0.3, 0.2, 3.0)
#: The perturbed plant's upper cable, relative to the model's.
L1_FACTOR = 0.9
#: The diagonal: cart (m), bridge (m), duration (s); planned and replayed with ideal servos.
DIAGONAL_MOVE = (1.0, 0.8, 2.2)
#: The diagonal's methods (of those asked; every one with --cases all or --methods), and the per-plane row's name.
DIAGONAL_METHODS, PER_PLANE = ('nvf', 'zv'), 'nvf/plane'
#: Seconds of free swing observed after each motion: over two periods of the slow mode (1.73 s).
SETTLE = 4.0


@dataclass
class SpatialRun:
    """One simulated motion of the spatial case (SI; the swing in mm)."""

    column: str                                 # one of COLUMNS
    method: str                                 # a method, or PER_PLANE
    plan_time_s: float                          # planning time, its NLP's build left out (both plants: one plan)
    peak_acceleration: float                    # peak norm of the horizontal reference acceleration (m/s^2)
    residual_mm: float                          # peak norm of the load's offset over SETTLE s after the motion
    duration: float                             # the motion's (s)
    t: np.ndarray = field(repr=False)           # simulation times (s) from the motion's start
    load_mm: np.ndarray = field(repr=False)     # norm of the load's horizontal offset (mm) at ``t``
    point_xy: np.ndarray = field(repr=False)    # (2, n) the suspension point (cart x, bridge y) (m) at ``t``
    load_xy: np.ndarray = field(repr=False)     # (2, n) the load from above (m) at ``t``


def diagonal_methods(methods, every: bool = False) -> list[str]:
    """The diagonal's rows: its own methods of ``methods`` (``every``: all of them), and the per-plane NVF
    beside NVF."""
    chosen = [m for m in methods if every or m in DIAGONAL_METHODS]
    return chosen + ([PER_PLANE] if 'nvf' in chosen else [])


def run_spatial(methods, every: bool = False, settle: float = SETTLE,
                log: Callable[[str], None] | None = None) -> list[SpatialRun]:
    """Plan and simulate the spatial case: a SpatialRun per column and method (see the module docstring).

    Args:
        methods: the methods of the 0.3 x 0.2 m move (any of ``planning.METHODS``); the diagonal runs
            those of them in DIAGONAL_METHODS (``every``: all of them).
        every: the diagonal runs every method of ``methods``.
        settle: seconds observed after each motion.
        log: called with one line per run.

    Raises:
        PlanError (a ValueError) if a method refuses a move.
    """
    solvers = SolverCache()  # NVF and RVF warm-start from their solvers' last plans, as the planner's pools do
    model = CraneParams()
    DX, DY, T = MOVE
    plans, times = _planned(methods, DX, DY, T, model, solvers)
    plants = [model, model.replace(L1=model.L1 * L1_FACTOR)]  # the planner's model stays nominal
    runs = []
    for method, ev in zip(methods, simulate_plans(plans, plants, settle)):
        runs += [_record(column, method, times[method], ev, i) for i, column in enumerate((NOMINAL, PERTURBED))]

    ideal = model.replace(tau=0.0)
    DX, DY, T = DIAGONAL_MOVE
    rows = diagonal_methods(methods, every)
    shared = [m for m in rows if m != PER_PLANE]
    diagonal, times = _planned(shared, DX, DY, T, ideal, SolverCache(straight_moves_in_their_plane=False))
    if PER_PLANE in rows:
        # each plane planned as the planar crane, blind to the other's motion (the same solver per axis)
        (x, tx), (y, ty) = (_timed(lambda D=D: plan('nvf', D, T, ideal, variational=solvers)) for D in (DX, DY))
        diagonal.append(travel_plan({CART_JOINT: x, BRIDGE_JOINT: y}))
        times[PER_PLANE] = tx + ty
    runs += [_record(DIAGONAL, method, times[method], ev)
             for method, ev in zip(rows, simulate_plans(diagonal, ideal, settle))]
    for r in runs if log is not None else ():
        log(f'{r.column:<18} {r.method:<9} residual {r.residual_mm:8.4f} mm, peak a_ref '
            f'{r.peak_acceleration:.3f} m/s^2, plan {1e3 * r.plan_time_s:.0f} ms')
    return runs


def _planned(methods, DX: float, DY: float, T: float, model: CraneParams, solvers: SolverCache):
    """([``methods``' plans of the straight move (DX, DY) m in T s on ``model``], {method: planning time (s)});
    RVF robust to L1, as the planner node plans it by default."""
    plans, times = [], {}
    for method in methods:
        one, times[method] = _timed(lambda: plan(method, DX, T, model, PlanOptions(robust=('L1',)),
                                                 variational=solvers, bridge=DY))
        plans.append(one)
    return plans, times


def _timed(planning: Callable[[], AxesPlan]) -> tuple[AxesPlan, float]:
    """(``planning()``, its wall time (s) without building an NLP): the planner node builds its solvers at
    start-up, so a plan's time is the solve's, comparable with the other cases' round trips."""
    start = time.perf_counter()
    one = planning()
    return one, time.perf_counter() - start - one.info.get('build_time_s', 0.0)


def _record(column: str, method: str, plan_time_s: float, ev: Evaluation, index: int = 0) -> SpatialRun:
    """The SpatialRun of plant ``index`` of ``ev``."""
    from crane_msgs_py.crane.geometry import load_offset
    p: AxesPlan = ev.plan
    grid = time_grid(p.duration, EVAL_STEP)
    a = np.hypot(p.evaluate_axis(CART_JOINT, grid).acceleration, p.evaluate_axis(BRIDGE_JOINT, grid).acceleration)
    sim = ev.sim
    dx, dy = load_offset(sim.theta1[index], sim.theta2[index], sim.phi1[index], sim.phi2[index],
                         sim.plants.L1[index], sim.plants.L2[index])
    point = np.stack([sim.y[index], sim.yb[index]])
    return SpatialRun(column, method, plan_time_s, float(a.max()), float(residual_load_mm(ev)[index]), p.duration,
                      sim.t, 1e3 * np.hypot(dx, dy), point, point + np.stack([dx, dy]))


def plot_spatial(runs: list[SpatialRun], path) -> Path:
    """The diagonal from above (the paths; the load around the goal after the motion, mm, where the methods
    differ) and its swing (mm) over time, linear and, after the motion, logarithmic."""
    from .figures import plt, save_figure  # headless (Agg) matplotlib

    DX, DY, T = DIAGONAL_MOVE
    fig, ((top, swing), (goal, rest)) = plt.subplots(2, 2, figsize=(12, 9))
    for k, r in enumerate(r for r in runs if r.column == DIAGONAL):
        color, label = f'C{k}', f'{r.method.upper()} ({r.residual_mm:.3g} mm)'
        after = r.t >= r.duration
        top.plot(*r.point_xy, color=color, lw=0.8, ls=':')
        top.plot(*r.load_xy, color=color, lw=1.2, label=label)
        goal.plot(*(1e3 * (r.load_xy[:, after] - np.array([[DX], [DY]]))), color=color, lw=1.0, label=label)
        swing.plot(r.t, r.load_mm, color=color, label=label)
        rest.semilogy(r.t[after], np.maximum(r.load_mm[after], 1e-5), color=color, label=label)
    top.set_title(f'top view: {DX:g} m x {DY:g} m in {T:g} s, tau 0 (dotted: the suspension point)', fontsize=10)
    top.set_xlabel('x, cart (m)')
    top.set_ylabel('y, bridge (m)')
    goal.set_title(f'the load around the goal over {SETTLE:g} s after the motion', fontsize=10)
    goal.set_xlabel('x - goal (mm)')
    goal.set_ylabel('y - goal (mm)')
    for ax in (top, goal):
        ax.set_aspect('equal', adjustable='datalim')
    swing.set_title('the norm of the load\'s horizontal offset from below the suspension point', fontsize=10)
    swing.set_ylabel('load swing (mm)')
    swing.axvline(T, color='k', lw=0.6, ls=':')
    rest.set_ylabel('residual swing (mm)')
    rest.set_xlabel('time from the motion\'s start (s)')
    rest.sharex(swing)
    for ax in (top, goal, swing, rest):
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
    return save_figure(fig, path)
