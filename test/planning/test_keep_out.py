"""Protected areas (contract "Routes and protected areas"): keep-out boxes, the masses' predicted path and
its clearance.

The distances are checked against closed forms; the path the planner
predicts on its CasADi model (``mass_path``) against crane_sim's independent
NumPy simulator driven by the same plan, its masses placed by crane_sim's
own cable directions.
"""
import math
import re

import numpy as np
import pytest

from crane_msgs_py.crane.params import CraneParams
from crane_planner.planning import PlanOptions
from crane_planner.planning.dispatch import SolverCache, plan
from crane_planner.planning.dynamics import mass_positions
from crane_planner.planning.keep_out import Box, KeepOut, KeepOutError, boxes_from_flat
from crane_planner.planning.mass_path import MassPath, predict_mass_path, rest_positions, solved_mass_path
from crane_planner.serving.moves import CHORD_ALLOWANCE, MoveError, keep_out_clearance
from crane_planner.tools.evaluate import simulate_plan
from crane_planner.tools.evaluate import simulated_masses as masses_of

NOMINAL = CraneParams().replace(tau=0.0, tau_hoist=0.0)
#: The contract's wall: x 0.25-0.35 m across the whole runway, from the floor up to 0.10 m above the load.
WALL = (0.25, 0.35, -math.inf, math.inf, -2.0, -0.76)


# -- boxes ---------------------------------------------------------------------------------------------------

def test_a_box_s_distance_is_euclidean_outside_and_minus_the_depth_inside():
    box = Box((0.0, 0.0, 0.0), (1.0, 2.0, 3.0))
    assert box.distance((-3.0, 1.0, 1.0)) == pytest.approx(3.0)  # a face
    assert box.distance((2.0, 4.0, 1.5)) == pytest.approx(math.hypot(1.0, 2.0))  # an edge
    assert box.distance((-1.0, -2.0, 5.0)) == pytest.approx(3.0)  # a corner: sqrt(1 + 4 + 4)
    assert box.distance((0.25, 1.0, 1.5)) == pytest.approx(-0.25)  # inside, nearest the x0 face
    assert box.distance((0.5, 1.9, 1.5)) == pytest.approx(-0.1)  # inside, nearest the y1 face
    points = np.array([[-3.0, 1.0, 1.0], [0.25, 1.0, 1.5]])
    assert box.distance(points) == pytest.approx([3.0, -0.25])


def test_an_unbounded_side_is_never_the_nearest():
    wall = boxes_from_flat(WALL)[0]
    assert wall.distance((0.3, 1e6, -1.0)) == pytest.approx(-0.05)
    assert wall.distance((0.0, -1e6, -0.5)) == pytest.approx(math.hypot(0.25, 0.26))
    assert wall.contains((0.3, 0.0, -0.861)) and not wall.contains((0.3, 0.0, -0.70), margin=0.02)


@pytest.mark.parametrize('values, words', [
    ([0, 1, 0, 1, 0], 'keep_out: 5 number(s); a box is six'),
    ([0, 1, 0, 1, 0, 1, 2, 1, 0, 1, 0, 1], 'keep_out: box 2: x min 2 > max 1'),
    ([0, 1, 0, float('nan'), 0, 1], 'keep_out: box 1: y is NaN'),
    ([0, 1, math.inf, math.inf, 0, 1], 'keep_out: box 1: y span inf..inf holds no point'),
])
def test_a_bad_box_is_refused_naming_it(values, words):
    with pytest.raises(KeepOutError, match=words.replace('(', r'\(').replace(')', r'\)')):
        boxes_from_flat(values)


def test_a_negative_margin_is_refused():
    with pytest.raises(KeepOutError, match='keep_out_margin: must be finite and >= 0 m, got -0.01'):
        KeepOut.from_values(WALL, -0.01)
    assert not KeepOut() and KeepOut.from_values(WALL).margin == 0.02


def test_a_rest_inside_a_box_or_within_the_margin_is_refused_naming_the_box_and_the_mass():
    keep_out = KeepOut.from_values((*WALL, 0.9, 1.1, -0.1, 0.1, -2.0, -0.1))
    def why(x):
        return keep_out.rest_violation(rest_positions(x, 0.0, 0.47, 0.391))
    assert why(0.0) is None  # 0.25 m before the wall: fine
    assert re.match(r'the load \(m2\) at rest there.* is inside keep_out box 1', why(0.3))
    # the upper mass hangs at z = -0.47, above the wall's top (-0.76): only the load is in it
    assert re.search(r'from \(margin 20 mm\) keep_out box 1', why(0.235))  # 15 mm before the wall
    assert re.match(r'the upper mass \(m1\) .* inside keep_out box 2', why(1.0))


# -- the predicted path against crane_sim's ----------------------------------------------------------------

def simulated_masses(p, params: CraneParams, settle: float):
    """(t, m1, m2) of crane_sim driven by ``p`` (1 ms, its own model), placed by crane_sim's cable directions."""
    ev = simulate_plan(p, params, settle=settle)
    m1, m2 = masses_of(ev.sim)
    return ev.sim.t, m1.T, m2.T


@pytest.mark.parametrize('method, axes', [
    ('zv', {}), ('nvf', {}), ('zvd', {'bridge': 0.2}), ('nvf', {'hoist': (0.47, 0.30)}),
    ('zv', {'bridge': 0.2, 'hoist': (0.47, 0.60)}),
])
def test_the_predicted_masses_follow_crane_sim_s_within_10_micrometres(method, axes):
    p = plan(method, 0.3, 3.0, NOMINAL, PlanOptions(), variational=SolverCache(), **axes)
    path = predict_mass_path(p, NOMINAL, {'cart': 0.1, 'bridge': -0.05}, settle=1.5)
    t, m1, m2 = simulated_masses(p, NOMINAL, 1.5)
    offset = np.array([0.1, -0.05, 0.0])
    for predicted, simulated in ((path.m1, m1), (path.m2, m2)):
        at_t = np.stack([np.interp(t, path.t, predicted[:, i]) for i in range(3)], axis=1)
        assert np.abs(at_t - (simulated + offset)).max() < 1e-5
    assert path.t[-1] == pytest.approx(3.0 + 1.5) and path.duration == 3.0
    swing = np.hypot(*(m2[:, :2] - m1[:, :2]).T).max()
    assert swing > 0.01  # the masses did swing: the agreement is not that of two rests


def test_the_masses_at_rest_hang_where_the_model_places_them_with_every_angle_0():
    rest = rest_positions(0.2, -0.1, 0.47, 0.391)
    p1, p2 = mass_positions()(0.2, -0.1, 0.47, 0.391, 0.0, 0.0, 0.0, 0.0)
    assert np.allclose(rest['m1'], np.asarray(p1).ravel(), atol=1e-15)
    assert np.allclose(rest['m2'], np.asarray(p2).ravel(), atol=1e-15)
    assert rest['m2'][2] == pytest.approx(-0.861)


@pytest.mark.parametrize('method, axes', [('nvf', {}), ('rvf', {'bridge': 0.2}), ('nvf', {'hoist': (0.47, 0.30)})])
def test_the_solved_masses_follow_crane_sim_s_and_rest_after_the_motion(method, axes):
    """An NVF/RVF plan's own solution places the masses where the independent simulator finds them, at each
    collocation point (no integration of ours), and at rest at the goal over the settle window."""
    p = plan(method, 0.3, 3.0, NOMINAL, PlanOptions(), variational=SolverCache(), **axes)
    path = solved_mass_path(p, NOMINAL, {'cart': 0.1, 'bridge': -0.05}, settle=1.5)
    t, m1, m2 = simulated_masses(p, NOMINAL, 1.5)
    offset = np.array([0.1, -0.05, 0.0])
    for solved, simulated in ((path.m1, m1), (path.m2, m2)):
        at_t = np.stack([np.interp(path.t, t, simulated[:, i]) for i in range(3)], axis=1) + offset
        assert np.abs(solved - at_t).max() < 2e-5
    assert path.t[-1] == pytest.approx(3.0 + 1.5) and 0.005 < np.diff(path.t[:-1]).max() < 0.05
    assert np.abs(m2[t > 3.0] + offset - path.m2[-1]).max() < 1e-4  # at rest where the solution ends
    assert np.hypot(*(m2[:, :2] - m1[:, :2]).T).max() > 0.01  # the masses did swing


def test_only_a_solvers_plan_carries_a_solved_path():
    assert solved_mass_path(plan('zv', 0.3, 3.0, NOMINAL, PlanOptions()), NOMINAL) is None


def test_between_points_finds_the_nearest_point_of_every_straight_step():
    """Against brute force: every step of a random path sampled at 2001 points, two boxes."""
    rng = np.random.default_rng(7)
    t = np.linspace(0.0, 2.0, 41)
    m1 = np.cumsum(rng.normal(0.0, 0.03, (41, 3)), axis=0) + [0.3, 0.0, -0.5]
    m2 = m1 + rng.normal(0.0, 0.05, (41, 3)) + [0.0, 0.0, -0.3]
    path = MassPath(t, m1, m2, 1.5)
    keep_out = KeepOut.from_values([0.25, 0.35, -0.1, 0.1, -2.0, -0.6, 0.5, 0.6, -1.0, 1.0, -2.0, -0.9], 0.02)
    s = np.linspace(0.0, 1.0, 2001)[None, :, None]
    brute = min(float(box.distance((m[:-1, None, :] + s * np.diff(m, axis=0)[:, None, :]).reshape(-1, 3)).min())
                for box in keep_out.boxes for m in (m1, m2))
    found = keep_out.between_points(path)
    resolution = max(np.linalg.norm(np.diff(m, axis=0), axis=1).max() for m in (m1, m2)) / 2000
    assert brute - resolution <= found.distance <= brute + 1e-12
    assert found.distance <= keep_out.clearance(path).distance
    assert found.box is not None and found.time == pytest.approx(found.time) and 0.0 <= found.time <= 2.0


def test_the_solved_path_decides_where_its_steps_keep_out_and_the_prediction_elsewhere():
    """The load passes 49 mm above the wall. Along the solved path's steps the clearance is within the
    chord allowance of the step-by-step prediction's; with margins it clears (40 mm, and a box far away: its
    points' clearance, no step reaching it) the clearance is the solved path's; with a margin it does not
    clear (48.5 mm) the prediction decides; a margin the solved points break by far (60 mm) is refused from
    them, naming the wall and the load."""
    lifted = NOMINAL.replace(L1=0.32)
    p = plan('nvf', 0.6, 4.0, lifted, PlanOptions(), variational=SolverCache())
    solved = solved_mass_path(p, lifted)
    far_box = (1.4, 1.5, -0.1, 0.1, -2.0, -0.1)
    for box, margin, trusted in ((WALL, 0.04, True), (far_box, 0.02, True), (WALL, 0.0485, False)):
        keep_out = KeepOut.from_values(box, margin)
        predicted = keep_out.clearance(predict_mass_path(p, lifted)).distance
        along = keep_out.between_points(solved).distance
        assert abs(along - predicted) <= CHORD_ALLOWANCE
        assert (along - CHORD_ALLOWANCE >= margin) == trusted
        at_points = keep_out.clearance(solved).distance
        distance = keep_out_clearance(p, {}, lifted, keep_out)
        assert p.info['min_clearance'] == distance
        if at_points - solved.largest_step() >= margin:  # (the far box: no step can reach it)
            assert distance == at_points
        else:
            assert distance == (along if trusted else predicted)
    with pytest.raises(MoveError, match='the load .m2. passes 49.0 mm from keep_out box 1'):
        keep_out_clearance(p, {}, lifted, KeepOut.from_values(WALL, 0.06))


def test_a_direct_move_past_the_wall_enters_it_and_is_refused_naming_the_wall():
    """The load hangs at -0.861 m, 0.10 m below the wall's top: a direct move of the cart past it enters it
    (the deepest at the wall's middle, x = 0.30 m, half its width), the upper mass never does."""
    keep_out = KeepOut.from_values(WALL, 0.02)
    p = plan('zv', 0.6, 4.0, NOMINAL, PlanOptions())
    path = predict_mass_path(p, NOMINAL)
    c = keep_out.clearance(path)
    assert c.mass == 'm2' and c.box.number == 1 and c.distance == pytest.approx(-0.05, abs=1e-4)
    assert c.point[0] == pytest.approx(0.30, abs=1e-4) and 0.0 < c.time < 4.0
    with pytest.raises(KeepOutError, match=r'the plan does not keep out: the load \(m2\) comes 50.0 mm into '
                                           r'keep_out box 1 \(x 0.25..0.35, y -inf..inf, z -2..-0.76 m\)'):
        keep_out.check(path)
    # lifted 0.15 m (the load at -0.711 m, 49 mm above the top): the same move keeps out
    lifted = predict_mass_path(p, NOMINAL.replace(L1=0.32))
    assert keep_out.check(lifted).distance == pytest.approx(0.049, abs=1e-4)
    assert KeepOut().clearance(lifted).distance == math.inf


def test_an_axis_held_beside_a_solved_plan_keeps_its_model_path_and_the_masses_where_they_were():
    """A cart move with the hoist held (the planner's direct plan before it routes): the solver's model path
    carries over, so its clearance needs no step-by-step prediction, and the masses are the cart plan's."""
    from crane_planner.serving.moves import with_axes_held
    p = plan('nvf', 0.6, 4.0, NOMINAL, PlanOptions(), variational=SolverCache())
    held = with_axes_held(p, {'hoist': NOMINAL.L1})
    assert held.model_path is p.model_path and held.joint_names == ('cart', 'hoist')
    alone, beside = solved_mass_path(p, NOMINAL), solved_mass_path(held, NOMINAL)
    assert beside.m1 == pytest.approx(alone.m1) and beside.m2 == pytest.approx(alone.m2)
