"""A plan's occupancy of the runway: where its girder and both masses will be, predicted on the planning model
(``planning.mass_path``), placed in ``runway`` by the crane's ``runway_offset``. Pure Python, no ROS import."""
from __future__ import annotations

import numpy as np

from crane_msgs_py.crane.params import CraneParams

from ..planning.mass_path import DEFAULT_SETTLE, plan_axes, predict_mass_path, solved_mass_path
from ..planning.plan import Plan
from .occupancy import OCCUPANCY_STEP, Footprint, Occupancy, Shape


def plan_occupancy(crane: str, plan: Plan, params: CraneParams, origin: dict, offset: tuple, start_ns: int,
                   published_ns: int, shape: Shape, settle: float = DEFAULT_SETTLE) -> Occupancy:
    """The occupancy of ``plan`` streamed from ``start_ns`` (its first knot), each travel axis from ``origin``
    (m, by joint name; the plan is relative), the crane's ``crane_base`` at ``offset`` (x, y) in ``runway``:
    the masses as the solver left them (``solved_mass_path``) or predicted (``predict_mass_path``) over the
    motion and ``settle`` s after, resampled every ``OCCUPANCY_STEP``; the girder where the bridge's reference
    puts it (at the origin's ``bridge``, or 0, without one)."""
    path = solved_mass_path(plan, params, origin, settle) or predict_mass_path(plan, params, origin, settle)
    end = float(path.t[-1])
    grid = np.arange(0.0, end, OCCUPANCY_STEP)
    t = np.append(grid[grid < end - 1e-9], end)  # (arange may reach ``end`` itself by rounding: 2.3 / 0.02)
    masses = np.stack([np.stack([np.interp(t, path.t, m[:, c]) for c in range(2)], axis=-1)
                       for m in (path.m1, path.m2)], axis=1)
    masses = masses + np.asarray(offset, dtype=float)[None, None, :2]
    bridge = plan_axes(plan).get('bridge')
    y0 = origin.get('bridge', 0.0)
    girder = (y0 + bridge.evaluate(np.minimum(t, plan.duration)).position if bridge is not None
              else np.full(len(t), y0)) + float(offset[1])
    return Occupancy(crane, published_ns, start_ns, t, Footprint(np.asarray(girder, dtype=float), masses), shape)
