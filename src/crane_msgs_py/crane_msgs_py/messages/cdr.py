"""The streamer's one-sample references read straight from their serialized bytes (CDR), and written so.

At 1 kHz the simulator cannot afford rclpy's typed messages: taking one JointTrajectory as a
Python object costs several times what taking its bytes does (``bench/reference_take.py`` measures both).
So it subscribes raw and reads the few fields it needs here: the header stamp, the joint
names and the first point's positions, velocities and accelerations of a
``trajectory_msgs/JointTrajectory``, or the data of a ``std_msgs/Float64MultiArray``.

The bytes are what the RMW hands over: a 4-byte encapsulation header (``0x00 0x01``
little-endian, ``0x00 0x00`` big-endian plain CDR), then the fields in declaration order,
each primitive aligned to its size counted from the end of that header; a string is its
length (with the terminating NUL) and its bytes; a sequence its count and its elements (an
empty sequence of doubles adds no padding). Truncated or inconsistent bytes raise ValueError,
as a message of the wrong shape does in ``conversions.read_reference``. The streamer, for its part,
publishes bytes written in place into a template rclpy serialized (``ReferenceWriter``). Pure Python,
no ROS import; tested against rclpy's own serializer.
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
        """A builtin_interfaces Time or Duration (int32 sec, uint32 nanosec) as ns."""
        at = self.at + (-self.at & 3)
        if at + 8 > len(self.data):
            raise ValueError(f'CDR truncated: {len(self.data)} bytes, {at + 8} needed')
        sec, nanosec = _STAMP[self.order].unpack_from(self.data, at)
        self.at = at + 8
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

    def trajectory_head(self) -> tuple[int, tuple, int]:
        """A JointTrajectory's fields before its first point: (header stamp ns, joint names, point count)."""
        stamp = self.stamp()
        self.string()  # frame_id
        names = tuple(self.string() for _ in range(self.count(len(self.data) // 5)))
        return stamp, names, self.count(len(self.data) // 24)

    def array_layout(self) -> None:
        """Past a Float64MultiArray's layout, to its data."""
        for _ in range(self.count(len(self.data) // 12)):  # layout.dim: (label, size, stride) each
            self.string()
            self.u32()
            self.u32()
        self.u32()  # layout.data_offset


def read_joint_trajectory(data: bytes) -> ReferenceSample:
    """The stamp, joint names and first point of a serialized ``trajectory_msgs/JointTrajectory``."""
    r = _Reader(data)
    stamp, names, points = r.trajectory_head()
    if not points:
        return ReferenceSample(stamp, names, 0, ())
    return ReferenceSample(stamp, names, points, r.doubles(), r.doubles(), r.doubles())


def read_float64_array(data: bytes) -> ReferenceSample:
    """The data of a serialized ``std_msgs/Float64MultiArray`` as the positions of one sample."""
    r = _Reader(data)
    r.array_layout()
    return ReferenceSample(None, None, 1, r.doubles())


class ReferenceWriter:
    """A one-sample reference's bytes with each sample's values written in place, for the streamer's 1 kHz
    publishing (an rclpy message filled and serialized costs several times as much).

    ``template`` is a serialized reference as rclpy writes it (``serialize_message`` of
    ``conversions.reference_message``): a one-point JointTrajectory with positions, velocities and
    accelerations of one size (``trajectory``), or a Float64MultiArray (positions only). Its layout is kept;
    ``write`` puts the stamp and the values where the template has them. ValueError if the template is not
    one of these.
    """

    def __init__(self, template: bytes, trajectory: bool = True):
        r = _Reader(template)
        self._buffer = bytearray(template)
        if trajectory:
            self._stamp = (_STAMP[r.order], r.at)
            if r.trajectory_head()[2] != 1:
                raise ValueError('the template must have one point')
            self._blocks = [self._block(r) for _ in range(3)]
            if len({n for _, _, n in self._blocks}) != 1:
                raise ValueError("the template's point must have as many velocities and accelerations as positions")
            r.doubles()  # effort
            r.stamp()  # time_from_start, the last field
        else:
            r.array_layout()
            self._stamp, self._blocks = None, [self._block(r)]
        # up to the last field: rclpy's serialize_message gives 4 bytes more than the middleware sends, and a
        # strict reader (rosbags, recording what the streamer sent) refuses a message longer than its fields
        del self._buffer[r.at:]
        self.width = self._blocks[0][2]

    @staticmethod
    def _block(r: _Reader) -> tuple:
        """(its Struct, where its doubles start, how many) of the next sequence of doubles."""
        at, n = r.at, len(r.doubles())
        start = r.at - 8 * n
        return struct.Struct(f'{r.order}{n}d'), start if n else at, n

    def write(self, stamp_ns: int, position, velocity=(), acceleration=()) -> bytes:
        """The reference's bytes with this stamp (ns; ignored by an array) and values (floats for one joint,
        sequences of ``width`` for several; an array takes the positions only)."""
        buffer = self._buffer
        if self._stamp is not None:
            stamp, at = self._stamp
            stamp.pack_into(buffer, at, *divmod(stamp_ns, 1_000_000_000))
        for (pack, at, n), values in zip(self._blocks, (position, velocity, acceleration)):
            if n == 1 and not isinstance(values, (tuple, list)):
                pack.pack_into(buffer, at, values)
            else:
                pack.pack_into(buffer, at, *values)
        return bytes(buffer)
