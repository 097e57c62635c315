"""streaming.streamer_state: the streamer's state as an explicit machine (legal moves only, the loop's event)."""
import pytest

from crane_planner.streaming.streamer_state import RUNNING, TRANSITIONS, IllegalTransition, State, StreamerState


def test_every_state_has_its_moves_and_the_loop_runs_only_streaming_or_stopping():
    assert set(TRANSITIONS) == set(State)
    assert RUNNING == {State.STREAMING, State.STOPPING}


def test_a_start_a_stop_to_rest_and_a_start_again():
    machine = StreamerState()
    assert machine.state is State.STOPPED and not machine.running.is_set()
    machine.to(State.WAITING)  # the hold is measured first
    assert not machine.running.is_set()
    machine.to(State.STREAMING)
    assert machine.running.is_set()
    machine.to(State.STOPPING)
    assert machine.running.is_set()  # the loop streams the stop to rest
    assert machine.end_stop()
    assert machine.state is State.STOPPED and not machine.running.is_set()
    machine.to(State.STREAMING)  # the hold known at once (initial_position)
    assert machine.running.is_set()


@pytest.mark.parametrize('start, illegal', [(State.STOPPED, State.STOPPING), (State.WAITING, State.STOPPING),
                                            (State.STREAMING, State.WAITING), (State.STREAMING, State.STREAMING),
                                            (State.STOPPING, State.STREAMING), (State.STOPPING, State.WAITING),
                                            (State.STOPPING, State.STOPPING)])
def test_an_illegal_move_raises_and_changes_nothing(start, illegal):
    machine = StreamerState()
    path = {State.STOPPED: [], State.WAITING: [State.WAITING], State.STREAMING: [State.STREAMING],
            State.STOPPING: [State.STREAMING, State.STOPPING]}[start]
    for state in path:
        machine.to(state)
    running = machine.running.is_set()
    with pytest.raises(IllegalTransition, match=f'{start.value} -> {illegal.value}'):
        machine.to(illegal)
    assert machine.state is start and machine.running.is_set() == running


def test_the_loops_end_of_a_stop_after_a_halt_changes_nothing():
    machine = StreamerState()
    machine.to(State.STREAMING)
    machine.to(State.STOPPING)
    machine.to(State.STOPPED)  # the axes' fault reaction halted it first
    assert not machine.end_stop()
    assert machine.state is State.STOPPED
    machine.to(State.STOPPED)  # a halt racing the loop's own end of a stop
    assert machine.state is State.STOPPED


def test_a_stop_cancels_only_a_start_waiting_for_the_hold():
    machine = StreamerState()
    assert not machine.cancel()
    machine.to(State.WAITING)
    assert machine.cancel()
    assert machine.state is State.STOPPED
    machine.to(State.STREAMING)
    assert not machine.cancel()
    assert machine.state is State.STREAMING
