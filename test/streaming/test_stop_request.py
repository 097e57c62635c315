"""streaming.stop_request: the streamer's ~/stop from each state and mode, on explicit ticks and a fake clock."""
import pytest

from crane_planner.streaming.braking_stop import METHOD
from crane_planner.streaming.reference_stream import ReferenceStream
from crane_planner.streaming.stop_request import request_stop
from crane_planner.streaming.streamer import Streamer
from crane_planner.streaming.streamer_state import State

from .test_reference_stream import EPOCH, HOLD, MS, PERIOD, quintic_knots
from .test_streamer import Loop, operator_moving, streaming

D, J = 0.5, 5.0


def stop(streamer, loop=None, take_over=None, cancel_start=lambda: None):
    now = (lambda: EPOCH + loop.tick * PERIOD) if loop else (lambda: EPOCH)
    return request_stop(streamer, take_over or (lambda: None), now, D, J, cancel_start)


def run_to_rest(loop, most=20_000):
    for _ in range(most):
        if not loop.streamer.stream.running:
            return
        loop.run(1)
    raise AssertionError('never stopped')


def test_stopped_or_waiting_it_is_already_stopped_and_a_waiting_start_is_cancelled():
    streamer = Streamer(ReferenceStream(PERIOD, HOLD, stopped=True))
    cancelled = []
    assert stop(streamer, cancel_start=lambda: cancelled.append(1)).message == 'already stopped'
    streamer.wait()
    assert stop(streamer, cancel_start=lambda: cancelled.append(1)).message == 'already stopped'
    assert streamer.state is State.STOPPED and cancelled == [1, 1]


def test_at_rest_it_stops_at_once():
    streamer = streaming()
    Loop(streamer).run(5)
    assert stop(streamer).message == 'stopped'
    assert streamer.state is State.STOPPED and not streamer.stream.running


def test_in_operator_mode_the_command_is_zeroed_and_the_stream_stops_once_at_rest():
    streamer = streaming()
    loop = Loop(streamer)
    operator = operator_moving(streamer, loop)
    answer = stop(streamer, loop)
    assert answer.message.startswith('stopping: the command set to zero') and not answer.warning
    assert streamer.state is State.STOPPING
    assert stop(streamer, loop).message == 'already stopping'
    run_to_rest(loop)
    assert streamer.state is State.STOPPED and streamer.stream.hold == operator.position[0]


def test_during_a_motion_without_a_stop_in_time_the_braking_ramp_and_a_warning():
    streamer = streaming()
    loop = Loop(streamer)
    streamer.stream.accept(*quintic_knots(), EPOCH + 3 * MS, EPOCH)
    loop.run(400)

    def late():
        raise ValueError('the stop planner is not ready')
    answer = stop(streamer, loop, late)
    assert METHOD in answer.message and 'not ready' in answer.warning
    assert streamer.state is State.STOPPING
    run_to_rest(loop)
    assert streamer.state is State.STOPPED
    assert abs(streamer.stream.hold - (HOLD + 0.3)) > 1e-3  # braked along the ramp, not the motion


def test_during_a_motion_a_stop_that_the_motion_outruns_stops_at_its_end():
    streamer = streaming()
    loop = Loop(streamer)
    streamer.stream.accept(*quintic_knots(), EPOCH + 3 * MS, EPOCH)
    loop.run(400)
    answer = stop(streamer, loop, lambda: None)
    assert answer.message.startswith('stopping: the motion ends before a stop could take over')
    run_to_rest(loop)
    assert streamer.state is State.STOPPED and streamer.stream.hold == pytest.approx(HOLD + 0.3)
