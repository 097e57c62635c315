"""serving.moves: a Move checked field by field, planned, described; every refusal names its field."""
import math

import pytest

from crane_msgs_py.params import CraneParams
from crane_planner.planning import PlanOptions
from crane_planner.serving import Planner
from crane_planner.serving.moves import Move, MoveBounds, MoveError, check_move, plan_move, summarize

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
    assert (move.method, move.joint_names, move.start, move.goal) == ('rvf', ('cart',), 0.25, 0.55)
    assert move.displacement == pytest.approx(0.3)
    assert check_move(Move(goal=(0.3,), duration=3.0), BOUNDS, None).start == 0.0  # no streamer: a preview from 0
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
