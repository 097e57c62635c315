"""An executed goal from arrival to result (serving.service) on a fake clock and a fake streamer: what only
a ROS graph could show before (a preempt or a cancel before the first send, a start already past, a goal
during a motion handed over on arrival, a cancel while a handover is sent again)."""
import math

import pytest

from crane_planner.planning.signals import Swing
from crane_planner.serving.goals import GoalState
from crane_planner.serving.moves import MoveError
from crane_planner.serving.transitions import JointReading, Measurement
from serving.fake_crane import MS, T0, Crane, move

S = GoalState


def test_a_goal_preempted_before_its_first_send_streams_nothing():
    crane = Crane()
    first = move(start_ns=T0 + 2_000_000_000)  # held until publish_lead (0.3 s) before its start
    goal = crane.goal('a', first)
    crane.at(T0 + 500 * MS, lambda: crane.goal('b', move(0.1)))
    outcome, feedback = crane.execute(goal, first)
    assert outcome.how == 'abort' and 'preempted by a newer goal before its motion started' in outcome.message
    assert 'nothing was streamed' in outcome.message and crane.published == []
    assert goal.history == [S.ARRIVED, S.HELD, S.PREEMPTED] and goal.state is S.ENDED
    assert crane.clock() < T0 + 600 * MS  # it ended at once, not at its start
    assert feedback[0] == dict(progress=0.0, time_remaining=outcome.plan.plan.duration, swing=pytest.approx(math.nan,
                                                                                               nan_ok=True))


def test_a_goal_canceled_before_it_was_sent_streams_nothing():
    crane = Crane()
    held = move(start_ns=T0 + 2_000_000_000)
    goal = crane.goal('a', held)
    crane.at(T0 + 500 * MS, lambda: crane.service.goals.cancel(goal.handle))
    outcome, _ = crane.execute(goal, held, canceled=lambda: goal.state is S.CANCELED)
    assert (outcome.how, outcome.message) == ('cancel', 'canceled before its motion started: nothing was streamed')
    assert crane.published == [] and S.SENT not in goal.history


def test_a_goal_held_for_its_lead_is_sent_publish_lead_before_its_start():
    crane = Crane()
    start = T0 + 1_000_000_000
    goal = crane.goal('a', move(start_ns=start))
    outcome, _ = crane.execute(goal, move(start_ns=start))
    sent_at, trajectory = crane.published[0]
    assert start - sent_at == pytest.approx(300 * MS, abs=50 * MS) and trajectory.stamp_ns == start
    assert outcome.success and 'zv: 0 -> 0.3 m' in outcome.message
    assert goal.history == [S.ARRIVED, S.HELD, S.SENT, S.FOLLOWING]


def test_a_goal_whose_start_passed_streams_from_the_next_tick_its_origin_from_stream_state():
    crane = Crane()
    late = move(start_ns=T0 - 5 * MS)
    goal = crane.goal('a', late)
    outcome, _ = crane.execute(goal, late)
    sent_at, trajectory = crane.published[0]
    assert trajectory.stamp_ns == T0 - 5 * MS  # as asked; the streamer starts it at its next tick
    running = crane.service.timeline.running
    assert running.confirmed and running.origin_ns == (sent_at // MS + 1) * MS  # the streamer's, not the stamp
    assert outcome.success
    assert any(level == 'warn' and 'start_time had passed 0.005 s' in line for level, line in crane.log.lines)


def run_old_goal_until(crane, ns):
    """Start the old goal's motion and leave it streaming at ``ns`` (its follower stopped early)."""
    first = move(duration=3.0)
    goal = crane.goal('old', first)
    running = []

    def stop_following():
        running.append(crane.service.timeline.running)
        raise StopFollowing()

    crane.at(ns, stop_following)
    with pytest.raises(StopFollowing):
        crane.service.execute(goal, first, 0.2, lambda **f: None, lambda: False)
    return goal, running[0]


class StopFollowing(Exception):
    pass


def test_a_shapers_goal_during_a_motion_is_handed_over_on_arrival_and_takes_the_motion_over():
    crane = Crane()
    old, running = run_old_goal_until(crane, T0 + 1_200_000_000)
    assert crane.service.view.in_motion() is running
    new_move = move(goal=0.5, duration=3.0)
    arrived = crane.clock()
    goal = crane.goal('new', new_move)
    assert goal.state is S.SENT and len(crane.published) == 2  # sent from the goal callback
    sent_at, handover = crane.published[1]
    assert sent_at == arrived and handover.stamp_ns == arrived + 1 * MS  # shaper_handover_lead
    outcome, _ = crane.execute(goal, new_move)
    assert outcome.success and 'taking over the motion' in outcome.message
    assert old.state is S.TAKEN_OVER and goal.history == [S.ARRIVED, S.SENT, S.FOLLOWING]
    assert crane.hold == pytest.approx(0.5)


def test_a_cancel_while_a_handover_the_streamer_refused_is_sent_again_streams_nothing_more():
    crane = Crane(refuse=0)
    old, running = run_old_goal_until(crane, T0 + 1_200_000_000)
    crane.refuse = 1  # the streamer refuses the first handover (late on arrival)
    new_move = move(goal=0.5, duration=3.0)
    goal = crane.goal('new', new_move)
    handover = crane.published[-1][1].stamp_ns
    canceled = []
    crane.at(handover + 30 * MS, lambda: canceled.append(True))  # before the streamer is seen refusing it
    outcome, _ = crane.execute(goal, new_move, canceled=lambda: bool(canceled))
    assert (outcome.how, outcome.message) == ('cancel', 'canceled before its motion started: nothing was streamed')
    assert len(crane.published) == 2  # the old motion's and the refused handover: none sent again
    assert old.state is not S.TAKEN_OVER and crane.service.timeline.running is running
    assert crane.clock() > handover + 50 * MS  # it waited to see the handover not taken


def test_a_variational_goal_during_a_motion_that_cannot_be_planned_ends_with_the_reason():
    crane = Crane()
    run_old_goal_until(crane, T0 + 1_200_000_000)
    nvf = move(goal=0.5, duration=3.0, method='nvf')
    goal = crane.goal('new', nvf)
    assert goal.state is S.ARRIVED  # a variational goal is planned in execute, not on arrival
    outcome, _ = crane.execute(goal, nvf)
    assert outcome.how == 'abort' and 'no NVF/RVF solver' in outcome.message and len(crane.published) == 1
    assert math.isnan(outcome.residual_swing)


def test_a_settle_is_refused_during_a_motion_and_without_a_measured_swing():
    crane = Crane()
    with pytest.raises(MoveError, match='no joint_states within 0.5 s'):
        crane.service.settle()
    # measured swinging once the motion runs (a shaper's goal sent while the load swings would damp it first)
    crane.at(T0 + 1_000_000_000, lambda: crane.service.on_joint_state(
        Measurement(crane.clock(), {'cart': JointReading(0.0)}, Swing(theta1=0.01))))
    run_old_goal_until(crane, T0 + 1_200_000_000)
    with pytest.raises(MoveError, match='a motion is streaming'):
        crane.service.settle()
    assert len(crane.published) == 1


def test_the_handover_warm_up_rehearses_a_shapers_handover_sends_nothing_and_counts_for_the_motions_goal():
    crane = Crane()
    old, running = run_old_goal_until(crane, T0 + 1_200_000_000)
    rehearsed = []
    crane.service.warm_handover(rehearsed.append)
    assert len(rehearsed) == 1 and rehearsed[0].stamp_ns > crane.clock() and len(crane.published) == 1
    assert rehearsed[0].starts[0] == pytest.approx(float(running.at(rehearsed[0].stamp_ns)[0][0][0]))
    assert old.warmups == 1
    with crane.service.handing_over:  # a handover being planned: no rehearsal takes the core from it
        crane.service.warm_handover(rehearsed.append)
    assert len(rehearsed) == 1


def test_a_goal_whose_motion_ends_before_its_handover_is_taken_is_planned_from_where_the_motion_ended():
    """Nothing accepted is lost: a new goal near the end of a motion, its handover refused (late on a busy
    host) until the motion has ended, is planned from rest once the streamer says it holds there."""
    crane = Crane()
    old, running = run_old_goal_until(crane, T0 + 2_950_000_000)  # 3 s motion: 50 ms left
    crane.refuse = 1  # the first handover came late
    new_move = move(goal=0.5, duration=2.0)
    goal = crane.goal('new', new_move)
    outcome, _ = crane.execute(goal, new_move)
    assert outcome.success and '0.3 -> 0.5 m' in outcome.message, outcome.message
    assert goal.history == [S.ARRIVED, S.SENT, S.HELD, S.SENT, S.FOLLOWING]
    sent_at, trajectory = crane.published[-1]
    assert sent_at >= running.end_ns and trajectory.starts[0] == pytest.approx(0.3)  # from rest, where it ended
    assert crane.hold == pytest.approx(0.5) and old.state is not S.TAKEN_OVER
    assert any(level == 'warn' and 'planning it from where the motion ended' in line for level, line in crane.log.lines)
