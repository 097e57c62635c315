"""streaming.status: the streamer's /diagnostics status."""
from crane_msgs_py.runtime import diagnostics
from crane_planner.streaming import status
from crane_planner.streaming.start_position import StartPosition


def start(asked: bool) -> StartPosition:
    s = StartPosition(('cart',), 'joint_states', (0.0,))
    if asked:
        s.request(0)
    return s


def test_levels_are_the_messages_own():
    assert (status.OK, status.WARN, status.ERROR) == (diagnostics.OK, diagnostics.WARN, diagnostics.ERROR)


def test_a_start_waiting_for_the_axes_position_is_a_warning_saying_nothing_streams():
    s = status.stream_status(False, False, False, start(True), None, 'ready', 0, 0.0)
    assert s.level == status.WARN and 'joint_states of cart' in s.message and 'nothing is streamed' in s.message


def test_states_and_levels():
    assert status.stream_status(True, True, False, start(False), None, 'ready', 0, 999.0).message == \
        'streaming at 999.0 Hz'
    assert status.stream_status(True, False, True, start(False), None, 'ready', 0, 1e3).state == 'operator, holding'
    assert status.stream_status(False, False, False, start(False), None, 'ready', 0, 0.0).state == 'stopped'
    unstoppable = status.stream_status(True, True, False, start(False), None, 'its process ended', 0, 1e3)
    assert unstoppable.level == status.WARN and 'stop planner' in unstoppable.message
    broken = status.stream_status(True, True, False, start(False), 'boom', 'ready', 0, 1e3)
    assert broken.level == status.ERROR and 'boom' in broken.message
