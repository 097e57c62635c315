"""The CDR reader against rclpy's own serializer (the RMW's bytes): every field it reads, any lengths."""
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from rclpy.serialization import serialize_message
from std_msgs.msg import Float64MultiArray, MultiArrayDimension
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from crane_msgs_py.messages.cdr import read_float64_array, read_joint_trajectory

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


@pytest.mark.parametrize('joints', [('cart',), ('cart', 'hoist'), ('cart', 'bridge', 'hoist')])
@pytest.mark.parametrize('output', ['joint_trajectory', 'float64_array'])
def test_the_writer_s_bytes_are_what_rclpy_serializes_of_the_filled_message(output, joints):
    """The streamer's reference bytes written in place are, to rclpy, the message it fills with the same sample
    (compared as messages: rclpy leaves its padding bytes uninitialized)."""
    from rclpy.serialization import deserialize_message
    from rosbags.typesys import Stores, get_typestore

    from crane_msgs_py.messages.cdr import ReferenceWriter
    from crane_msgs_py.messages.conversions import fill_reference, reference_message
    typestore = get_typestore(Stores.ROS2_JAZZY)
    type_name = 'std_msgs/msg/Float64MultiArray' if output == 'float64_array' else 'trajectory_msgs/msg/JointTrajectory'
    msg = reference_message(output, joint=list(joints))
    writer = ReferenceWriter(serialize_message(msg), trajectory=output == 'joint_trajectory')
    assert writer.width == len(joints)
    rng = np.random.default_rng(3)
    for stamp in (1, 1_795_756_847_724_352_513, 2**31 * 1_000_000_000 - 1):
        values = [tuple(float(x) for x in rng.normal(size=len(joints))) for _ in range(3)]
        if len(joints) == 1:
            values = [v[0] for v in values]
        fill_reference(msg, stamp, *values)
        data = writer.write(stamp, *values)
        assert deserialize_message(data, type(msg)) == msg
        # to the byte, what rosbags (the recordings' reader, strict about the length) reads as the same sample
        read = typestore.deserialize_cdr(data, type_name)
        assert tuple(read.data if output == 'float64_array' else read.points[0].positions) == \
            pytest.approx(values[0] if len(joints) > 1 else (values[0],))


def test_the_writer_refuses_a_template_of_another_shape():
    from crane_msgs_py.messages.cdr import ReferenceWriter
    two_points = JointTrajectory(joint_names=['cart'], points=[point([1.0], [0.0], [0.0])] * 2)
    with pytest.raises(ValueError, match='one point'):
        ReferenceWriter(serialize_message(two_points))
    uneven = JointTrajectory(joint_names=['cart'], points=[point([1.0], [], [0.0])])
    with pytest.raises(ValueError, match='as many velocities'):
        ReferenceWriter(serialize_message(uneven))
