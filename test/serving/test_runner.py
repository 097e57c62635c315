"""The goal runner (serving.runner) on a fake clock: one worker steps every executing goal; a goal submitted
while one executes is pending until the worker's next step, then current, and the goal it preempts is stepped
beside it to the outcome its own steps give. Also the axes' timeline (serving.timeline)."""
import threading

import pytest

from crane_planner.serving.runner import GoalRunner, RunnerStopped
from crane_planner.serving.timeline import Timeline
from serving.fake_clock import FakeClock

T0 = 40_000_000_000


def ticks(name, log, n, wait=0.05, clock=None):
    """Steps that log each step (and the time, if a clock is given) and end after ``n`` steps."""
    for k in range(n):
        log.append((name, k) if clock is None else (name, k, clock()))
        yield wait
    return f'{name} done'


def runner_on(clock):
    return GoalRunner(clock.timer, clock.sleep)


def test_a_goals_steps_run_to_its_outcome_waiting_what_each_step_yields():
    clock, log = FakeClock(T0), []
    runner = runner_on(clock)
    assert runner.run(ticks('a', log, 3, clock=clock)) == 'a done'
    assert log == [('a', 0, T0), ('a', 1, T0 + 50_000_000), ('a', 2, T0 + 100_000_000)]
    assert runner.current is None and runner.pending is None and runner.step() is None  # nothing left


def test_a_goal_submitted_while_one_executes_is_pending_until_the_next_step_then_current_beside_the_old():
    clock, log = FakeClock(T0), []
    runner = runner_on(clock)
    old = runner.submit(ticks('old', log, 3))
    runner.step()
    assert runner.current is old and runner.pending is None
    new = runner.submit(ticks('new', log, 2))
    assert runner.pending is new and runner.current is old  # not before the worker's next step
    clock.advance(0.05)
    runner.step()
    assert runner.current is new and runner.finishing == [old] and runner.pending is None
    assert log == [('old', 0), ('old', 1), ('new', 0)]  # the preempted one stepped beside the new one
    while runner.step() is not None:
        clock.advance(0.05)
    assert (old.result(), new.result()) == ('old done', 'new done') and runner.finishing == []


def test_a_pending_goal_replaced_within_one_step_is_stepped_to_its_outcome():
    clock, log = FakeClock(T0), []
    runner = runner_on(clock)
    first = runner.submit(ticks('first', log, 1))
    second = runner.submit(ticks('second', log, 1))  # at most one pending: the first finishes beside it
    assert runner.pending is second and runner.finishing == [first]
    runner.step()
    assert runner.current is second and log == [('first', 0), ('second', 0)]
    clock.advance(0.05)
    runner.step()
    assert first.result() == 'first done' and second.result() == 'second done'


def test_a_step_due_later_is_not_taken_early_and_the_next_due_time_is_told():
    clock, log = FakeClock(T0), []
    runner = runner_on(clock)
    run = runner.submit(ticks('a', log, 2, wait=0.2))
    due = runner.step()
    assert due == pytest.approx(clock.timer() + 0.2)
    clock.advance(0.1)
    assert runner.step() == pytest.approx(due) and log == [('a', 0)]
    clock.advance(0.1)
    runner.step()
    assert log == [('a', 0), ('a', 1)] and not run.done.is_set()


def test_what_a_goals_steps_raise_is_raised_to_its_caller_and_the_others_go_on():
    clock, log = FakeClock(T0), []
    runner = runner_on(clock)

    def broken():
        yield 0.01
        raise KeyError('a bug')

    other = runner.submit(ticks('other', log, 3))
    with pytest.raises(KeyError, match='a bug'):
        runner.run(broken())
    while not other.done.is_set():
        clock.advance(0.05)
        runner.step()
    assert other.result() == 'other done'


def test_a_wait_that_raises_ends_the_goal_it_was_driven_for():
    """Driven on the caller's thread, the wait is the goal's own: what it raises (a fake clock's hook) ends that
    goal, and the runner keeps no trace of it."""
    clock, log = FakeClock(T0), []
    runner = runner_on(clock)

    def hook(now):
        if now >= T0 + 100_000_000:
            raise RuntimeError('stop here')

    clock.hooks.append(hook)
    with pytest.raises(RuntimeError, match='stop here'):
        runner.run(ticks('a', log, 10))
    clock.hooks.remove(hook)
    assert runner.current is None and runner.pending is None and runner.finishing == []
    assert runner.run(ticks('b', log, 1)) == 'b done'


def test_the_worker_thread_serves_goals_submitted_from_other_threads_and_a_stop_ends_those_left():
    runner = GoalRunner()
    runner.start()
    log, results = [], {}

    def caller(name, n):
        results[name] = runner.run(ticks(name, log, n, wait=0.001))

    threads = [threading.Thread(target=caller, args=(name, 3)) for name in ('a', 'b')]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(10.0)
    assert results == {'a': 'a done', 'b': 'b done'}

    def forever():
        while True:
            yield 0.001

    left = runner.submit(forever())
    runner.stop()
    with pytest.raises(RunnerStopped):
        left.result()
    with pytest.raises(RunnerStopped):
        runner.run(ticks('late', log, 1))


@pytest.mark.filterwarnings('ignore::pytest.PytestUnhandledThreadExceptionWarning')  # (raised on, to be seen)
def test_a_worker_that_fails_ends_every_goal_and_refuses_the_next_instead_of_leaving_them_waiting():
    class Failing(GoalRunner):
        def step(self):  # the worker's own machinery breaks (not a goal's steps: those are the goal's outcome)
            raise SystemError('broken')

    runner = Failing()
    waiting = runner.submit(ticks('a', [], 3))
    runner.start()
    assert waiting.done.wait(10.0)  # (a hang guard: ended at once)
    runner._thread.join(10.0)  # (its failure raised on, within this test)
    with pytest.raises(RunnerStopped, match='broken'):
        waiting.result()
    with pytest.raises(RunnerStopped):
        runner.run(ticks('late', [], 1))


def test_the_timeline_changes_with_a_goal_only_if_the_goal_may_and_replaces_only_what_it_still_streams():
    timeline = Timeline()
    assert timeline.running is None and not timeline.sent_any()
    first, second = object(), object()
    assert not timeline.send(first, together=lambda: False)  # the goal gave way: nothing is sent
    assert timeline.running is None and not timeline.sent_any()
    assert timeline.send(first)
    changed = []
    assert not timeline.replace(second, None, together=lambda: changed.append(True))
    assert timeline.running is first and changed == []
    assert timeline.replace(first, second, together=lambda: changed.append(True))
    assert timeline.running is second and changed == [True]
    assert timeline.clear(second) and timeline.running is None
    assert timeline.sent_any()  # a motion sent once: a streaming one is this planner's own
