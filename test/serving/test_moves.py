"""serving.moves: a Move checked field by field, planned, described; every refusal names its field."""
import math

import pytest

from crane_msgs_py.crane.params import CraneParams
from crane_planner.planning import PlanOptions
from crane_planner.serving import Planner
from crane_planner.serving.moves import AxisMove, Move, MoveBounds, MoveError, check_move, plan_move, summarize

BOUNDS = MoveBounds(('cart',), 'rvf', max_displacement=2.0, max_duration=20.0)
HOLD = {'cart': 0.25}


@pytest.mark.parametrize('move, field, needle', [
    (Move(method='xyz', goal=(0.3,), duration=3.0), 'method', "unknown method 'xyz'"),
    (Move(joint_names=('hoist',), goal=(0.3,), duration=3.0), 'joint_names', "unknown joint 'hoist'"),
    (Move(joint_names=('cart', 'cart'), goal=(0.3, 0.3), duration=3.0), 'joint_names', 'named twice'),
    (Move(goal=(0.3, 0.1), duration=3.0), 'goal', '2 value(s) for 1 joint(s)'),
    (Move(goal=(), duration=3.0), 'goal', '0 value(s) for 1 joint(s)'),
    (Move(start=(0.0, 0.0), goal=(0.3,), duration=3.0), 'start', '2 value(s) for 1 joint(s)'),
    (Move(goal=(math.nan,), duration=3.0), 'goal', 'cart must be finite'),
    (Move(start=(math.inf,), goal=(0.3,), duration=3.0), 'start', 'cart must be finite'),
    (Move(goal=(0.3,), duration=-1.0), 'duration', 'got -1.0'),
    (Move(goal=(0.3,), duration=math.nan), 'duration', 'must be finite'),
    (Move(goal=(0.3,), duration=math.inf), 'duration', 'must be finite'),
    (Move(goal=(5.0,), duration=3.0), 'goal', 'exceeds max_displacement 2 m'),
    (Move(goal=(0.3,), duration=25.0), 'duration', '25 s exceeds max_duration 20 s'),
])
def test_each_bad_field_is_refused_naming_it_and_its_bound(move, field, needle):
    with pytest.raises(MoveError) as err:
        check_move(move, BOUNDS, HOLD)
    assert err.value.field == field and str(err.value).startswith(f'move.{field}: ') and needle in str(err.value)


def test_an_empty_start_is_where_the_streamer_holds_the_axes_else_zero():
    move = check_move(Move(goal=(0.55,), duration=3.0), BOUNDS, HOLD)
    assert (move.method, move.joint_names, move.axes) == ('rvf', ('cart',), {'cart': AxisMove(0.25, 0.55)})
    assert move.displacement == pytest.approx(0.3)
    # no streamer: a preview from 0
    assert check_move(Move(goal=(0.3,), duration=3.0), BOUNDS, None).axes['cart'].start == 0.0
    assert check_move(Move(start=(0.1,), goal=(0.3,), duration=0.0), BOUNDS, HOLD).duration is None  # fastest


@pytest.mark.parametrize('move, needle', [
    (Move(method='zv', goal=(0.3,), duration=0.5), 'zv'),                   # shorter than the shaper itself
    (Move(method='zv', start=(0.0,), goal=(0.3,), duration=3.0), 'max_velocity 0.1'),  # a limit it would break
    (Move(method='nvf', goal=(0.3,), duration=0.0), 'max_velocity'),        # fastest without a limit
])
def test_a_refusal_of_the_planning_core_names_the_duration(move, needle):
    options = PlanOptions(max_velocity=0.1) if 'max_velocity 0.1' in needle else PlanOptions()
    checked = check_move(move, BOUNDS, HOLD)
    with pytest.raises(MoveError) as err:
        plan_move(Planner(), checked, BOUNDS, CraneParams(), options)
    assert str(err.value).startswith('move.duration') and needle in str(err.value)


def test_a_fastest_plan_beyond_max_duration_is_refused_naming_it():
    bounds = MoveBounds(('cart',), 'zv', max_displacement=2.0, max_duration=2.0)
    checked = check_move(Move(goal=(1.5,), duration=0.0), bounds, HOLD)
    with pytest.raises(MoveError, match=r'move.duration: the fastest zv plan lasts .* beyond max_duration 2 s'):
        plan_move(Planner(), checked, bounds, CraneParams(), PlanOptions(max_velocity=0.3))


def test_the_summary_gives_the_peaks_of_the_reference_per_joint():
    checked = check_move(Move(method='zv', goal=(0.3,), duration=3.0), BOUNDS, None)
    plan = plan_move(Planner(), checked, BOUNDS, CraneParams(), PlanOptions())
    summary = summarize(plan, checked.joint_names, 0.001)
    dense = plan.evaluate([k * 1e-4 for k in range(30001)])
    assert summary.joint_names == ('cart',) and summary.duration == 3.0 and summary.method == 'zv'
    assert summary.peak_velocity[0] == pytest.approx(abs(dense.velocity).max(), rel=1e-6)
    assert summary.peak_acceleration[0] == pytest.approx(abs(dense.acceleration).max(), rel=1e-4)
    assert math.isnan(summary.predicted_residual) and summary.solve_time == 0.001


HOIST_BOUNDS = MoveBounds(('cart', 'hoist'), 'zv', max_displacement=2.0, max_duration=20.0)


def test_a_move_with_a_hoist_starts_at_the_model_length_without_a_streamer_and_holds_what_it_leaves_out():
    lift = check_move(Move(goal=(0.3, 0.27), duration=3.0), HOIST_BOUNDS, None, L1=0.47)
    assert lift.axes == {'cart': AxisMove(0.0, 0.3), 'hoist': AxisMove(0.47, 0.27)}
    assert lift.joints == ('cart', 'hoist') and lift.starts == (0.0, 0.47)
    held = check_move(Move(joint_names=('cart',), goal=(0.3,), duration=3.0), HOIST_BOUNDS,
                      {'cart': 0.1, 'hoist': 0.4})
    assert held.axes == {'cart': AxisMove(0.1, 0.3), 'hoist': AxisMove(0.4, 0.4)} and held.displacement == 0.3 - 0.1
    assert held.goals == {'cart': 0.3, 'hoist': 0.4}
    later = held.starting({'cart': 0.2}, 7)
    assert later.axes == {'cart': AxisMove(0.2, 0.3), 'hoist': AxisMove(0.4, 0.4)} and later.start_ns == 7
    for move, field in ((Move(goal=(0.3, -0.1), duration=3.0), 'goal'),
                        (Move(start=(0.0, 0.0), goal=(0.3, 0.3), duration=3.0), 'start')):
        with pytest.raises(MoveError, match=f'move.{field}: hoist .* the rope length'):
            check_move(move, HOIST_BOUNDS, None)
    with pytest.raises(MoveError, match='hoist displacement 2.53 m from the start exceeds max_displacement 2 m'):
        check_move(Move(goal=(0.3, 3.0), duration=3.0), HOIST_BOUNDS, None)


def test_a_hoisting_move_plans_both_axes_and_a_held_hoist_is_planned_at_its_length():
    params = CraneParams(tau=0.0)
    lift = plan_move(Planner(), check_move(Move(goal=(0.3, 0.27), duration=3.0), HOIST_BOUNDS, None, L1=0.47),
                     HOIST_BOUNDS, params, PlanOptions())
    assert lift.joint_names == ('cart', 'hoist') and lift.starts['hoist'] == 0.47
    assert lift.evaluate_axis('hoist', 3.0).position[0] == pytest.approx(0.27, abs=1e-12)
    summary = summarize(lift, ('cart', 'hoist'))
    assert summary.peak_velocity[1] == pytest.approx(15 / 8 * 0.2 / 3.0, rel=1e-6)  # the hoist's quintic
    # the hoist still: the cart's plan on the model at the rope's length now (0.3 m, not the parameter's 0.47)
    held = plan_move(Planner(), check_move(Move(goal=(0.3, 0.3), duration=3.0), HOIST_BOUNDS, {'cart': 0.0,
                                                                                                'hoist': 0.3}),
                     HOIST_BOUNDS, params, PlanOptions())
    from crane_planner.planning.dispatch import plan
    at_length = plan('zv', 0.3, 3.0, params.replace(L1=0.3))
    assert held.axes['cart'].info['impulse_times'] == at_length.info['impulse_times']
    assert summarize(held, ('cart', 'hoist')).peak_velocity[1] == 0.0


class Recording:
    """A planner that plans by ``dispatch`` (no pools) and records the axes it was asked to move beside the cart."""

    def __init__(self):
        from crane_planner.planning.dispatch import SolverCache
        self.asked, self.solvers = [], SolverCache()

    def plan(self, method, displacement, duration, params, options, hoist=None, **bridge):
        from crane_planner.planning.dispatch import plan
        self.asked.append(dict(hoist=hoist, **bridge))
        return plan(method, displacement, duration, params, options, self.solvers, hoist, **bridge)


def test_a_bridge_that_moves_is_planned_with_the_cart_and_one_that_does_not_is_held():
    bounds = MoveBounds(('cart', 'bridge', 'hoist'), 'nvf', max_displacement=2.0, max_duration=20.0)
    hold = {'cart': 0.1, 'bridge': -0.2, 'hoist': 0.4}
    planner, params = Recording(), CraneParams(tau=0.0)
    diagonal = plan_move(planner, check_move(Move(joint_names=('cart', 'bridge'), goal=(0.4, 0.0), duration=3.0),
                                             bounds, hold), bounds, params, PlanOptions())
    assert planner.asked[-1] == {'hoist': None, 'bridge': pytest.approx(0.2)}
    assert diagonal.joint_names == ('cart', 'bridge', 'hoist') and diagonal.starts['hoist'] == 0.4
    assert diagonal.axes['bridge'].evaluate(3.0).position[0] == pytest.approx(0.2, abs=1e-9)
    along = plan_move(planner, check_move(Move(method='zv', joint_names=('cart',), goal=(0.4,), duration=3.0),
                                          bounds, hold), bounds, params, PlanOptions())
    assert planner.asked[-1] == {'hoist': None}  # a shaper's plan of the cart, the bridge and the hoist held
    assert along.joint_names == ('cart', 'bridge', 'hoist')
    assert along.starts == {'cart': 0.0, 'bridge': 0.0, 'hoist': 0.4}
    assert summarize(along, ('cart', 'bridge', 'hoist')).peak_velocity[1:] == (0.0, 0.0)
    # without a streamer the bridge starts at 0, like the cart
    assert check_move(Move(goal=(0.3, 0.1, 0.5), duration=3.0), bounds, None).starts == (0.0, 0.0, 0.47)
