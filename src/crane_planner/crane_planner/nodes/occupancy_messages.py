"""``crane_interfaces/Occupancy`` <-> ``runway.occupancy.Occupancy`` (contract "Cranes sharing a runway"), and the
other cranes' occupancies drawn as markers (``runway_markers``).

ROS only: the messages' fields to the record and back. An incoming message is checked field by field before it
becomes a record, and refused (``OccupancyRefused``, its reason naming the field) if its frame is not
``runway``, it names no crane, its arrays differ in length or are empty, its times do not start at 0 and
increase, a number is not finite, or a size is negative: the planner ignores it and counts it.
"""
from __future__ import annotations

import math

import numpy as np
from crane_interfaces.msg import Occupancy as OccupancyMsg
from geometry_msgs.msg import Point
from visualization_msgs.msg import Marker, MarkerArray

from crane_msgs_py.messages.conversions import set_stamp, stamp_ns
from crane_planner.runway.occupancy import RUNWAY_FRAME, Footprint, Occupancy, Shape

#: The per-sample arrays of the message, in its order.
ARRAYS = ('t', 'girder', 'hook_x', 'hook_y', 'load_x', 'load_y')


class OccupancyRefused(ValueError):
    """An incoming occupancy that cannot be used; the message says which field and why."""


def to_message(occupancy: Occupancy) -> OccupancyMsg:
    """``occupancy`` as published: stamped when it was first published, in ``runway``."""
    msg = OccupancyMsg()
    msg.header.frame_id = RUNWAY_FRAME
    set_stamp(msg.header.stamp, occupancy.published_ns)
    msg.crane = occupancy.crane
    set_stamp(msg.start, occupancy.start_ns)
    f = occupancy.footprint
    for name, values in zip(ARRAYS, (occupancy.t, f.girder, f.masses[:, 0, 0], f.masses[:, 0, 1],
                                     f.masses[:, 1, 0], f.masses[:, 1, 1])):
        setattr(msg, name, np.asarray(values, dtype=float).tolist())
    msg.girder_half_width = occupancy.shape.girder_half_width
    msg.load_half_size = occupancy.shape.load_half_size
    return msg


def from_message(msg: OccupancyMsg) -> Occupancy:
    """The record of a received occupancy; ``OccupancyRefused`` says why it cannot be used."""
    who = f'occupancy of {msg.crane!r}' if msg.crane else 'occupancy'
    if msg.header.frame_id != RUNWAY_FRAME:
        raise OccupancyRefused(f'{who}: header.frame_id {msg.header.frame_id!r} is not {RUNWAY_FRAME!r}')
    if not msg.crane:
        raise OccupancyRefused('occupancy: crane is empty (every crane has a name)')
    arrays = {name: np.asarray(getattr(msg, name), dtype=float) for name in ARRAYS}
    lengths = {name: len(values) for name, values in arrays.items()}
    if len(set(lengths.values())) != 1 or not lengths['t']:
        raise OccupancyRefused(f'{who}: its arrays must have one equal, non-zero length, got '
                               + ', '.join(f'{name} {n}' for name, n in lengths.items()))
    for name, values in arrays.items():
        if not np.all(np.isfinite(values)):
            raise OccupancyRefused(f'{who}: {name} has a value that is not finite')
    t = arrays['t']
    if t[0] != 0.0 or np.any(np.diff(t) <= 0.0):
        raise OccupancyRefused(f'{who}: t must start at 0 and increase, got {t[:4].tolist()}'
                               + ('...' if len(t) > 4 else ''))
    for name in ('girder_half_width', 'load_half_size'):
        value = getattr(msg, name)
        if not (math.isfinite(value) and value >= 0.0):
            raise OccupancyRefused(f'{who}: {name} must be a finite distance >= 0 (m), got {value}')
    masses = np.stack([np.stack([arrays['hook_x'], arrays['hook_y']], axis=-1),
                       np.stack([arrays['load_x'], arrays['load_y']], axis=-1)], axis=1)
    return Occupancy(msg.crane, stamp_ns(msg.header.stamp), stamp_ns(msg.start), t,
                     Footprint(arrays['girder'], masses), Shape(msg.girder_half_width, msg.load_half_size))


#: How often (s) the planner draws the other cranes (``runway_markers``), and how long each drawing lasts (s): a
#: crane no longer heard disappears by itself.
MARKERS_PERIOD, MARKERS_LIFETIME = 0.2, 0.5
#: The girder as drawn: its length along x (m), about the runway's x = 0 (a bridge spans the runway).
GIRDER_DRAWN = 4.0


def runway_markers(others, now_ns: int, offset, frame_id: str, lifetime: float = MARKERS_LIFETIME) -> MarkerArray:
    """The other cranes' occupancies (``runway.occupancy.Occupancy``) as markers in this crane's ``frame_id``
    (``offset``: where its origin lies in ``runway``), seen from above at z = 0 (an occupancy has no heights), one
    namespace ``runway/<crane>`` each: where each stands at ``now_ns`` (its girder as a translucent box as wide as
    its ``girder_half_width``, both masses as discs of ``load_half_size``) and the path its load takes from
    there to the end of its occupancy (a line strip: a claimed motion; nothing for a hold)."""
    dx, dy = offset
    msg = MarkerArray()
    for other in sorted(others, key=lambda o: o.crane):
        here = other.at(np.array([now_ns]))
        shape = other.shape

        def marker(marker_id, kind, rgba):
            m = Marker()
            m.header.frame_id = frame_id
            set_stamp(m.header.stamp, now_ns)
            m.ns, m.id, m.type, m.action = f'runway/{other.crane}', marker_id, kind, Marker.ADD
            m.pose.orientation.w = 1.0
            m.color.r, m.color.g, m.color.b, m.color.a = rgba
            m.lifetime.sec, m.lifetime.nanosec = int(lifetime), round((lifetime % 1.0) * 1e9)
            msg.markers.append(m)
            return m

        girder = marker(0, Marker.CUBE, (0.9, 0.5, 0.1, 0.35))
        girder.pose.position.x, girder.pose.position.y = -dx, float(here.girder[0]) - dy
        girder.scale.x, girder.scale.y, girder.scale.z = GIRDER_DRAWN, max(2 * shape.girder_half_width, 1e-3), 0.01
        for k in range(2):
            disc = marker(1 + k, Marker.CYLINDER, (0.9, 0.2, 0.1, 0.5))
            x, y = here.masses[0, k]
            disc.pose.position.x, disc.pose.position.y = float(x) - dx, float(y) - dy
            disc.scale.x = disc.scale.y = max(2 * shape.load_half_size, 1e-3)
            disc.scale.z = 0.01
        ahead = (other.start_ns + np.round(np.asarray(other.t) * 1e9)).astype(np.int64) > now_ns
        if np.any(ahead):
            path = marker(3, Marker.LINE_STRIP, (0.9, 0.2, 0.1, 0.8))
            path.scale.x = 0.01
            points = [here.masses[0, 1]] + list(other.footprint.masses[ahead, 1])
            path.points = [Point(x=float(x) - dx, y=float(y) - dy, z=0.0) for x, y in points]
    return msg
