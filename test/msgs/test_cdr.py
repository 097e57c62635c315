"""The CDR reader against rclpy's own serializer (the RMW's bytes): every field it reads, any lengths."""
import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from rclpy.serialization import serialize_message
from std_msgs.msg import Float64MultiArray, MultiArrayDimension
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from crane_msgs_py.cdr import read_float64_array, read_joint_trajectory

names = st.text(st.characters(codec='utf-8', exclude_characters='\x00'), max_size=9)
doubles = st.lists(st.floats(allow_nan=False), max_size=4)


def point(positions, velocities, accelerations, effort=(), sec=0):
    p = JointTrajectoryPoint(positions=positions, velocities=velocities, accelerations=accelerations,
                             effort=list(effort))
    p.time_from_start.sec = sec
    return p


@settings(max_examples=200, deadline=None)
@given(sec=st.integers(-2**31, 2**31 - 1), nanosec=st.integers(0, 999_999_999), frame_id=names,
       joints=st.lists(names, max_size=4), first=st.tuples(doubles, doubles, doubles, doubles),
       more=st.integers(0, 2))
def test_a_joint_trajectory_reads_as_rclpy_wrote_it(sec, nanosec, frame_id, joints, first, more):
    msg = JointTrajectory(joint_names=joints)
    msg.header.stamp.sec, msg.header.stamp.nanosec, msg.header.frame_id = sec, nanosec, frame_id
    msg.points = [point(*first)] + [point([1.0], [], [2.0], sec=k) for k in range(more)]
    sample = read_joint_trajectory(serialize_message(msg))
    assert sample.stamp_ns == sec * 1_000_000_000 + nanosec
    assert sample.joint_names == tuple(joints)
    assert sample.points == 1 + more
    assert (sample.positions, sample.velocities, sample.accelerations) == tuple(tuple(x) for x in first[:3])


def test_a_trajectory_without_points_reads_with_none():
    msg = JointTrajectory(joint_names=['cart'])
    sample = read_joint_trajectory(serialize_message(msg))
    assert (sample.points, sample.positions, sample.joint_names) == (0, (), ('cart',))


@settings(max_examples=100, deadline=None)
@given(data=doubles, dims=st.lists(st.tuples(names, st.integers(0, 2**32 - 1), st.integers(0, 2**32 - 1)),
                                   max_size=3), offset=st.integers(0, 2**32 - 1))
def test_a_float64_array_reads_its_data_past_any_layout(data, dims, offset):
    msg = Float64MultiArray(data=data)
    msg.layout.dim = [MultiArrayDimension(label=label, size=size, stride=stride) for label, size, stride in dims]
    msg.layout.data_offset = offset
    sample = read_float64_array(serialize_message(msg))
    assert sample.positions == tuple(data) and sample.stamp_ns is None and sample.points == 1


def test_special_values_survive():
    msg = JointTrajectory(joint_names=['cart'], points=[point([math.inf], [-0.0], [math.nan])])
    sample = read_joint_trajectory(serialize_message(msg))
    assert sample.positions == (math.inf,) and math.copysign(1.0, sample.velocities[0]) == -1.0
    assert math.isnan(sample.accelerations[0])


@pytest.mark.parametrize('cut', [0, 3, 4, 10, 30, 60])
def test_truncated_or_foreign_bytes_are_refused_naming_why(cut):
    msg = JointTrajectory(joint_names=['cart'], points=[point([1.0], [2.0], [3.0])])
    data = serialize_message(msg)
    with pytest.raises(ValueError, match='CDR|encapsulation'):
        read_joint_trajectory(data[:cut])
    with pytest.raises(ValueError, match='encapsulation'):
        read_joint_trajectory(b'\x00\x07' + data[2:])


def test_a_corrupt_count_is_refused_before_anything_is_allocated():
    data = bytearray(serialize_message(JointTrajectory(joint_names=['cart'])))
    data[20:24] = (2**32 - 1).to_bytes(4, 'little')  # joint_names' count (after the header's stamp and frame_id)
    with pytest.raises(ValueError, match='more than'):
        read_joint_trajectory(bytes(data))
