"""The streamer's one-sample references read straight from their serialized bytes (CDR).

At 1 kHz the simulator cannot afford rclpy's typed messages: taking one JointTrajectory as a
Python object costs about ten times what taking its bytes does (``bench/reference_take.py``).
So it subscribes raw and reads the few fields it needs here: the header stamp, the joint
names and the first point's positions, velocities and accelerations of a
``trajectory_msgs/JointTrajectory``, or the data of a ``std_msgs/Float64MultiArray``.

The bytes are what the RMW hands over: a 4-byte encapsulation header (``0x00 0x01``
little-endian, ``0x00 0x00`` big-endian plain CDR), then the fields in declaration order,
each primitive aligned to its size counted from the end of that header; a string is its
length (with the terminating NUL) and its bytes; a sequence its count and its elements (an
empty sequence of doubles adds no padding). Truncated or inconsistent bytes raise ValueError,
as a message of the wrong shape does in ``conversions.read_reference``. Pure Python, no ROS
import; tested against rclpy's own serializer.
"""
from __future__ import annotations

import struct
from dataclasses import dataclass

_ENCAPSULATIONS = {b'\x00\x01': '<', b'\x00\x00': '>'}
_HEADER = 4  # bytes of the encapsulation header, before the aligned payload
_U32 = {order: struct.Struct(order + 'I') for order in '<>'}
_STAMP = {order: struct.Struct(order + 'iI') for order in '<>'}
_DOUBLES: dict = {}  # (byte order, count) -> its Struct's unpack_from


@dataclass(slots=True)
class ReferenceSample:
    """What a reference message says: its stamp (ns; None for a Float64MultiArray, which has none), joint
    names (None for a Float64MultiArray), how many points it has (1 for an array), and the first point's
    positions, velocities and accelerations (m, m/s, m/s^2; empty where the message has none)."""

    stamp_ns: int | None
    joint_names: tuple | None
    points: int
    positions: tuple
    velocities: tuple = ()
    accelerations: tuple = ()


class _Reader:
    """A cursor over one CDR payload (written for speed: the simulator reads 1,000 a second)."""

    __slots__ = ('data', 'order', 'at', '_u32')

    def __init__(self, data: bytes):
        order = _ENCAPSULATIONS.get(data[:2]) if len(data) >= _HEADER else None
        if order is None:
            raise ValueError(f'not plain CDR: encapsulation {bytes(data[:2]).hex() or "missing"}')
        self.data, self.order, self.at, self._u32 = data, order, _HEADER, _U32[order]

    def u32(self) -> int:
        at = self.at + (-self.at & 3)  # aligned to 4 from the payload's start, which is itself aligned to 4
        if at + 4 > len(self.data):
            raise ValueError(f'CDR truncated: {len(self.data)} bytes, {at + 4} needed')
        self.at = at + 4
        return self._u32.unpack_from(self.data, at)[0]

    def stamp(self) -> int:
        if self.at + 8 > len(self.data):
            raise ValueError(f'CDR truncated: {len(self.data)} bytes, {self.at + 8} needed')
        sec, nanosec = _STAMP[self.order].unpack_from(self.data, self.at)
        self.at += 8
        return sec * 1_000_000_000 + nanosec

    def count(self, limit: int) -> int:
        """A sequence's length, refused beyond ``limit`` elements (a corrupt count would allocate)."""
        n = self.u32()
        if n > limit:
            raise ValueError(f'CDR sequence of {n} elements: more than the {limit} expected at most')
        return n

    def string(self) -> str:
        n = self.u32()
        at, data = self.at, self.data
        if n == 0 or at + n > len(data) or data[at + n - 1] != 0:
            raise ValueError('CDR string not terminated')
        self.at = at + n
        return bytes(data[at:at + n - 1]).decode()

    def doubles(self) -> tuple:
        n = self.count(len(self.data) // 8)
        if not n:
            return ()
        at = self.at + (-(self.at - _HEADER) & 7)  # doubles align to 8 from the payload's start
        if at + 8 * n > len(self.data):
            raise ValueError(f'CDR truncated: {len(self.data)} bytes, {at + 8 * n} needed')
        unpack = _DOUBLES.get((self.order, n))
        if unpack is None:
            unpack = _DOUBLES.setdefault((self.order, n), struct.Struct(f'{self.order}{n}d').unpack_from)
        self.at = at + 8 * n
        return unpack(self.data, at)


def read_joint_trajectory(data: bytes) -> ReferenceSample:
    """The stamp, joint names and first point of a serialized ``trajectory_msgs/JointTrajectory``."""
    r = _Reader(data)
    stamp = r.stamp()
    r.string()  # frame_id
    names = tuple(r.string() for _ in range(r.count(len(data) // 5)))
    points = r.count(len(data) // 24)
    if not points:
        return ReferenceSample(stamp, names, 0, ())
    return ReferenceSample(stamp, names, points, r.doubles(), r.doubles(), r.doubles())


def read_float64_array(data: bytes) -> ReferenceSample:
    """The data of a serialized ``std_msgs/Float64MultiArray`` as the positions of one sample."""
    r = _Reader(data)
    for _ in range(r.count(len(data) // 12)):  # layout.dim: (label, size, stride) each
        r.string()
        r.u32()
        r.u32()
    r.u32()  # layout.data_offset
    return ReferenceSample(None, None, 1, r.doubles())
