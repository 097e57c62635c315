"""Plans and states <-> standard messages (crane_msgs_py.conversions, names)."""
import math
from types import SimpleNamespace

import numpy as np
import pytest
from nav_msgs.msg import Path
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from trajectory_msgs.msg import JointTrajectory

from crane_msgs_py import conversions as cv
from crane_msgs_py.names import plan_service, service_of
from crane_msgs_py.params import ParameterError

START_NS = 1_700_000_000 * 10**9 + 999_000_000  # nanoseconds that carry into the seconds


def samples(n=7, T=0.06):
    t = np.append(np.arange(n - 1) * (T / (n - 1)), T)
    return SimpleNamespace(t=t, position=0.1 * t**2, velocity=0.2 * t, acceleration=np.full(n, 0.2))


def test_path_knots_carry_start_plus_time_and_start_plus_position():
    s = samples()
    path = cv.samples_to_path(s, start_position=1.5, start_ns=START_NS, frame_id='crane_base')
    path = deserialize_message(serialize_message(path), Path)
    assert path.header.frame_id == 'crane_base'
    assert (path.header.stamp.sec, path.header.stamp.nanosec) == (1_700_000_000, 999_000_000)
    assert len(path.poses) == len(s.t)
    second = path.poses[1]  # t = 10 ms: the stamp carries into the next second
    assert (second.header.stamp.sec, second.header.stamp.nanosec) == (1_700_000_001, 9_000_000)
    assert second.header.frame_id == 'crane_base'
    assert second.pose.position.x == pytest.approx(1.5 + 0.1 * 0.01**2, abs=1e-15)
    q = second.pose.orientation
    assert (q.x, q.y, q.z, q.w) == (0.0, 0.0, 0.0, 1.0)
    t, x = cv.path_to_arrays(path)
    assert np.allclose(t, s.t, atol=1e-9) and t[-1] == pytest.approx(0.06, abs=1e-9)
    assert np.allclose(x, 1.5 + s.position, atol=1e-15)


def test_relative_plan_has_zero_start_stamp():
    path = cv.samples_to_path(samples(), start_ns=0)
    assert path.header.stamp.sec == 0 and path.header.stamp.nanosec == 0
    assert path.poses[-1].header.stamp.nanosec == 60_000_000


def test_joint_trajectory_round_trip():
    s = samples()
    msg = cv.samples_to_joint_trajectory(s, start_position=-0.2, start_ns=START_NS)
    msg = deserialize_message(serialize_message(msg), JointTrajectory)
    assert list(msg.joint_names) == ['cart'] and cv.stamp_ns(msg.header.stamp) == START_NS
    assert msg.points[-1].time_from_start.sec == 0 and msg.points[-1].time_from_start.nanosec == 60_000_000
    t, p, v, a = cv.joint_trajectory_to_arrays(msg)
    assert np.allclose(t, s.t, atol=1e-9)
    assert np.allclose(p, s.position - 0.2) and np.allclose(v, s.velocity) and np.allclose(a, s.acceleration)


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
    assert plan_service() == '~/plan' and plan_service('zv') == '~/plan/zv'
    assert service_of('crane_planner', plan_service('rvf')) == 'crane_planner/plan/rvf'
    with pytest.raises(ValueError):
        service_of('crane_planner', 'plan')
