"""The goals' states (serving.goals): legal transitions only, and the book's rules (preempt the unsent,
cancel before sending, take over, forget the unaccepted)."""
import pytest

from crane_planner.serving.execution import Execution
from crane_planner.serving.goals import TRANSITIONS, Goal, Goals, GoalState, IllegalTransition
from crane_planner.serving.timeline import Timeline
from crane_planner.serving.transitions import Running
from serving.fake_clock import FakeClock

S = GoalState
T0 = 10_000_000_000


def motion(origin_ns=T0, x=0.0):
    return Running(('cart',), [0.0, 1.0], [[x], [x + 0.1]], [[0.0], [0.0]], [[0.0], [0.0]], origin_ns)


def execution(start_ns=T0):
    return Execution(1.0, 1.0, start_ns, 0.6, 0.2)


def test_every_state_has_its_transitions_and_the_ends_lead_nowhere():
    assert set(TRANSITIONS) == set(GoalState)
    assert TRANSITIONS[S.ENDED] == set() and TRANSITIONS[S.FORGOTTEN] == set()
    assert all(S.ENDED in TRANSITIONS[s] for s in GoalState if s not in (S.ENDED, S.FORGOTTEN))


@pytest.mark.parametrize('path, illegal', [
    ((S.SENT, S.FOLLOWING), S.HELD),  # a streaming trajectory is never held again
    ((S.PREEMPTED,), S.SENT),  # a goal that gave way never streams
    ((S.CANCELED,), S.SENT),
    ((S.SENT, S.FOLLOWING), S.SENT),
    ((S.SENT, S.TAKEN_OVER), S.FOLLOWING),
    ((S.ENDED,), S.ENDED),
    ((S.FORGOTTEN,), S.ENDED),
    ((S.HELD,), S.FORGOTTEN),  # an accepted goal is never forgotten
])
def test_an_illegal_transition_raises_naming_both_states(path, illegal):
    goal = Goal(T0)
    for state in path:
        goal.change(state)
    with pytest.raises(IllegalTransition, match=f'{goal.state.value} cannot become {illegal.value}'):
        goal.change(illegal)
    assert goal.state is path[-1]


def test_a_new_goal_preempts_the_unsent_ones_only():
    goals, timeline = Goals(FakeClock(T0)), Timeline()
    held, _ = goals.arrive('a')
    goals.accept('a', 'handle a')
    assert goals.hold(held)
    moving, _ = goals.arrive('b')
    goals.accept('b', 'handle b')
    sent = motion()
    assert timeline.send(sent, lambda: goals.send(moving, execution(), sent))
    newest, _ = goals.arrive('c')
    assert held.state is S.PREEMPTED and moving.state is S.SENT and newest.state is S.ARRIVED
    never = motion()
    assert not timeline.send(never, lambda: goals.send(held, execution(), never))  # it never streams
    assert timeline.running is moving.running


def test_a_cancel_before_sending_means_nothing_may_be_sent_and_after_it_changes_nothing():
    goals = Goals(FakeClock(T0))
    first, _ = goals.arrive('a')
    goals.accept('a', 'h1')
    assert goals.cancel('h1') is first and first.state is S.CANCELED
    assert not goals.hold(first) and not goals.send(first, execution())
    second, _ = goals.arrive('b')
    goals.accept('b', 'h2')
    assert goals.send(second, execution())
    goals.cancel('h2')
    assert second.state is S.SENT  # its own thread stops the motion
    third, _ = goals.arrive('c')
    goals.accept('c', 'h3')
    assert not goals.send(third, execution(), canceled=lambda: True)  # the server's own flag counts too
    assert third.state is S.CANCELED


def test_a_goal_sent_ends_the_settle_windows_of_the_others_at_its_start():
    goals = Goals(FakeClock(T0))
    done, _ = goals.arrive('a')
    goals.send(done, execution(T0))
    goals.follow(done)
    late, _ = goals.arrive('b')
    goals.send(late, execution(T0 + 3_000_000_000), motion(T0 + 3_000_000_000))
    assert done.execution.cut_ns == T0 + 3_000_000_000 and late.execution.cut_ns is None


def test_a_handover_taken_takes_the_moving_goal_over_and_makes_the_motion_the_new_ones():
    goals, timeline = Goals(FakeClock(T0)), Timeline()
    old, _ = goals.arrive('a')
    first = motion()
    timeline.send(first, lambda: goals.send(old, execution(), first))
    goals.follow(old)
    new, _ = goals.arrive('b')
    assert goals.send(new, execution(T0 + 500_000_000))  # a handover: not the streamer's motion yet
    assert timeline.running is old.running
    spliced = motion(x=1.0)
    timeline.send(spliced, lambda: goals.take_over(new, T0 + 500_000_000, spliced) or True)
    assert old.state is S.TAKEN_OVER and new.state is S.FOLLOWING
    assert timeline.running is spliced and new.running is spliced and goals.owner(spliced) is new
    assert old.execution.cut_ns == T0 + 500_000_000
    assert not goals.send(old, execution())  # taken over: nothing more of it is sent


def test_a_goal_never_accepted_is_forgotten_after_a_while_and_an_accepted_one_never():
    clock = FakeClock(T0)
    goals = Goals(clock, unaccepted_after=10.0)
    lost, _ = goals.arrive('lost')
    kept, _ = goals.arrive('kept')
    goals.accept('kept', 'handle')
    clock.ns += 9_000_000_000
    _, forgotten = goals.arrive('x')
    assert forgotten == [] and len(goals) == 3
    clock.ns += 2_000_000_000
    _, forgotten = goals.arrive('y')
    assert forgotten == [lost] and lost.state is S.FORGOTTEN and kept.state is S.PREEMPTED
    assert goals.of('handle') is kept and len(goals) == 3  # kept, x and y


def test_the_origin_of_a_motion_is_its_goals_executions_once_the_streamer_says_it():
    goals = Goals(FakeClock(T0))
    goal, _ = goals.arrive('a')
    running = motion(origin_ns=0)
    goals.send(goal, execution(), running)
    assert goals.origin_of(running) is None
    goal.execution.on_stream_state(T0 + 1_000_000, T0 + 1_000_000, 1.0, T0 + 1_000_000)
    assert goals.origin_of(running) == T0 + 1_000_000
    goals.count_warmup(running, 0.001)
    goals.count_warmup(motion(), 0.001)  # not a goal's motion: counted for nobody
    assert (goal.warmups, goal.warmup_s) == (1, 0.001)
