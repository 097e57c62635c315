"""serving.yielding: a long solve paces itself between IPOPT iterations, a short or lone one does not."""
import time

import pytest

from crane_planner.serving.yielding import YieldingCallback


@pytest.fixture
def sleeps(monkeypatch):
    slept = []
    monkeypatch.setattr(time, 'sleep', slept.append)
    return slept


def callback():
    return YieldingCallback(3, 2, 1)


def test_a_solve_beside_another_pauses_half_its_last_iteration_past_after(sleeps):
    long, other = callback(), callback()
    with long.solving(), other.solving():
        assert YieldingCallback._active == 2
        long.start, long._last = 0.0, 0.07
        long.between_iterations(0.01)  # 10 ms into the solve: not yet
        long.between_iterations(0.08)  # past `after` (50 ms): half of the 10 ms iteration
    assert sleeps == [pytest.approx(0.005)]
    assert YieldingCallback._active == 0


def test_a_lone_solve_pauses_only_past_alone_after_and_then_as_long_as_its_iteration(sleeps):
    lone = callback()
    with lone.solving():
        lone.start, lone._last = 0.0, 0.09
        lone.between_iterations(0.1)  # 100 ms alone: a warm fastest request is not slowed
        lone._last = 0.25
        lone.between_iterations(0.26)
        lone._last = 0.3
        lone.between_iterations(0.5)  # never more than 20 ms at a time
    assert sleeps == [pytest.approx(0.01), pytest.approx(0.02)]


def test_the_deadline_stops_the_solve_at_its_next_iteration(sleeps):
    cb = callback()
    with cb.solving(deadline=time.perf_counter() - 1.0):
        assert cb.eval([]) == [1]
    with cb.solving(deadline=None):
        assert cb.eval([]) == [0]
    assert sleeps == []
