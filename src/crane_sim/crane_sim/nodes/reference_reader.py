"""The simulator's ``reference`` subscription, read by its stepping loop, not by an executor.

An axis controller reads its setpoint once a cycle from what the fieldbus received; so does the
simulator's loop: each step it takes every reference the middleware has received since the last
one. Handing 1 kHz messages through an executor's callbacks cost the simulator a large part of a
core on its own; taking their bytes (``raw``) and reading the few fields the loop needs
(``crane_msgs_py.messages.cdr``) costs a small fraction of that (``bench/reference_take.py``), and the
middleware's own threads keep receiving while the Python process stalls. Each message's receive
time is the middleware's.

The subscription belongs to a hidden node of its own (``_<sim node>_reference``, hidden as
tf2's listener nodes are), which no executor spins: an executor would take the messages first.
Global remappings (``-r reference:=...``) reach it; the topic is the sim's ``reference`` in its
namespace.
"""
from __future__ import annotations

from rclpy.node import Node
from std_msgs.msg import Float64MultiArray
from trajectory_msgs.msg import JointTrajectory

from crane_msgs_py.messages.cdr import ReferenceSample, read_float64_array, read_joint_trajectory
from crane_msgs_py.messages.names import OUTPUT_FLOAT64_ARRAY, OUTPUT_JOINT_TRAJECTORY, REFERENCE_TOPIC
from crane_msgs_py.runtime.taking import take_all

#: ``reference_type`` values: the streamer's two outputs, their message types and readers.
REFERENCE_TYPES = {OUTPUT_JOINT_TRAJECTORY: JointTrajectory, OUTPUT_FLOAT64_ARRAY: Float64MultiArray}
_READERS = {OUTPUT_JOINT_TRAJECTORY: read_joint_trajectory, OUTPUT_FLOAT64_ARRAY: read_float64_array}


class ReferenceReader:
    """The references of one type on ``node``'s ``reference`` topic, taken by ``take`` (one thread)."""

    def __init__(self, node: Node, kind: str, qos):
        self._node = Node(f'_{node.get_name()}_reference', namespace=node.get_namespace(), context=node.context,
                          start_parameter_services=False, enable_rosout=False)
        self._read = _READERS[kind]
        self._subscription = self._node.create_subscription(REFERENCE_TYPES[kind], REFERENCE_TOPIC,
                                                            self._never_called, qos, raw=True)

    @staticmethod
    def _never_called(_):
        raise AssertionError('the reference subscription is taken from by ReferenceReader.take, never spun')

    def take(self, now_ns: int) -> list[tuple[int, ReferenceSample | None]]:
        """Every reference received since the last call, oldest first: (receive time, ns of ROS time; its
        content, or None if its bytes are not one). ``now_ns`` stands in for a receive time the middleware
        does not give."""
        read, taken = self._read, []
        for data, info in take_all(self._subscription):
            try:
                sample = read(data)
            except ValueError:
                sample = None
            taken.append((info.get('received_timestamp') or now_ns, sample))
        return taken

    def destroy(self) -> None:
        self._node.destroy_node()
