"""Via points in the planner's service (contract "Routes and protected areas"): a Move's via checked field by
field, NVF through them exactly, a shaper only within via_tolerance of its straight path, else refused naming
the point; a goal during a motion with via points refused."""
import math

import numpy as np
import pytest

from crane_planner.serving import Planner
from crane_planner.serving.config import PARAMETERS, Config
from crane_planner.serving.moves import Move, MoveError, check_move, plan_keeping_out
from serving.test_service import T0, Crane, run_old_goal_until


def config(**values) -> Config:
    defaults = {name: default for name, (default, _, _) in PARAMETERS.items()}
    return Config.from_values({**defaults, 'joints': ['cart', 'bridge'], 'tau': 0.0, **values})


@pytest.mark.parametrize('via, words', [
    (((0.5,),), 'move.via: point 1: 1 value(s) for 2 joint(s) (cart, bridge)'),
    (((0.5, 0.0), (0.5, math.nan)), 'move.via: point 2: positions must be finite'),
])
def test_a_bad_via_point_is_refused_naming_it(via, words):
    cfg = config()
    with pytest.raises(MoveError, match=words.replace('(', r'\(').replace(')', r'\)')):
        check_move(Move('nvf', goal=(0.6, 0.4), duration=4.0, via=via), cfg.bounds, None)


def test_a_fastest_move_or_a_rope_of_no_length_through_a_via_point_is_refused():
    cfg = config(**{'limits.cart.max_velocity': 0.5})
    with pytest.raises(MoveError, match='move.via: a move through via points needs a duration'):
        check_move(Move('nvf', goal=(0.6, 0.4), duration=0.0, via=((0.5, 0.0),)), cfg.bounds, None)
    hoisted = config(joints=['cart', 'hoist'])
    with pytest.raises(MoveError, match=r'move.via: point 1: hoist -0.1 m: the rope length \(L1\) must be > 0'):
        check_move(Move('nvf', goal=(0.6, 0.47), duration=4.0, via=((0.3, -0.1),)), hoisted.bounds, None)


def plan(cfg, method, via, goal=(0.6, 0.4), start=(0.1, -0.2)):
    checked = check_move(Move(method, start=start, goal=goal, duration=4.0, via=via), cfg.bounds, None)
    return plan_keeping_out(Planner(), checked, cfg.bounds, cfg.params, cfg.options, cfg.keep_out)


def test_nvf_passes_the_via_point_exactly_from_wherever_the_move_starts():
    p = plan(config(), 'nvf', ((0.5, -0.1),))
    t = np.linspace(0.0, 4.0, 40001)
    x = p.axes['cart'].evaluate(t).position + 0.1
    y = p.axes['bridge'].evaluate(t).position - 0.2
    assert np.hypot(x - 0.5, y + 0.1).min() < 1e-3 and p.info['route'] == 'via'


def test_a_shaper_passes_a_via_point_on_its_straight_path_and_is_refused_one_off_it():
    cfg = config()
    p = plan(cfg, 'zv', ((0.35, 0.1),))  # on the line from (0.1, -0.2) to (0.6, 0.4)
    assert p.method == 'zv'
    with pytest.raises(MoveError) as refused:
        plan(cfg, 'zv', ((0.35, 0.0),))  # 0.1 m off it (64 mm from the line)
    assert refused.value.field == 'via' and str(refused.value).startswith(
        "move.via: point 1 (cart 0.35, bridge 0 m) is 64 mm from the zv plan's straight path, beyond via_tolerance "
        '10 mm')
    assert plan(config(via_tolerance=0.07), 'zv', ((0.35, 0.0),)).method == 'zv'


def test_a_goal_during_a_motion_with_via_points_is_refused_and_the_motion_goes_on():
    crane = Crane()
    old, running = run_old_goal_until(crane, T0 + 1_200_000_000)
    new = Move('zv', goal=(0.5,), duration=3.0, via=((0.4,),))
    goal = crane.goal('new', new)
    outcome, _ = crane.execute(goal, new)
    assert outcome.how == 'abort' and outcome.message.startswith('move.via: a goal during a motion goes straight')
    assert len(crane.published) == 1
    crane.clock.sleep(3.0)
    assert crane.hold == pytest.approx(0.3)
