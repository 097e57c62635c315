"""A plan's occupancy of the runway: where its girder and both masses will be, predicted on the planning model
(``planning.mass_path``), placed in ``runway`` by the crane's ``runway_offset``. Pure Python, no ROS import."""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from crane_msgs_py.crane.params import CraneParams

from ..planning.mass_path import DEFAULT_SETTLE, MassPath, plan_axes, predict_mass_path, solved_mass_path
from ..planning.plan import Plan
from .occupancy import OCCUPANCY_STEP, Footprint, Occupancy, Shape

#: A swing (m) a plan leaves under this is taken as none: the crane stands as its last sample has it.
SWING_LEFT = 1e-4


def plan_occupancy(crane: str, plan: Plan, params: CraneParams, origin: dict, offset: tuple, start_ns: int,
                   published_ns: int, shape: Shape, settle: float = DEFAULT_SETTLE,
                   start: dict | None = None) -> Occupancy:
    """The occupancy of ``plan`` streamed from ``start_ns`` (its first knot), each travel axis from ``origin``
    (m, by joint name; the plan is relative), the crane's ``crane_base`` at ``offset`` (x, y) in ``runway``:
    the masses as the solver left them (``solved_mass_path``) or predicted (``predict_mass_path``) over the
    motion and ``settle`` s after, resampled every ``OCCUPANCY_STEP``; the girder where the bridge's reference
    puts it (at the origin's ``bridge``, or 0, without one). A plan that leaves the load swinging more than
    ``SWING_LEFT`` ends at the rest below the trolley, ``shape``'s load half-size grown by that swing.
    ``start``: the model's states where a plan from a moving, swinging state starts (``continuation.problem_start``,
    with ``params`` its model); None: from rest."""
    path = solved_mass_path(plan, params, origin, settle) or predict_mass_path(plan, params, origin, settle,
                                                                               start=start)
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

    # After its last sample a crane stands as that sample has it. A plan that leaves the load swinging (EI by
    # design, any plan on a model it was not made for) would be frozen there at one phase of its swing: the
    # last sample is the rest below the trolley instead, and each mass's disc grows by the swing left.
    rest = np.array([origin.get('cart', 0.0) + float(plan.evaluate([plan.duration]).position[0]), girder[-1]
                     - float(offset[1])])
    left = swing_left(path, rest)
    if left > SWING_LEFT:
        masses[-1] = rest + np.asarray(offset, dtype=float)[:2]
        shape = replace(shape, load_half_size=shape.load_half_size + left)
    return Occupancy(crane, published_ns, start_ns, t, Footprint(np.asarray(girder, dtype=float), masses), shape)


def swing_left(path: MassPath, rest) -> float:
    """The largest distance (m), seen from above, of either mass from ``rest`` (x, y: below the trolley where
    the plan ends) after the motion: the swing the plan leaves, as far as ``path``'s settle window shows it."""
    after = path.t >= path.duration
    return max(float(np.linalg.norm(m[after, :2] - rest, axis=1).max(initial=0.0)) for m in (path.m1, path.m2))
