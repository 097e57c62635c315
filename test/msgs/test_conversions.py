"""Plans and states <-> standard messages (crane_msgs_py.messages.conversions, names)."""
import math
from types import SimpleNamespace

import numpy as np
import pytest
from crane_interfaces.msg import Move, StreamState
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from trajectory_msgs.msg import JointTrajectory

from crane_msgs_py.crane.params import ParameterError
from crane_msgs_py.messages import conversions as cv
from crane_msgs_py.messages.names import EXECUTE_MOVE_ACTION, PLAN_MOVE_SERVICE, service_of

START_NS = 1_700_000_000 * 10**9 + 999_000_000  # nanoseconds that carry into the seconds


def samples(n=7, T=0.06):
    t = np.append(np.arange(n - 1) * (T / (n - 1)), T)
    return SimpleNamespace(t=t, position=0.1 * t**2, velocity=0.2 * t, acceleration=np.full(n, 0.2))


def test_a_move_message_carries_the_request_per_joint_and_survives_serialization():
    msg = deserialize_message(serialize_message(cv.move_message([0.3], 2.5, [0.1], 'zv', ['cart'], START_NS)), Move)
    assert (msg.method, list(msg.joint_names), list(msg.start), list(msg.goal)) == ('zv', ['cart'], [0.1], [0.3])
    assert msg.duration == 2.5 and cv.stamp_ns(msg.start_time) == START_NS
    empty = cv.move_message([0.3], 0.0)
    assert (empty.method, list(empty.joint_names), list(empty.start), cv.stamp_ns(empty.start_time)) == ('', [], [], 0)


def test_stream_state_fill_in_place_and_read_back():
    msg = cv.stream_state_message()
    cv.fill_stream_state(msg, START_NS, True, 0.25, 0.1, -0.2, START_NS - 10**9, 3.0, motion_origin_ns=START_NS - 2)
    back = deserialize_message(serialize_message(msg), StreamState)
    assert cv.read_stream_state(back) == (START_NS, 'streaming', {'cart': 0.25}, START_NS - 10**9, 3.0, START_NS - 2,
                                          {'cart': 0.0}, '')
    assert (back.header.frame_id, list(back.velocity), list(back.acceleration)) == ('crane_base', [0.1], [-0.2])
    cv.fill_stream_state(msg, START_NS + 1, False, 0.3, 0.0, 0.0, 7, 0.0)
    assert cv.read_stream_state(msg)[5] == 7  # the origin is the first tick unless given
    assert cv.read_stream_state(msg)[:3] == (START_NS + 1, 'holding', {'cart': 0.3}) and msg.state == 'holding'
    cv.fill_stream_state(msg, START_NS + 2, True, 0.3, 0.0, 0.0, 0, 0.0, operator=True)
    assert cv.read_stream_state(msg)[1] == 'operator'
    # a sway feedback's correction: in the published position, not in the source's (the hold) read back
    cv.fill_stream_state(msg, START_NS + 3, False, 0.302, 0.0, 0.0, 0, 0.0, correction=(0.002,))
    back = deserialize_message(serialize_message(msg), StreamState)
    assert list(back.position) == [0.302] and list(back.correction) == [0.002]
    _, _, source, _, _, _, correction, _ = cv.read_stream_state(back)
    assert source == {'cart': pytest.approx(0.3, abs=1e-15)} and correction == {'cart': 0.002}
    # why the streamer itself stopped the motion (its runway guard), kept until it says otherwise
    cv.fill_stream_state(msg, START_NS + 4, False, 0.3, 0.0, 0.0, 0, 0.0, reason='the runway guard stopped it')
    back = deserialize_message(serialize_message(msg), StreamState)
    assert cv.read_stream_state(back)[7] == 'the runway guard stopped it'
    cv.fill_stream_state(msg, START_NS + 5, False, 0.3, 0.0, 0.0, 0, 0.0)
    assert cv.read_stream_state(msg)[7] == ''


def test_crane_state_fill_in_place_and_survive_serialization():
    from crane_interfaces.msg import CraneState
    msg = cv.crane_state_message('crane_a', 'runway')
    cv.fill_crane_state(msg, START_NS, 1.25, 0.3, 0.5, (0.49, 1.24), (0.48, 1.23), (1.1, 1.6), 'warning', 'crane_b')
    back = deserialize_message(serialize_message(msg), CraneState)
    assert (back.header.frame_id, back.crane, cv.stamp_ns(back.header.stamp)) == ('runway', 'crane_a', START_NS)
    assert (back.girder, back.girder_velocity, back.trolley) == (1.25, 0.3, 0.5)
    assert (back.hook_x, back.hook_y, back.load_x, back.load_y) == (0.49, 1.24, 0.48, 1.23)
    assert (back.reach_low, back.reach_high, back.guard, back.guard_crane) == (1.1, 1.6, 'warning', 'crane_b')


def test_joint_trajectory_round_trip():
    s = samples()
    msg = cv.samples_to_joint_trajectory(s, start_position=-0.2, start_ns=START_NS)
    msg = deserialize_message(serialize_message(msg), JointTrajectory)
    assert list(msg.joint_names) == ['cart'] and cv.stamp_ns(msg.header.stamp) == START_NS
    assert msg.points[-1].time_from_start.sec == 0 and msg.points[-1].time_from_start.nanosec == 60_000_000
    t, p, v, a = cv.joint_trajectory_to_arrays(msg)
    assert np.allclose(t, s.t, atol=1e-9)
    assert np.allclose(p, s.position - 0.2) and np.allclose(v, s.velocity) and np.allclose(a, s.acceleration)


def test_joint_trajectory_columns_hold_a_joint_left_out_where_told_and_refuse_it_otherwise():
    s = samples()
    msg = cv.samples_to_joint_trajectory(s, start_position=-0.2)
    t, p, v, a = cv.joint_trajectory_columns(msg, ('cart', 'hoist'), (None, 0.47))
    assert p.shape == v.shape == a.shape == (t.size, 2)
    assert np.allclose(p[:, 0], s.position - 0.2) and np.allclose(a[:, 0], s.acceleration)
    assert np.all(p[:, 1] == 0.47) and not v[:, 1].any() and not a[:, 1].any()  # the hoist held at rest
    with pytest.raises(ValueError, match='hoist'):
        cv.joint_trajectory_columns(msg, ('cart', 'hoist'))


def test_joint_trajectory_without_cart_or_accelerations_is_refused():
    msg = cv.samples_to_joint_trajectory(samples())
    msg.joint_names = ['x']
    with pytest.raises(ValueError, match='cart'):
        cv.joint_trajectory_to_arrays(msg)
    msg = cv.samples_to_joint_trajectory(samples())
    msg.points[2].accelerations = []
    with pytest.raises(ValueError, match='accelerations'):
        cv.joint_trajectory_to_arrays(msg)


@pytest.mark.parametrize('output, msg_type', [('joint_trajectory', JointTrajectory),
                                              ('float64_array', Float64MultiArray)])
def test_reference_fill_in_place_and_read_back(output, msg_type):
    msg = cv.reference_message(output)
    assert type(msg) is msg_type
    cv.fill_reference(msg, START_NS + 1_000_000, 0.25, 0.5, -1.0)
    msg = deserialize_message(serialize_message(msg), msg_type)
    stamp, p, v, a = cv.read_reference(msg)
    if output == 'joint_trajectory':
        assert (stamp, p, v, a) == (START_NS + 1_000_000, 0.25, 0.5, -1.0)
    else:
        assert stamp is None and p == 0.25 and math.isnan(v) and math.isnan(a)
    with pytest.raises(ParameterError, match="output must be one of joint_trajectory, float64_array, got 'csv'"):
        cv.reference_message('csv')


def test_reference_with_several_points_is_refused():
    msg = cv.samples_to_joint_trajectory(samples())
    with pytest.raises(ValueError, match='one point'):
        cv.read_reference(msg)


def test_joint_state_in_place_and_reordered():
    msg = cv.joint_state_message()
    assert list(msg.name) == ['cart', 'theta1', 'theta2']
    cv.fill_joint_state(msg, START_NS, [0.3, 0.01, -0.02], [0.0, 0.1, 0.2])
    msg = deserialize_message(serialize_message(msg), JointState)
    pos, vel = cv.joint_state_to_arrays(msg, ['theta2', 'cart'])
    assert pos.tolist() == [-0.02, 0.3] and vel.tolist() == [0.2, 0.0]
    with pytest.raises(ValueError, match='theta3'):
        cv.joint_state_to_arrays(msg, ['theta3'])


def test_stamps_in_nanoseconds():
    assert cv.stamp_ns(cv.time_msg(START_NS)) == START_NS
    d = cv.duration_msg(2_500_000_000)
    assert (d.sec, d.nanosec) == (2, 500_000_000)
    neg = cv.time_msg(-1)  # before the epoch: sec negative, nanosec in [0, 1e9)
    assert (neg.sec, neg.nanosec) == (-1, 999_999_999) and cv.stamp_ns(neg) == -1


def test_service_names():
    assert service_of('crane_planner', PLAN_MOVE_SERVICE) == 'crane_planner/plan_move'
    assert service_of('crane_planner', EXECUTE_MOVE_ACTION) == 'crane_planner/execute_move'
    with pytest.raises(ValueError):
        service_of('crane_planner', 'plan')


@pytest.mark.parametrize('output', ['joint_trajectory', 'float64_array'])
def test_a_reference_of_the_cart_and_the_hoist_carries_a_column_each_and_reads_back_by_name(output):
    from crane_msgs_py.messages.conversions import fill_reference, read_reference, reference_message
    msg = reference_message(output, joint=['cart', 'hoist'])
    fill_reference(msg, 5_000_000_123, (0.25, 0.4), (0.1, -0.05), (0.2, -0.3))
    wire = deserialize_message(serialize_message(msg), type(msg))
    stamp, p, v, a = read_reference(wire, ('cart', 'hoist'))
    assert list(p) == [0.25, 0.4]
    if output == 'float64_array':  # [cart, hoist] positions, as a forward command controller takes them
        assert list(wire.data) == [0.25, 0.4] and stamp is None and np.all(np.isnan(v))
    else:
        assert list(wire.joint_names) == ['cart', 'hoist'] and stamp == 5_000_000_123
        assert list(v) == [0.1, -0.05] and list(a) == [0.2, -0.3]
        assert list(read_reference(wire, ('hoist', 'cart'))[1]) == [0.4, 0.25]  # by name, not position
    with pytest.raises(ValueError, match='2 joint|2 position'):
        read_reference(reference_message(output), ('cart', 'hoist'))
