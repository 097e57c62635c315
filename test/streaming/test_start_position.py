"""streaming.start_position: the streamer's hold is where the axes stand, measured at rest."""
import pytest

from crane_planner.streaming.start_position import (
    REST_SPEED,
    TRANSITIONS,
    IllegalPhase,
    Phase,
    StartPosition,
)

S = 1_000_000_000
JOINTS = ('cart', 'hoist')


def measured(**kw):
    return StartPosition(JOINTS, 'joint_states', (0.0, 0.47), **kw)


def test_the_hold_is_the_first_measurement_at_rest_after_the_request():
    start = measured()
    assert start.on_joint_state(['cart', 'hoist', 'theta1', 'theta2'], [8.7, 0.5, 0.0, 0.0], [0.0] * 4) is None
    assert start.phase is Phase.IDLE  # nothing asked yet: a measurement alone starts nothing
    assert start.request(0) is None and start.phase is Phase.WAITING
    hold = start.on_joint_state(['theta1', 'hoist', 'cart', 'theta2'], [0.1, 0.52, 8.7, 0.0], [0.0] * 4)
    assert hold.position == (8.7, 0.52) and hold.source == 'joint_states'  # by name, in the streamed order
    assert start.phase is Phase.KNOWN and start.hold == hold


def test_an_axis_still_moving_is_waited_for():
    start = measured()
    start.request(0)
    assert start.on_joint_state(['cart', 'hoist'], [8.6, 0.47], [0.2, 0.0]) is None
    assert 'cart' in start.waiting_for and '0.2' in start.waiting_for
    assert start.on_joint_state(['cart', 'hoist'], [8.7, 0.47], [0.5 * REST_SPEED, 0.0]).position == (8.7, 0.47)


def test_joint_states_without_a_streamed_joint_do_not_give_a_hold():
    start = measured()
    start.request(0)
    assert start.on_joint_state(['cart', 'theta1'], [1.0, 0.0], [0.0, 0.0]) is None
    assert 'hoist' in start.waiting_for


def test_initial_position_is_held_only_when_told_or_when_no_feedback_exists_and_the_fallback_is_on():
    told = StartPosition(JOINTS, 'initial_position', (0.1, 0.5))
    assert told.request(0).position == (0.1, 0.5) and told.phase is Phase.KNOWN
    never = measured()
    never.request(0)
    assert never.poll(100 * S) is None and never.phase is Phase.WAITING  # no fallback: it waits
    fallback = measured(fallback_after=2.0)
    fallback.request(10 * S)
    assert fallback.poll(12 * S) is None
    hold = fallback.poll(12 * S + 1)
    assert hold.position == (0.0, 0.47) and 'initial_fallback_after' in hold.reason
    heard = measured(fallback_after=2.0)
    heard.request(0)
    heard.on_joint_state(['cart', 'hoist'], [3.0, 0.47], [0.3, 0.0])  # feedback exists, moving: waited for
    assert heard.poll(60 * S) is None


def test_every_start_measures_again():
    start = measured()
    start.request(0)
    start.on_joint_state(['cart', 'hoist'], [1.0, 0.47], [0.0, 0.0])
    start.request(5 * S)  # ~/start after a ~/stop: the crane may have moved meanwhile
    assert start.hold is None and start.phase is Phase.WAITING
    assert start.on_joint_state(['cart', 'hoist'], [2.0, 0.47], [0.0, 0.0]).position == (2.0, 0.47)


def test_a_stop_before_the_hold_is_known_asks_nothing_more():
    start = measured()
    start.request(0)
    start.cancel()
    assert start.phase is Phase.IDLE
    assert start.on_joint_state(['cart', 'hoist'], [2.0, 0.47], [0.0, 0.0]) is None


def test_transitions_are_explicit():
    assert Phase.IDLE not in TRANSITIONS[Phase.IDLE]
    start = StartPosition(('cart',), 'joint_states', (0.0,))
    with pytest.raises(IllegalPhase):
        start._to(Phase.IDLE)  # (nothing was asked)
    told = StartPosition(('cart',), 'initial_position', (0.0,))
    told.request(0)
    assert told.request(1).position == (0.0,)  # a ~/stop and ~/start of a streamer without feedback


def test_bad_settings_are_refused_naming_them():
    with pytest.raises(ValueError, match='hold_source'):
        StartPosition(JOINTS, 'guess', (0.0, 0.47))
    with pytest.raises(ValueError, match='initial position'):
        StartPosition(JOINTS, 'joint_states', (0.0,))
