"""Keep-out boxes in the planner's service (contract "Routes and protected areas"): a preview or a goal whose
predicted masses would come within the margin of a box, or whose start or goal is in one, is refused naming
the box; one that keeps out says its clearance. On the fake clock and streamer of ``test_service``."""
import math

import numpy as np
import pytest

from crane_planner.planning.keep_out import KeepOutError
from crane_planner.serving.config import PARAMETERS, Config
from crane_planner.serving.goals import GoalState
from crane_planner.serving.moves import Move, MoveError, summarize
from serving.test_service import T0, Crane, move, run_old_goal_until

#: A wall across the runway from the floor to 0.10 m above the hanging load (at -0.861 m with L1 0.47 m).
WALL = [0.25, 0.35, -math.inf, math.inf, -2.0, -0.76]


def config(**values) -> Config:
    defaults = {name: default for name, (default, _, _) in PARAMETERS.items()}
    return Config.from_values({**defaults, 'method': 'zv', **values})


def crane_with(**values) -> Crane:
    crane = Crane()
    crane.config = config(**values)
    return crane


def test_a_preview_past_the_wall_is_refused_naming_it_and_with_the_load_lifted_says_its_clearance():
    crane = crane_with(keep_out=WALL, tau=0.0)
    with pytest.raises(MoveError) as refused:
        crane.service.plan(move(goal=0.6, duration=4.0), 'plan_move')
    assert refused.value.field == 'keep_out'
    assert str(refused.value).startswith('move.keep_out: the zv plan does not keep out: the load (m2) comes 50.0 mm '
                                         'into keep_out box 1 (x 0.25..0.35, y -inf..inf, z -2..-0.76 m)')
    assert refused.value.values['goal'] == 0.6  # the status on /diagnostics says which request
    crane.config = config(keep_out=WALL, tau=0.0, L1=0.32)  # the load 0.15 m higher: 49 mm above the wall
    planned = crane.service.plan(move(goal=0.6, duration=4.0), 'plan_move')
    assert planned.values['min_clearance'] == pytest.approx(0.049, abs=1e-4)
    assert summarize(planned.plan).min_clearance == pytest.approx(0.049, abs=1e-4)


def test_without_boxes_nothing_is_predicted_and_the_clearance_is_infinite():
    crane = crane_with()
    planned = crane.service.plan(move(goal=0.6, duration=4.0), 'plan_move')
    assert 'min_clearance' not in planned.values and summarize(planned.plan).min_clearance == math.inf


@pytest.mark.parametrize('label, start, goal', [('goal', 0.0, 0.3), ('start', 0.3, 0.6), ('goal', 0.0, 0.24)])
def test_a_start_or_goal_with_a_mass_in_a_box_or_within_its_margin_is_refused_naming_it(label, start, goal):
    crane = crane_with(keep_out=WALL)
    with pytest.raises(MoveError, match=rf'move.{label}: the load \(m2\) at rest there, .* keep_out box 1') as e:
        crane.service.plan(Move('zv', start=(start,), goal=(goal,), duration=4.0), 'plan_move')
    assert e.value.field == label


@pytest.mark.parametrize('values, words', [
    ({'keep_out': WALL[:5]}, 'keep_out: 5 number(s)'),
    ({'keep_out': [0.35, 0.25, 0, 1, 0, 1]}, 'keep_out: box 1: x min 0.35 > max 0.25'),
    ({'keep_out_margin': -0.01}, 'keep_out_margin: must be finite and >= 0 m'),
])
def test_a_bad_keep_out_parameter_is_refused_naming_it(values, words):
    with pytest.raises(KeepOutError) as refused:
        config(**values)
    assert str(refused.value).startswith(words)


def test_a_goal_sent_with_boxes_set_draws_the_load_s_predicted_path_for_its_motion_and_settle():
    """The route on crane_markers: the load's path as planned (every 50 ms, in crane_base: from the hold, the
    load 0.861 m below the trolley), shown for the motion, its settle window and a second; without boxes none."""
    drawn = []
    crane = crane_with(keep_out=[1.0, 1.1, -math.inf, math.inf, -2.0, -0.76], tau=0.0)
    crane.service.serving.draw = lambda points, lifetime: drawn.append((points, lifetime))
    goal = crane.goal('a', move(goal=0.3, duration=3.0), settle=0.5)
    outcome, _ = crane.execute(goal, move(goal=0.3, duration=3.0), settle=0.5)
    assert outcome.how == 'succeed', outcome.message
    [(points, lifetime)] = drawn
    assert lifetime == pytest.approx(3.0 + 0.5 + 1.0) and points.shape == (71, 3)
    assert points[0] == pytest.approx([0.0, 0.0, -0.861])
    assert points[-1] == pytest.approx([0.3, 0.0, -0.861], abs=1e-4)
    assert np.abs(points[:, 0] - np.linspace(0, 0.3, 71)).max() > 0.01  # the load's, not the trolley's
    crane = crane_with(tau=0.0)
    crane.service.serving.draw = lambda points, lifetime: drawn.append((points, lifetime))
    crane.execute(crane.goal('b', move(goal=0.3, duration=3.0)), move(goal=0.3, duration=3.0))
    assert len(drawn) == 1


def test_a_goal_during_a_motion_whose_handover_would_enter_a_box_is_refused_and_the_motion_goes_on():
    """The running motion (0 -> 0.3 m) keeps out of a wall at 0.45-0.55 m; a new goal at 0.8 m would take the
    load through it: refused naming the wall, nothing handed over, the running motion ends at 0.3 m."""
    crane = crane_with(keep_out=[0.45, 0.55, -math.inf, math.inf, -2.0, -0.76])
    old, running = run_old_goal_until(crane, T0 + 1_200_000_000)
    new_move = move(goal=0.8, duration=3.0)
    goal = crane.goal('new', new_move)
    outcome, _ = crane.execute(goal, new_move)
    assert outcome.how == 'abort' and outcome.message.startswith('move.keep_out: the zv plan does not keep out')
    assert 'keep_out box 1 (x 0.45..0.55' in outcome.message and len(crane.published) == 1
    assert old.state is not GoalState.TAKEN_OVER
    crane.clock.sleep(3.0)
    assert crane.hold == pytest.approx(0.3)


def test_nvf_and_zv_past_the_wall_are_routed_over_it_a_long_shaper_and_a_cart_alone_are_refused_saying_why():
    """With a hoist (the rope 0.47 m at both ends), NVF lifts the load over the wall: its PlanInfo says
    route over and a clearance of at least the margin; so does ZV (its straight move, the hoist's detour
    shaped); ZVD, twice as long a shaper, leaves the hoist no time in 4 s and is refused saying so; on a
    planner of the cart alone NVF has no way past it."""
    from crane_planner.serving import Planner
    from crane_planner.serving.moves import check_move, plan_keeping_out
    planner = Planner()
    hoisted = config(joints=['cart', 'hoist'], keep_out=WALL, tau=0.0, tau_hoist=0.0, max_solve_time=10.0)
    move_ = check_move(Move('nvf', goal=(0.6, 0.47), duration=4.0), hoisted.bounds, None, hoisted.params.L1)
    plan = plan_keeping_out(planner, move_, hoisted.bounds, hoisted.params, hoisted.options, hoisted.keep_out)
    summary = summarize(plan, move_.joints)
    assert summary.route == 'over' and 0.02 <= summary.min_clearance < 0.04
    assert plan.axes['hoist'].evaluate([4.0]).position[0] + plan.starts['hoist'] == pytest.approx(0.47, abs=1e-9)
    zv = check_move(Move('zv', goal=(0.6, 0.47), duration=4.0), hoisted.bounds, None, hoisted.params.L1)
    shaped = plan_keeping_out(planner, zv, hoisted.bounds, hoisted.params, hoisted.options, hoisted.keep_out)
    summary = summarize(shaped, zv.joints)  # its straight move, the hoist lifting the load over and back
    assert summary.route == 'over' and summary.min_clearance >= 0.02
    zvd = check_move(Move('zvd', goal=(0.6, 0.47), duration=4.0), hoisted.bounds, None, hoisted.params.L1)
    with pytest.raises(MoveError, match=r'no route past it: over \(hoist -0.151 m\): the hoist has 1.\d\d s to '
                                        'lift the load (before|after) the box, not more than the zvd shaper'):
        plan_keeping_out(planner, zvd, hoisted.bounds, hoisted.params, hoisted.options, hoisted.keep_out)
    alone = config(keep_out=WALL, tau=0.0)
    cart = check_move(Move('nvf', goal=(0.6,), duration=4.0), alone.bounds, None, alone.params.L1)
    with pytest.raises(MoveError, match='no route past it: the served axes allow none'):
        plan_keeping_out(planner, cart, alone.bounds, alone.params, alone.options, alone.keep_out)
