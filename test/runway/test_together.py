"""runway.together (several cranes' moves planned together offline, first published, first served) and
runway.anchors (the anchors' rule on the same moves): a crane's moves chained on its timeline, a refused move
leaving its crane where it stands, the least wait against the anchors' wait for the other's end, and the
rule's braking distances against what the move itself has left to go."""
import numpy as np
import pytest

from crane_msgs_py.crane.params import CraneParams
from crane_planner.planning.dispatch import plan
from crane_planner.runway.anchors import anchors_rule, braking_distances
from crane_planner.runway.together import Crane, Move, Scenario, plan_together

A = Crane('a', (0.0, 0.0), {'cart': 0.5, 'bridge': 1.0})
B = Crane('b', (0.0, 2.5), {'cart': 0.5, 'bridge': 0.0})
#: a leaves slowly (1 m in 4 s), b follows quickly (1.8 m in 2 s) and would catch it up
FOLLOWING = (Move('a', 'zv', {'bridge': 0.0}, 4.0, 0.0), Move('b', 'zv', {'bridge': -1.8}, 2.0, 0.1))


def girder_at(together, crane: str, t: float) -> float:
    return float(together.timelines[crane].at(np.array([round(t * 1e9)])).girder[0])


def test_a_cranes_moves_follow_each_other_on_its_timeline_each_from_where_the_last_ended():
    moves = (Move('a', 'zv', {'bridge': 0.0, 'cart': 1.0}, 3.0, 0.0),
             Move('a', 'nzv', {'bridge': 0.5}, 2.5, 1.0))  # asked before the first ends: starts at its end
    t = plan_together(Scenario((A, B), moves))
    first, second = t.placed
    assert second.asked == 3.0 and second.origin == {'cart': 1.0, 'bridge': 0.0} and second.delay == 0.0
    assert [girder_at(t, 'a', s) for s in (0.0, 3.0, 5.5, 9.0)] == pytest.approx([1.0, 0.0, 0.5, 0.5], abs=1e-9)
    assert girder_at(t, 'a', 1.5) == pytest.approx(0.5, abs=0.05)  # half way through the first
    assert t.total() == t.alone() == pytest.approx(5.5)
    assert girder_at(t, 'b', 4.0) == 2.5  # b never moved


def test_a_refused_move_leaves_its_crane_where_it_stands_and_its_next_move_starts_there():
    moves = (Move('a', 'zv', {'bridge': 2.5}, 3.0, 0.0),  # onto b's girder: no delay helps
             Move('a', 'zv', {'bridge': 0.5}, 2.0, 1.0))
    t = plan_together(Scenario((A, B), moves))
    refused, then = t.placed
    assert "crane 'b'" in refused.refused and refused.refused_by == 'b' and refused.occupancy is None
    assert then.origin['bridge'] == 1.0 and then.asked == 1.0 and not then.refused
    assert t.moved == [then] and t.total() == pytest.approx(3.0)  # from the first start asked for (0 s)


def test_planned_around_the_other_the_follower_waits_the_least_the_anchors_rule_until_the_other_has_finished():
    t = plan_together(Scenario((A, B), FOLLOWING))
    a, b = t.placed
    assert a.delay == 0.0 and b.waited_for == 'a' and 0.0 < b.delay < 2.0
    assert min(c.distance for c in t.closest(b).values()) >= 0.2
    rule = anchors_rule(t)
    assert [m.start for m in rule.timed] == pytest.approx([0.0, 4.0])  # b starts when a's motion ends
    assert rule.total == pytest.approx(6.0) and t.total() == pytest.approx(max(a.end, b.end))
    assert t.total() < 5.0
    # far apart, the rule lets both start when asked
    far = Crane('b', (0.0, 8.0), B.start)
    assert [m.start for m in anchors_rule(plan_together(Scenario((A, far), FOLLOWING))).timed] == [0.0, 0.1]


@pytest.mark.parametrize('method', ['zv', 'ei', 'nvf'])
def test_the_rules_braking_distance_is_never_more_than_the_move_has_left(method):
    """A drive braking within the move's own peak deceleration and jerk stops no later than the move itself
    does, so the rule asks no more than a crane can do."""
    p = plan(method, 0.3, 3.0, CraneParams(), bridge=1.2)
    t = np.linspace(0.0, 3.0, 301)
    b = braking_distances(p, t, 0.5, 5.0)
    left = 1.2 - p.evaluate_axis('bridge', t).position
    assert np.all(b <= left + 1e-5) and b[-1] == 0.0
    assert b.max() > 0.1  # (a real distance, at speed)
    assert braking_distances(p, np.array([3.5]), 0.5, 5.0)[0] == 0.0  # after the motion: at rest
    assert not braking_distances(plan(method, 0.3, 3.0, CraneParams()), t, 0.5, 5.0).any()  # no bridge
