"""What the planner knows of the crane (serving.crane_view) on a fake clock: the streamer heard or not,
where it holds the axes, the motion in progress and its origin from stream_state."""
import math

import pytest

from crane_planner.planning.signals import Swing
from crane_planner.serving.crane_view import CraneView, StreamSample, joint_sample
from crane_planner.serving.execution import Execution
from crane_planner.serving.goals import Goals
from crane_planner.serving.moves import MoveError
from crane_planner.serving.preview import check_executable
from crane_planner.serving.timeline import Timeline
from crane_planner.serving.transitions import JointReading, Running
from serving.fake_clock import FakeClock

T0 = 30_000_000_000
MS = 1_000_000


def motion(origin_ns, duration=1.0):
    return Running(('cart',), [0.0, duration], [[0.0], [0.3]], [[0.0], [0.0]], [[0.0], [0.0]], origin_ns)


def sample(stamp_ns, state='holding', hold=0.0, start=0, duration=0.0, origin=0):
    return StreamSample(stamp_ns, state, {'cart': hold}, start, duration, origin)


@pytest.fixture
def crane():
    clock = FakeClock(T0)
    goals, timeline = Goals(clock), Timeline()
    view = CraneView(clock, goals, timeline, fresh=1.0, sleep=clock.sleep, monotonic=clock.timer)
    return clock, goals, timeline, view


def test_the_streamer_counts_as_heard_while_its_state_is_fresh(crane):
    clock, _, _, view = crane
    assert view.heard() is None and view.hold() is None and view.age() is None
    view.on_stream_state(sample(T0, hold=0.25))
    clock.ns += 900 * MS
    assert view.hold() == {'cart': 0.25} and view.age() == pytest.approx(0.9)
    clock.ns += 200 * MS
    assert view.heard() is None and view.hold() is None and view.age() == pytest.approx(1.1)
    view.on_stream_state(sample(clock(), 'operator'))
    assert view.heard().operator


def test_joint_states_become_a_measurement_with_the_hoist_if_there_is_one():
    m = joint_sample(T0, [0.1, 0.01, -0.02], [0.2, math.nan, 0.3])
    assert (m.stamp_ns, m.joints, m.swing) == (T0, {'cart': JointReading(0.1, 0.2)}, Swing(0.01, -0.02, 0.0, 0.3))
    m = joint_sample(T0, [0.1, 0.01, -0.02], [0.2, 0.0, 0.3], ['cart', 'hoist', 'theta1', 'theta2'],
                     [0.1, 0.55, 0.01, -0.02], [0.2])
    assert m.joints == {'cart': JointReading(0.1, 0.2), 'hoist': JointReading(0.55, 0.0)}


def test_joint_states_whose_positions_are_not_finite_are_no_measurement():
    """A camera that has lost the load sends NaN angles: no measurement (ValueError naming the joint, which the
    planner node drops), never a swing the planner would plan from or a dead executor."""
    with pytest.raises(ValueError, match='theta1 is nan'):
        joint_sample(T0, [0.1, math.nan, math.nan], [0.2, math.nan, math.nan])
    with pytest.raises(ValueError, match='cart is inf'):
        joint_sample(T0, [math.inf, 0.01, -0.02], [0.2, 0.0, 0.0])
    with pytest.raises(ValueError, match='hoist is nan'):
        joint_sample(T0, [0.1, 0.01, -0.02], [0.2, 0.0, 0.3], ['cart', 'hoist', 'theta1', 'theta2'],
                     [0.1, math.nan, 0.01, -0.02], [0.2])


def test_a_motion_with_a_stamp_is_in_motion_until_its_end(crane):
    clock, _, timeline, view = crane
    running = motion(T0 + 100 * MS)
    timeline.send(running)
    assert view.in_motion() is running
    clock.ns = running.end_ns
    assert view.in_motion() is None


def test_a_motion_the_streamer_holds_instead_of_streaming_counts_as_refused(crane):
    clock, _, timeline, view = crane
    running = motion(T0)
    timeline.send(running)
    view.on_stream_state(sample(T0 + 50 * MS))
    assert view.in_motion() is running  # not yet: it may start at the next tick
    clock.ns += 150 * MS
    view.on_stream_state(sample(clock()))
    assert view.in_motion() is None


def test_a_motion_sent_as_soon_as_possible_learns_its_origin_from_its_goals_stream_state(crane):
    clock, goals, timeline, view = crane
    goal, _ = goals.arrive('a')
    running = motion(0)
    execution = Execution(1.0, 1.0, T0, 0.6, 0.2)
    timeline.send(running, lambda: goals.send(goal, execution, running))
    assert view.in_motion() is running and not view.origin(running, wait=0.0)
    assert not view.origin(running, wait=0.1) and clock() - T0 >= 100 * MS  # it waited for it
    tick = clock() + 1 * MS
    execution.on_stream_state(tick, tick, 1.0, tick)
    assert view.origin(running) and running.origin_ns == tick and running.confirmed
    goals.remove(goal)
    assert view.in_motion() is running  # its origin known: in motion until its end, its goal ended or not


def test_a_motion_sent_as_soon_as_possible_whose_goal_ended_before_it_started_is_not_in_motion(crane):
    _, goals, timeline, view = crane
    goal, _ = goals.arrive('a')
    running = motion(0)
    timeline.send(running, lambda: goals.send(goal, Execution(1.0, 1.0, T0, 0.6, 0.2), running))
    goals.remove(goal)
    assert view.in_motion() is None


def test_a_motion_streaming_before_this_planner_sent_any_is_foreign_until_it_ends():
    S = 1_000_000_000
    now = [10 * S]
    goals, timeline = Goals(lambda: now[0]), Timeline()
    view = CraneView(lambda: now[0], goals, timeline)
    view.on_stream_state(StreamSample(now[0], 'streaming', {'cart': 0.2}, 9 * S, 4.0, 9 * S))
    assert view.foreign_motion() == pytest.approx(3.0)
    with pytest.raises(MoveError, match='did not send.*ends in 3 s'):
        check_executable(None, {'cart': 0.2}, foreign=view.foreign_motion())
    now[0] = 13 * S + 1
    view.on_stream_state(StreamSample(now[0], 'streaming', {'cart': 0.6}, 9 * S, 4.0, 9 * S))
    assert view.foreign_motion() is None  # (its last ticks: over by the clock)
    timeline.send(object())  # once this planner has sent a motion, the streamer's is its own
    timeline.send(None)
    now[0] = 10 * S
    view.on_stream_state(StreamSample(now[0], 'streaming', {'cart': 0.2}, 9 * S, 4.0, 9 * S))
    assert view.foreign_motion() is None
