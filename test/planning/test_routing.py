"""Routes past keep-out boxes (contract "Routes and protected areas"): the ways the served axes allow, and
NVF planned with the keep-out path constraints, checked on crane_sim's independent model.

The contract's cases on the paper's rig (tau 0, margin 0.02 m): the cart's 0.6 m in 4 s past a wall
(x 0.25-0.35 m, every y, z -2 to -0.76 m; the load hangs at -0.861 m) with the rope at 0.47 m at both
ends, lifted over it; and past a column (x 0.25-0.35 m, y -0.1-0.1 m, z -2 to -0.1 m) with a bridge,
taken around it. Replayed in crane_sim (1 ms), both masses stay the margin out, NVF leaves at most
0.1 mm of swing and the move ends at its goal.
"""
import math

import casadi as ca
import numpy as np
import pytest

from crane_msgs_py.crane.params import CraneParams
from crane_planner.planning import PlanOptions
from crane_planner.planning.collocation import keep_out_values, smooth_max
from crane_planner.planning.dispatch import VariationalRequest, hoisting_options, variational_solver
from crane_planner.planning.keep_out import KeepOut
from crane_planner.planning.mass_path import predict_mass_path
from crane_planner.planning.routing import NLP_EXTRA, ROUTE_EXTRA, plateau, route_candidates
from crane_planner.planning.shaped_route import shaped_route
from crane_planner.tools.evaluate import simulate_plan
from planning.test_keep_out import simulated_masses

NOMINAL = CraneParams().replace(tau=0.0, tau_hoist=0.0)
WALL = KeepOut.from_values([0.25, 0.35, -math.inf, math.inf, -2.0, -0.76], 0.02)
COLUMN = KeepOut.from_values([0.25, 0.35, -0.1, 0.1, -2.0, -0.1], 0.02)


def test_a_wall_is_passed_over_with_a_hoist_and_a_column_around_with_a_bridge_the_smaller_detour_first():
    over = route_candidates(WALL, {}, {'cart': 0.6, 'hoist': 0.0}, 0.47, 0.391, ('cart', 'hoist'))
    # the load's rest 0.861 m down, the wall's top 0.76 m: lifted 0.101 m + the margin + the extra
    assert [(r.kind, r.axis) for r in over] == [('over', 'hoist')]
    assert over[0].excursion == pytest.approx(-(0.861 - 0.76 + 0.02 + ROUTE_EXTRA))
    assert 0.2 < over[0].enter < 0.5 < over[0].leave < 0.8  # the cart's quintic over x 0.15-0.45 m
    around = route_candidates(COLUMN, {'bridge': 0.05}, {'cart': 0.6, 'bridge': 0.0}, 0.47, 0.391,
                              ('cart', 'bridge'))
    assert [r.excursion for r in around] == pytest.approx([0.1 + 0.05 - 0.05, -0.1 - 0.05 - 0.05])
    assert route_candidates(WALL, {}, {'cart': 0.6, 'bridge': 0.0}, 0.47, 0.391, ('cart', 'bridge')) == []  # no end
    assert route_candidates(COLUMN, {}, {'cart': 0.6}, 0.47, 0.391, ('cart',)) == []
    assert route_candidates(WALL, {}, {'cart': -0.6}, 0.47, 0.391, ('cart', 'hoist')) == []  # away from it
    high = KeepOut.from_values([0.25, 0.35, -math.inf, math.inf, -2.0, -0.3], 0.02)  # 0.3 m below the trolley
    assert route_candidates(high, {}, {'cart': 0.6, 'hoist': 0.0}, 0.47, 0.391, ('cart', 'hoist')) == []


def test_the_plateau_rests_at_both_ends_and_its_derivatives_are_its_slopes():
    s = np.linspace(0.0, 1.0, 20001)
    value, *rates = plateau(s, 0.3, 0.8)
    assert value[0] == 0.0 and value[-1] == 0.0 and np.all(value[(s >= 0.3) & (s <= 0.8)] == 1.0)
    assert all(abs(r[0]) < 1e-9 and abs(r[-1]) < 1e-9 for r in rates[:2])  # rest: velocity, acceleration
    smooth = (np.abs(s - 0.3) > 1e-3) & (np.abs(s - 0.8) > 1e-3) & (s > 1e-3) & (s < 1 - 1e-3)  # the jerk jumps there
    for lower, higher in zip([value, *rates[:2]], rates):
        assert np.abs(np.gradient(lower, s) - higher)[smooth].max() < 1e-3 * np.abs(higher).max()


@pytest.mark.parametrize('margin', [0.0, 0.02, 0.05])
@pytest.mark.parametrize('shape', ['box', 'post'])
def test_the_keep_out_rows_smooth_maximum_keeps_a_mass_out_by_nearly_the_clearance_they_ask_for(shape, margin):
    """The NLP's row for a mass and a box asks the smooth maximum of its six face distances to be at least the
    clearance c (the margin and ``NLP_EXTRA``). Judged by the box's Euclidean distance (``Box.distance``) at
    points all around a corner of the box, where the faces tie: a point the row accepts is at least 0.95 c
    out, and less than 1.3 mm nearer than c (from a post of no width, where both faces of x and of y tie too,
    0.92 c and 2.3 mm); where one face is nearer than the others by far the row is that face's distance."""
    sides = [0.0, 0.3, -0.2, 0.2, -2.0, -0.5] if shape == 'box' else [0.3, 0.3, 0.2, 0.2, -2.0, -0.5]
    box = KeepOut.from_values(sides, margin)
    _, _, clearance, delta, *sides = keep_out_values(box, {}, NLP_EXTRA)
    v, d = ca.SX.sym('v', 6), ca.SX.sym('d')
    smax = ca.Function('smax', [v, d], [smooth_max(v, d)])
    rng = np.random.default_rng(7)
    corner = np.array([0.3, 0.2, -0.5])  # the box's upper x, y and z: all three faces tie there
    reach = 3 * clearance if shape == 'box' else 1.5 * clearance  # (a post rejects a thin region)
    points = corner + rng.uniform(-reach, reach, (20000, 3))
    lo, hi = np.array(sides[0::2]), np.array(sides[1::2])
    faces = np.hstack([lo - points, points - hi])
    rows = np.array(smax.map(len(points))(faces.T, delta)).ravel()
    distance = box.boxes[0].distance(points)
    accepted = rows >= clearance
    assert accepted.sum() > 3000 and (~accepted).sum() > 3000
    ratio, loss = (0.95, 1.3e-3) if shape == 'box' else (0.92, 2.3e-3)
    assert distance[accepted].min() >= max(ratio * clearance, clearance - loss)
    assert np.all(rows >= faces.max(axis=1) - 1e-12)
    if shape == 'box':  # (near a post no face is alone)
        alone = np.sort(faces, axis=1)[:, -2] < faces.max(axis=1) - 6 * delta  # one face nearer by 6 delta
        assert np.abs(rows - faces.max(axis=1))[alone].max() < 5 * delta * np.exp(-6)


def routed(method, moves, keep_out, route_kind, options=PlanOptions()):
    routes = [r for r in route_candidates(keep_out, {}, moves, NOMINAL.L1, NOMINAL.L2, tuple(moves))
              if r.kind == route_kind]
    request = VariationalRequest('plan', method, moves, 4.0, NOMINAL, options, route=routes[0], keep_out=keep_out,
                                 origin={})
    return request.run(variational_solver(method, options))


@pytest.mark.parametrize('case', ['wall', 'column'])
def test_nvf_routes_keep_both_masses_out_leave_no_swing_and_end_at_the_goal(case):
    if case == 'wall':
        moves, keep_out, kind = {'cart': 0.6, 'hoist': 0.0}, WALL, 'over'
        p = routed('nvf', moves, keep_out, kind, hoisting_options(PlanOptions()))
    else:
        moves, keep_out, kind = {'cart': 0.6, 'bridge': 0.0}, COLUMN, 'around'
        p = routed('nvf', moves, keep_out, kind)
    assert p.info['route'] == kind
    t, m1, m2 = simulated_masses(p, NOMINAL, 4.0)
    for box in keep_out.boxes:
        assert box.distance(m1).min() >= 0.02 and box.distance(m2).min() >= 0.02
    assert min(box.distance(m1).min(), box.distance(m2).min()) < 0.04  # near the box: not a wide detour
    ev = simulate_plan(p, NOMINAL, settle=4.0)
    assert ev.metrics[0]['residual']['load_mm'] <= 0.1
    ends = {name: one.evaluate(np.array([4.0])).position[0] for name, one in p.axes.items()}
    assert ends['cart'] == pytest.approx(0.6, abs=1e-9) and abs(ends[next(n for n in moves if n != 'cart')]) < 1e-9
    detour = p.axes['hoist' if case == 'wall' else 'bridge'].evaluate(np.linspace(0.0, 4.0, 401)).position
    assert (detour.min() < -0.1) if case == 'wall' else (np.abs(detour).max() > 0.1)  # it did lift / step aside


@pytest.mark.parametrize('case', ['wall', 'column'])
def test_zv_routes_its_straight_move_with_a_shaped_detour_and_keeps_both_masses_out(case):
    """A shaper's route: the straight ZV move, the hoist (wall) or the bridge (column) stepping aside and
    back in two ZV-shaped legs; replayed in crane_sim both masses stay the margin out and the move ends
    at its goal. The swing left: small around the column (each leg ends without swing on the linearized
    model), a few mm over the wall (the cart's shaper is designed for the rope at its ends, not the
    shortened one it passes the wall with)."""
    from crane_planner.planning.dispatch import plan, shaper_design
    from crane_planner.serving.moves import with_axes_held
    if case == 'wall':
        moves, keep_out, axis = {'cart': 0.6, 'hoist': 0.0}, WALL, 'hoist'
        straight = with_axes_held(plan('zv', 0.6, 4.0, NOMINAL), {'hoist': NOMINAL.L1})
    else:
        moves, keep_out, axis = {'cart': 0.6, 'bridge': 0.0}, COLUMN, 'bridge'
        straight = plan('zv', 0.6, 4.0, NOMINAL, bridge=0.0)
    [route, *_] = route_candidates(keep_out, {}, moves, NOMINAL.L1, NOMINAL.L2, tuple(moves))
    path = predict_mass_path(straight, NOMINAL, {}, settle=0.0)
    p = shaped_route(straight, route, path, keep_out, *shaper_design(NOMINAL, PlanOptions()))
    assert p.info['route'] == route.kind and p.axes['cart'] is straight.axes['cart']
    t, m1, m2 = simulated_masses(p, NOMINAL, 4.0)
    for box in keep_out.boxes:
        assert box.distance(m1).min() >= 0.02 and box.distance(m2).min() >= 0.02
    # straight, the same move would not keep out
    _, s1, s2 = simulated_masses(straight, NOMINAL, 4.0)
    assert min(min(box.distance(s1).min(), box.distance(s2).min()) for box in keep_out.boxes) < 0.02
    ev = simulate_plan(p, NOMINAL, settle=4.0)
    assert ev.metrics[0]['residual']['load_mm'] <= (10.0 if case == 'wall' else 0.5)
    detour = p.axes[axis].evaluate(np.linspace(0.0, 4.0, 4001))
    assert detour.position[-1] == pytest.approx(0.0, abs=1e-12) and np.abs(detour.velocity[[0, -1]]).max() < 1e-12
    assert np.abs(detour.position).max() == pytest.approx(abs(route.excursion), rel=1e-9)  # out, then back


def test_a_duration_too_short_for_a_shaped_detour_is_refused_naming_the_time_it_leaves():
    from crane_planner.planning.dispatch import plan, shaper_design
    from crane_planner.planning.plan import PlanError
    straight = plan('zvd', 0.6, 4.0, NOMINAL, bridge=0.0)
    [route, *_] = route_candidates(COLUMN, {}, {'cart': 0.6, 'bridge': 0.0}, NOMINAL.L1, NOMINAL.L2,
                                   ('cart', 'bridge'))
    with pytest.raises(PlanError, match=r'the bridge has 1\.\d\d s to step aside .* the box, not more than the zvd'):
        shaped_route(straight, route, predict_mass_path(straight, NOMINAL, {}, settle=0.0), COLUMN,
                     *shaper_design(NOMINAL, PlanOptions()))
