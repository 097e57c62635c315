"""Plans and states <-> standard ROS messages, the contract's conventions as code.

- A plan's samples (any object with arrays ``t``, ``position``, ``velocity``,
  ``acceleration``, like ``crane_planner.planning.plan.Samples``; plans are relative,
  from 0 at t = 0) become a ``trajectory_msgs/JointTrajectory`` (joint
  ``cart``, positions/velocities/accelerations, ``time_from_start`` = t_k,
  header stamp = start stamp).
- A ``crane_interfaces/Move`` is built from plain values (``move_message``).
- The streamer's ``crane_interfaces/StreamState`` is filled in place and read back.
- The streamer's one-sample ``reference`` (a one-point JointTrajectory or a
  ``Float64MultiArray`` [position]) is filled in place and read back here.
- ``sensor_msgs/JointState`` <-> arrays in a given joint order.

Times are integer nanoseconds (as ``rclpy.time.Time.nanoseconds``) so that
stamps never lose precision. rclpy converts every pose and point to a Python
object, so builders pre-size their lists, do the arithmetic on whole numpy
arrays and touch each element once; sequence fields take array.array/numpy
directly.
"""
from __future__ import annotations

import array
import math

import numpy as np
from builtin_interfaces.msg import Duration, Time
from crane_interfaces.msg import CraneState, Move, StreamState
from geometry_msgs.msg import Point
from rclpy.serialization import serialize_message
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint
from visualization_msgs.msg import Marker, MarkerArray

from crane_msgs_py.crane.params import check_choice
from crane_msgs_py.messages.cdr import ReferenceSample, ReferenceWriter
from crane_msgs_py.messages.names import (
    CART_JOINT,
    DEFAULT_FRAME_ID,
    OUTPUT_FLOAT64_ARRAY,
    OUTPUT_JOINT_TRAJECTORY,
    OUTPUTS,
    SIM_JOINTS,
)

NS = 1_000_000_000


def stamp_ns(stamp) -> int:
    """``builtin_interfaces/Time`` or ``Duration`` as integer nanoseconds."""
    return stamp.sec * NS + stamp.nanosec


def set_stamp(stamp, ns: int):
    """Write ``ns`` into an existing Time/Duration message (sec, nanosec >= 0); return it."""
    sec, nanosec = divmod(int(ns), NS)
    stamp.sec = sec
    stamp.nanosec = nanosec
    return stamp


def time_msg(ns: int) -> Time:
    return set_stamp(Time(), ns)


def duration_msg(ns: int) -> Duration:
    return set_stamp(Duration(), ns)


def _offsets_ns(t) -> np.ndarray:
    """Sample times (s) as integer nanosecond offsets, rounded."""
    return np.rint(np.asarray(t, dtype=float) * NS).astype(np.int64)


def samples_to_joint_trajectory(samples, start_position: float = 0.0, start_ns: int = 0,
                                frame_id: str = DEFAULT_FRAME_ID,
                                joint: str = CART_JOINT) -> JointTrajectory:
    """One-joint trajectory of a relative plan started at ``start_position`` at ``start_ns``.

    Several joints: ``samples``, ``start_position`` and ``joint`` are sequences
    of the same length (the samples at the same times).
    """
    several = isinstance(joint, (list, tuple))
    samples_list = list(samples) if several else [samples]
    starts = list(start_position) if several else [start_position]
    offsets = _offsets_ns(samples_list[0].t)
    secs, nsecs = np.divmod(offsets, NS)
    secs, nsecs = secs.tolist(), nsecs.tolist()
    p = np.column_stack([s0 + np.asarray(s.position, dtype=float) for s, s0 in zip(samples_list, starts)]).tolist()
    v = np.column_stack([np.asarray(s.velocity, dtype=float) for s in samples_list]).tolist()
    a = np.column_stack([np.asarray(s.acceleration, dtype=float) for s in samples_list]).tolist()
    points = [None] * len(p)
    for k in range(len(p)):
        point = JointTrajectoryPoint()
        point.positions = array.array('d', p[k])
        point.velocities = array.array('d', v[k])
        point.accelerations = array.array('d', a[k])
        point.time_from_start.sec = secs[k]
        point.time_from_start.nanosec = nsecs[k]
        points[k] = point
    msg = JointTrajectory()
    msg.header.frame_id = frame_id
    set_stamp(msg.header.stamp, start_ns)
    msg.joint_names = list(joint) if several else [joint]
    msg.points = points
    return msg


def joint_trajectory_to_arrays(msg: JointTrajectory, joint: str = CART_JOINT):
    """(t, position, velocity, acceleration) of ``joint``; t = time_from_start (s).

    Raises ValueError naming what is missing: the joint, or velocities and
    accelerations (needed for quintic Hermite interpolation).
    """
    try:
        j = list(msg.joint_names).index(joint)
    except ValueError:
        raise ValueError(f'trajectory has no joint {joint!r} (joints: {list(msg.joint_names)})') from None
    n = len(msg.points)
    t = np.empty(n)
    p, v, a = np.empty(n), np.empty(n), np.empty(n)
    width = len(msg.joint_names)
    for k, point in enumerate(msg.points):
        if len(point.positions) != width:
            raise ValueError(f'point {k} has {len(point.positions)} positions for {width} joints')
        if len(point.velocities) != width or len(point.accelerations) != width:
            raise ValueError(f'point {k} lacks velocities or accelerations')
        t[k] = stamp_ns(point.time_from_start) * 1e-9
        p[k] = point.positions[j]
        v[k] = point.velocities[j]
        a[k] = point.accelerations[j]
    return t, p, v, a


def joint_trajectory_columns(msg: JointTrajectory, joints, holds=None):
    """(t, position, velocity, acceleration) of ``joints``, a column each: (points, joints) arrays. A joint
    the trajectory leaves out holds at rest at its entry of ``holds`` if that is not None, else ValueError
    names it (``joint_trajectory_to_arrays``)."""
    t = joint_trajectory_to_arrays(msg, joints[0])[0]
    columns = []
    for joint, hold in zip(joints, holds or [None] * len(joints)):
        if hold is None or joint in msg.joint_names:
            columns.append(joint_trajectory_to_arrays(msg, joint)[1:])
        else:
            columns.append((np.full(t.size, float(hold)), np.zeros(t.size), np.zeros(t.size)))
    return (t, *(np.column_stack(c) for c in zip(*columns)))


def reference_message(output: str = OUTPUT_JOINT_TRAJECTORY, frame_id: str = DEFAULT_FRAME_ID,
                      joint=CART_JOINT):
    """A reusable one-sample reference message of the streamer's ``output`` type, for ``joint`` (a name, or a
    sequence of them: one column each, e.g. [cart, hoist]).

    Raises ParameterError naming ``output`` if it is not one of ``OUTPUTS``.
    """
    joints = list(joint) if isinstance(joint, (list, tuple)) else [joint]
    zeros = (0.0,) * len(joints)
    if check_choice('output', output, OUTPUTS) == OUTPUT_FLOAT64_ARRAY:
        msg = Float64MultiArray()
        msg.data = array.array('d', zeros)
        return msg
    msg = JointTrajectory()
    msg.header.frame_id = frame_id
    msg.joint_names = joints
    point = JointTrajectoryPoint()
    point.positions = array.array('d', zeros)
    point.velocities = array.array('d', zeros)
    point.accelerations = array.array('d', zeros)
    msg.points = [point]
    return msg


def reference_writer(msg) -> ReferenceWriter:
    """The bytes of a message from ``reference_message`` written in place for each sample (``cdr.ReferenceWriter``:
    what the streamer publishes at 1 kHz, a fraction of the cost of filling and serializing the message)."""
    return ReferenceWriter(serialize_message(msg), trajectory=type(msg) is JointTrajectory)


def fill_reference(msg, stamp: int, position, velocity, acceleration):
    """Write one sample into a message from ``reference_message`` in place (no allocation).

    Floats for one joint, tuples (one value per joint) for several. A
    Float64MultiArray carries the positions only (a forward command
    controller's input).
    """
    if type(msg) is JointTrajectory:
        s = msg.header.stamp
        s.sec, s.nanosec = divmod(stamp, NS)
        point = msg.points[0]
        if type(position) is tuple:
            point.positions[:] = array.array('d', position)
            point.velocities[:] = array.array('d', velocity)
            point.accelerations[:] = array.array('d', acceleration)
        else:
            point.positions[0] = position
            point.velocities[0] = velocity
            point.accelerations[0] = acceleration
    elif type(position) is tuple:
        msg.data[:] = array.array('d', position)
    else:
        msg.data[0] = position


def reference_sample(msg) -> ReferenceSample:
    """What a typed reference message (a JointTrajectory or a Float64MultiArray) says, as ``cdr`` reads it
    from the message's bytes."""
    if type(msg) is JointTrajectory:
        first = msg.points[0] if msg.points else None
        columns = (tuple(first.positions), tuple(first.velocities), tuple(first.accelerations)) if first else ()
        return ReferenceSample(stamp_ns(msg.header.stamp), tuple(msg.joint_names), len(msg.points), *columns)
    return ReferenceSample(None, None, 1, tuple(msg.data))


def read_reference(msg, joints=None) -> tuple:
    """(stamp ns or None, position, velocity, acceleration) of a reference message.

    ``msg`` is a JointTrajectory, a Float64MultiArray, or what ``cdr`` read
    from the bytes of one (a ``ReferenceSample``).
    With ``joints`` None: one joint, floats. With ``joints`` (names, e.g.
    [cart, hoist]): arrays in that order; a JointTrajectory is matched by its
    joint names, a Float64MultiArray must hold one position per joint.
    A Float64MultiArray has no stamp, velocity or acceleration: None, NaN, NaN.
    A message that is not one sample of these joints raises ValueError.
    """
    sample = msg if isinstance(msg, ReferenceSample) else reference_sample(msg)
    width = 1 if joints is None else len(joints)
    if sample.joint_names is not None:  # a JointTrajectory
        if sample.points != 1 or len(sample.joint_names) != width:
            raise ValueError(f'reference must be one point of {width} joint(s), got {sample.points} '
                             f'point(s) of {len(sample.joint_names)} joint(s)')
        if len(sample.positions) != width:
            raise ValueError('reference point has no position per joint')
        v = sample.velocities if len(sample.velocities) == width else (math.nan,) * width
        a = sample.accelerations if len(sample.accelerations) == width else (math.nan,) * width
        if joints is None:
            return sample.stamp_ns, sample.positions[0], v[0], a[0]
        names = list(sample.joint_names)
        if sorted(names) != sorted(joints):
            raise ValueError(f'reference joints {names} are not {list(joints)}')
        order = [names.index(j) for j in joints]
        return (sample.stamp_ns, *(np.asarray(x, dtype=float)[order] for x in (sample.positions, v, a)))
    if len(sample.positions) != width:
        raise ValueError(f'reference array must hold {width} position(s), got {len(sample.positions)} values')
    if joints is None:
        return None, sample.positions[0], math.nan, math.nan
    return None, np.asarray(sample.positions, dtype=float), np.full(width, math.nan), np.full(width, math.nan)


def joint_state_message(names=None) -> JointState:
    """A reusable JointState with position and velocity pre-sized for ``names``."""
    names = list(names or SIM_JOINTS)
    msg = JointState()
    msg.name = names
    msg.position = array.array('d', bytes(8 * len(names)))
    msg.velocity = array.array('d', bytes(8 * len(names)))
    return msg


def fill_joint_state(msg: JointState, stamp: int, position, velocity):
    """Write stamp, positions and velocities (sequences in ``msg.name`` order) in place."""
    s = msg.header.stamp
    s.sec, s.nanosec = divmod(stamp, NS)
    pos, vel = msg.position, msg.velocity
    for k in range(len(pos)):
        pos[k] = position[k]
        vel[k] = velocity[k]


def joint_state_to_arrays(msg: JointState, names) -> tuple[np.ndarray, np.ndarray]:
    """(position, velocity) ordered as ``names``; ValueError names a missing joint.

    A state without velocities gives NaN velocities.
    """
    index = {name: k for k, name in enumerate(msg.name)}
    missing = [n for n in names if n not in index]
    if missing:
        raise ValueError(f'joint state lacks joint(s) {", ".join(missing)}')
    order = [index[n] for n in names]
    pos = np.asarray(msg.position, dtype=float)[order]
    vel = (np.asarray(msg.velocity, dtype=float)[order] if len(msg.velocity) == len(msg.name)
           else np.full(len(order), math.nan))
    return pos, vel


#: Marker ids of ``crane_markers``: the cart, the two cables (one strip), the two masses.
CART_MARKER, CABLES_MARKER, MASS1_MARKER, MASS2_MARKER, BRIDGE_MARKER = range(5)
#: Length (m) of the bridge's girder as drawn, along x (the trolley's rail).
BRIDGE_SPAN = 2.0


def crane_markers_message(frame_id: str = DEFAULT_FRAME_ID, bridge: bool = False) -> MarkerArray:
    """A reusable MarkerArray drawing the crane in ``frame_id`` (x along the rail, y along the runway, z up):
    a cart (the trolley, a cube), the cables (one line strip suspension point - m1 - m2), the masses (spheres)
    and with ``bridge`` the bridge's girder (a long box along x through the trolley); fill with
    ``fill_crane_markers``."""
    shapes = [(CART_MARKER, Marker.CUBE, (0.10, 0.06, 0.04), (0.3, 0.3, 0.35)),
              (CABLES_MARKER, Marker.LINE_STRIP, (0.006, 0.0, 0.0), (0.1, 0.1, 0.1)),
              (MASS1_MARKER, Marker.SPHERE, (0.04, 0.04, 0.04), (0.2, 0.45, 0.8)),
              (MASS2_MARKER, Marker.SPHERE, (0.05, 0.05, 0.05), (0.85, 0.35, 0.1))]
    if bridge:
        shapes.append((BRIDGE_MARKER, Marker.CUBE, (BRIDGE_SPAN, 0.04, 0.03), (0.9, 0.7, 0.1)))
    msg = MarkerArray()
    for marker_id, kind, (sx, sy, sz), (r, g, b) in shapes:
        m = Marker()
        m.header.frame_id = frame_id
        m.ns, m.id, m.type, m.action = 'crane', marker_id, kind, Marker.ADD
        m.scale.x, m.scale.y, m.scale.z = sx, sy, sz
        m.color.r, m.color.g, m.color.b, m.color.a = r, g, b, 1.0
        m.pose.orientation.w = 1.0
        if kind == Marker.LINE_STRIP:
            m.points = [Point(), Point(), Point()]
        msg.markers.append(m)
    return msg


def fill_crane_markers(msg: MarkerArray, stamp: int, suspension, p1, p2):
    """Write the stamp, the suspension point (the trolley, on the bridge) and both masses' positions (m,
    (x, y, z) in the crane frame) in place."""
    markers = msg.markers
    for m in markers:
        set_stamp(m.header.stamp, stamp)
    for point, (x, y, z) in zip(markers[CABLES_MARKER].points, (suspension, p1, p2)):
        point.x, point.y, point.z = x, y, z
    for marker, (x, y, z) in ((markers[CART_MARKER], suspension), (markers[MASS1_MARKER], p1),
                              (markers[MASS2_MARKER], p2)):
        marker.pose.position.x, marker.pose.position.y, marker.pose.position.z = x, y, z
    if len(markers) > BRIDGE_MARKER:
        markers[BRIDGE_MARKER].pose.position.y = suspension[1]


#: How far (m) a keep-out box's unbounded side is drawn beyond its other side (from the origin if both are).
KEEP_OUT_DRAWN = 5.0


def _drawn_span(lo: float, hi: float) -> tuple[float, float]:
    """A box's span along one axis as drawn: an unbounded side ``KEEP_OUT_DRAWN`` beyond the other one."""
    if math.isinf(lo) and math.isinf(hi):
        return -KEEP_OUT_DRAWN, KEEP_OUT_DRAWN
    if math.isinf(lo):
        return hi - KEEP_OUT_DRAWN, hi
    if math.isinf(hi):
        return lo, lo + KEEP_OUT_DRAWN
    return lo, hi


def keep_out_markers(boxes, margin: float, frame_id: str, stamp: int, lifetime: float = 2.0) -> MarkerArray:
    """The keep-out boxes (``(lower, upper)`` corners, m, in ``frame_id``) as translucent red cubes (namespace
    ``keep_out``) and each grown by ``margin`` as a fainter one (``keep_out_margin``); an unbounded
    side is drawn ``KEEP_OUT_DRAWN`` beyond the other (``_drawn_span``). They expire after ``lifetime`` s
    (a publisher refreshes them sooner): a box no longer set disappears by itself."""
    msg = MarkerArray()
    for k, (lower, upper) in enumerate(boxes):
        for ns, grow, alpha in (('keep_out', 0.0, 0.5), ('keep_out_margin', margin, 0.15)):
            lo, hi = zip(*(_drawn_span(a - grow, b + grow) for a, b in zip(lower, upper)))
            m = Marker()
            m.header.frame_id = frame_id
            set_stamp(m.header.stamp, stamp)
            m.ns, m.id, m.type, m.action = ns, k, Marker.CUBE, Marker.ADD
            m.pose.position.x, m.pose.position.y, m.pose.position.z = ((a + b) / 2 for a, b in zip(lo, hi))
            m.pose.orientation.w = 1.0
            m.scale.x, m.scale.y, m.scale.z = (max(b - a, 1e-3) for a, b in zip(lo, hi))
            m.color.r, m.color.g, m.color.b, m.color.a = 0.9, 0.1, 0.1, alpha
            m.lifetime.sec, m.lifetime.nanosec = int(lifetime), round((lifetime % 1.0) * 1e9)
            msg.markers.append(m)
    return msg


def route_markers(points, frame_id: str, stamp: int, lifetime: float) -> MarkerArray:
    """The load's planned path ``points`` ((n, 3), m, in ``frame_id``) as a green line strip (namespace
    ``route``), expiring after ``lifetime`` s: drawn while the motion runs and settles."""
    m = Marker()
    m.header.frame_id = frame_id
    set_stamp(m.header.stamp, stamp)
    m.ns, m.id, m.type, m.action = 'route', 0, Marker.LINE_STRIP, Marker.ADD
    m.pose.orientation.w = 1.0
    m.scale.x = 0.01  # the line's width (m)
    m.color.r, m.color.g, m.color.b, m.color.a = 0.1, 0.8, 0.2, 0.9
    m.points = [Point(x=float(x), y=float(y), z=float(z)) for x, y, z in points]
    m.lifetime.sec, m.lifetime.nanosec = int(lifetime), round((lifetime % 1.0) * 1e9)
    return MarkerArray(markers=[m])


def move_message(goal, duration: float, start=(), method: str = '', joint_names=(), start_ns: int = 0,
                 via=()) -> Move:
    """A ``crane_interfaces/Move``: positions (m) per joint of ``joint_names`` (empty: the planner's
    joints), ``duration`` (s; 0 = the fastest within the planner's limits), ``start`` empty = where the
    streamer holds the axes, ``start_ns`` 0 = as soon as possible, ``via`` the points passed on the way
    (each positions per joint)."""
    msg = Move()
    msg.via = [JointTrajectoryPoint(positions=[float(x) for x in point]) for point in via]
    msg.method = method or ''
    msg.joint_names = list(joint_names)
    msg.start = [float(x) for x in start]
    msg.goal = [float(x) for x in goal]
    msg.duration = float(duration)
    set_stamp(msg.start_time, int(start_ns))
    return msg


def stream_state_message(joints=(CART_JOINT,), frame_id: str = DEFAULT_FRAME_ID) -> StreamState:
    """A reusable ``StreamState`` for ``joints`` (filled in place by ``fill_stream_state``)."""
    msg = StreamState()
    msg.header.frame_id = frame_id
    msg.joint_names = list(joints)
    msg.position = array.array('d', [0.0] * len(joints))
    msg.velocity = array.array('d', [0.0] * len(joints))
    msg.acceleration = array.array('d', [0.0] * len(joints))
    msg.correction = array.array('d', [0.0] * len(joints))
    return msg


STREAMING, HOLDING = 'streaming', 'holding'
#: ``StreamState.state`` of a streamer in operator mode (it follows cmd_vel, not trajectories).
OPERATOR = 'operator'


def fill_stream_state(msg: StreamState, stamp: int, streaming: bool, position, velocity,
                      acceleration, motion_start_ns: int, motion_duration: float, operator: bool = False,
                      motion_origin_ns: int | None = None, correction=None, reason: str = ''):
    """One tick's state of a stream into a message from ``stream_state_message``, in place (floats for one
    joint, tuples for several); ``operator``: the state is ``operator`` (the streamer follows cmd_vel);
    ``motion_origin_ns``: when the motion's first knot is streamed (default: its first tick); ``correction``:
    the sway feedback's share of ``position`` per joint (a sequence; None: none); ``reason``: why the streamer
    itself stopped or refused the newest motion (its runway guard; '' if nothing did)."""
    s = msg.header.stamp
    s.sec, s.nanosec = divmod(stamp, NS)
    msg.state = OPERATOR if operator else STREAMING if streaming else HOLDING
    if type(position) is tuple:
        msg.position[:] = array.array('d', position)
        msg.velocity[:] = array.array('d', velocity)
        msg.acceleration[:] = array.array('d', acceleration)
    else:
        msg.position[0], msg.velocity[0], msg.acceleration[0] = position, velocity, acceleration
    m = msg.motion_start
    m.sec, m.nanosec = divmod(motion_start_ns, NS)
    msg.motion_duration = motion_duration
    o = msg.motion_origin
    o.sec, o.nanosec = divmod(motion_start_ns if motion_origin_ns is None else motion_origin_ns, NS)
    if correction is not None:
        msg.correction[:] = array.array('d', correction)
    if msg.reason != reason:
        msg.reason = reason


def read_stream_state(msg: StreamState) -> tuple[int, str, dict, int, float, int, dict, str]:
    """(stamp ns, state: streaming/holding/operator, {joint: the source's position}, motion start ns, motion
    duration s, motion origin ns, {joint: the sway feedback's correction}, reason: why the streamer stopped or
    refused the newest motion itself) of a ``StreamState``: the position the source streams (the hold, the
    motion's) is the published one less the correction."""
    correction = dict(zip(msg.joint_names, msg.correction)) if len(msg.correction) else {}
    source = {name: p - correction.get(name, 0.0) for name, p in zip(msg.joint_names, msg.position)}
    return (stamp_ns(msg.header.stamp), msg.state, source, stamp_ns(msg.motion_start), msg.motion_duration,
            stamp_ns(msg.motion_origin), correction, msg.reason)


def crane_state_message(crane: str, frame_id: str) -> CraneState:
    """A reusable ``CraneState`` of the crane named ``crane`` in ``frame_id`` (the runway's; filled in place by
    ``fill_crane_state``)."""
    msg = CraneState(crane=crane)
    msg.header.frame_id = frame_id
    return msg


def fill_crane_state(msg: CraneState, stamp: int, girder: float, girder_velocity: float, trolley: float,
                     hook: tuple, load: tuple, reach: tuple, guard: str, guard_crane: str,
                     footprint: tuple = (0.0, 0.0), planned: bool = False) -> None:
    """One tick's live state of a crane on the runway into a message from ``crane_state_message``, in place:
    the girder's y (m) and velocity (m/s), the trolley's x, the hook's and the load's (x, y), its stopping
    envelope (low, high) along y, its guard's level and the crane that level is for, its footprint (low, high)
    along y and whether it follows its published occupancy."""
    s = msg.header.stamp
    s.sec, s.nanosec = divmod(stamp, NS)
    msg.girder, msg.girder_velocity, msg.trolley = girder, girder_velocity, trolley
    msg.hook_x, msg.hook_y = hook
    msg.load_x, msg.load_y = load
    msg.reach_low, msg.reach_high = reach
    msg.footprint_low, msg.footprint_high = footprint
    msg.planned = planned
    if msg.guard != guard or msg.guard_crane != guard_crane:
        msg.guard, msg.guard_crane = guard, guard_crane
