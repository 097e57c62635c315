"""``crane-plan choose``: per method, the fastest move within the axis limits, and its worst swing over a band.

For each method: the fastest plan (``Planner.fastest``), its peaks (of the
reference, exact for shapers, dense for NVF/RVF), and the worst residual load
swing over a band of plants (L1 within +-span, optionally L2 too), simulated
as ``crane-plan sweep`` does. The recommendation is the fastest method whose
worst residual is within the tolerance; every other method gets the reason it
was passed over. Pure Python (no ROS).
"""
from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from crane_msgs_py.crane.params import CraneParams
from crane_planner.planning import PlanError, PlanOptions, dispatch
from crane_planner.serving import Planner

from .evaluate import axes_report, residual_load_mm, simulate_plans


@dataclass
class Candidate:
    """One method's fastest plan and how it fares over the band (None where refused)."""

    method: str
    duration: float | None = None
    peak_velocity: float | None = None
    peak_acceleration: float | None = None
    peak_jerk: float | None = None
    worst_residual_mm: float | None = None
    residual_mm: list = field(default_factory=list)  # per plant of the band
    axes: dict = field(default_factory=dict)  # each further axis's start, goal and peaks (``evaluate.axes_report``)
    refused: str = ''
    verdict: str = ''  # 'chosen', or why it was passed over

    def row(self) -> dict:
        return {k: v for k, v in self.__dict__.items()}


@dataclass
class Choice:
    displacement: float
    tolerance_mm: float
    plants: list  # [(L1, L2)] of the band
    candidates: list
    chosen: str | None

    def as_json(self) -> dict:
        return {'displacement': self.displacement, 'tolerance_mm': self.tolerance_mm,
                'plants': [{'L1': a, 'L2': b} for a, b in self.plants], 'chosen': self.chosen,
                'methods': [c.row() for c in self.candidates]}


def band(model: CraneParams, span_L1: float, points: int, span_L2: float | None = None) -> list[CraneParams]:
    """Plants with L1 at model x (1 + linspace(-span, span, points)); with ``span_L2`` each also at
    L2 x (1 - span_L2), L2 and L2 x (1 + span_L2)."""
    L1s = model.L1 * (1.0 + np.linspace(-span_L1, span_L1, points))
    L2s = [model.L2] if not span_L2 else model.L2 * (1.0 + np.array([-span_L2, 0.0, span_L2]))
    return [model.replace(L1=float(a), L2=float(b)) for a in L1s for b in L2s]


def _peaks(plan) -> tuple[float, float, float]:
    """The cart's peak |v|, |a|, |jerk| (an ``AxesPlan``'s are its cart's)."""
    if hasattr(plan, 'peaks'):
        return plan.peaks()
    s = plan.evaluate(np.linspace(0.0, plan.duration, 20_001))
    return tuple(float(np.max(np.abs(x))) for x in (s.velocity, s.acceleration, s.jerk))


def choose(displacement: float, model: CraneParams, options: PlanOptions, methods, plants,
           tolerance_mm: float, settle: float, planner: Planner | None = None, progress=None,
           hoist=None, bridge: float | None = None) -> Choice:
    """Evaluate every method's fastest plan over ``plants``; pick the fastest within ``tolerance_mm``
    (``hoist`` = (L1_start, L1_goal): hoisting while travelling, the plants' L1 their start lengths; ``bridge``
    (m): the bridge's displacement, the plants spatial and the residual the norm of the load's offset)."""
    planner = planner or Planner()
    candidates, plans = [], []
    # Every method's search at once: CasADi lets go of the GIL while it builds and solves, so
    # NVF's and RVF's first free-time NLPs (most of the time) share the cores instead of taking turns.
    with ThreadPoolExecutor(max_workers=max(1, len(methods))) as pool:
        # dispatch with the planner's solvers, as Planner.fastest does, which takes no bridge (yet)
        searches = [pool.submit(dispatch.fastest, method, displacement, model, options, planner.variational, hoist,
                                bridge) for method in methods]
    for method, search in zip(methods, searches):
        c = Candidate(method)
        try:
            plan = search.result()
        except PlanError as exc:
            c.refused = str(exc)
        else:
            c.duration = plan.duration
            c.peak_velocity, c.peak_acceleration, c.peak_jerk = _peaks(plan)
            c.axes = axes_report(plan)
            plans.append((c, plan))
        candidates.append(c)
        if progress:
            progress(f'{method}: ' + (f'{c.duration:.3f} s' if c.duration is not None else 'refused'))
    if plans:  # every (plan, plant) pair in one simulation
        for (c, _), ev in zip(plans, simulate_plans([p for _, p in plans], plants, settle)):
            c.residual_mm = residual_load_mm(ev).tolist()
            c.worst_residual_mm = max(c.residual_mm)
    if progress:
        progress(f'simulated {len(plans)} x {len(plants)} runs')
    fit = [c for c in candidates if c.duration is not None and c.worst_residual_mm <= tolerance_mm]
    chosen = min(fit, key=lambda c: c.duration) if fit else None
    for c in candidates:
        if c is chosen:
            c.verdict = 'chosen: the fastest within the tolerance'
        elif c.refused:
            c.verdict = f'refused: {c.refused}'
        elif c.worst_residual_mm > tolerance_mm:
            c.verdict = f'worst residual {c.worst_residual_mm:.2f} mm over the band exceeds {tolerance_mm:g} mm'
        else:
            c.verdict = f'within the tolerance but slower than {chosen.method} ({c.duration:.3f} s vs ' \
                        f'{chosen.duration:.3f} s)'
    return Choice(float(displacement), float(tolerance_mm), [(p.L1, p.L2) for p in plants], candidates,
                  chosen.method if chosen else None)
