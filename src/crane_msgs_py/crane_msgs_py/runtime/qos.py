"""QoS profiles of the crane trajectory server's topics (contract).

Publishers and subscribers of one topic must use compatible profiles; take
them from here rather than spelling them out.
"""
from __future__ import annotations

import copy

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy


def _keep_last(depth: int, reliable: bool = False, latched: bool = False) -> QoSProfile:
    """A profile keeping the last ``depth`` messages: best effort unless ``reliable``; volatile unless ``latched``
    (transient local: a late reader gets what was published before it joined)."""
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                      reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE)


#: ``trajectory``: the last successful plan is latched, so a streamer that
#: (re)connects gets it, and it is never lost (one message per request, large).
TRAJECTORY_QOS = _keep_last(1, reliable=True, latched=True)

#: ``reference``: the 1 kHz setpoint stream. Best effort: a setpoint is
#: superseded 1 ms later, so a retransmitted one would arrive stale and be
#: discarded anyway, while reliable delivery would add acknowledgement traffic
#: and head-of-line blocking behind a lost sample (latency spikes where the
#: receiver needs freshness). Volatile: a late joiner must not get old
#: setpoints. A queue of 10 ms: with best effort only the reader's queue
#: matters; a receiver that wants the newest setpoint (a forward command
#: controller) has a short backlog at most. A best-effort publisher only
#: matches best-effort subscribers: subscribe with a best-effort profile.
REFERENCE_QOS = _keep_last(10)

#: ``reference`` for receivers that need every sample (the sim integrates
#: them, recorders count them): the same policies with a queue of 1 s, so a
#: receiver stalled for less than that (a busy machine, a virtual CPU
#: descheduled by its host) still gets every sample, in order.
REFERENCE_EVERY_SAMPLE_QOS = _keep_last(1000)

#: ``stream_state``: the streamer's state at 50 Hz, a status in the sensor data style (best
#: effort, volatile): the next one supersedes a lost one within 20 ms.
STREAM_STATE_QOS = _keep_last(10)

#: ``/runway/state``: each crane's live state at 50 Hz for the other cranes' guards, as ``stream_state`` (best
#: effort, volatile: the next one supersedes a lost one), with a queue of 0.5 s of one crane's: several cranes
#: publish into it.
RUNWAY_STATE_QOS = _keep_last(25)

#: ``joint_states``: measurements in the sensor data style (REP 2003: best
#: effort, volatile) with a queue of 0.5 s at 50 Hz instead of the sensor data profile's 5, so a
#: reader that stalls briefly still gets every sample of a 50 Hz stream.
JOINT_STATES_QOS = _keep_last(25)

#: ``cmd_vel`` as the streamer reads it: best effort (it matches reliable publishers, such as
#: teleop_twist_keyboard's and crane-teleop's, and best-effort ones), depth 1: the newest command wins.
CMD_VEL_QOS = _keep_last(1)

#: ``axis_status``: a state that changes seldom, published on each change and once a second: reliable and
#: transient local with depth 1, so a reader that joins late (a supervisor, a test) gets the newest state at
#: once, as ``trajectory`` is latched.
AXIS_STATUS_QOS = _keep_last(1, reliable=True, latched=True)

#: ``/runway/occupancy``: every crane's planner publishes the space its crane will occupy when it sends a motion
#: and when it holds. Reliable (a lost one would let another crane plan into it) and transient local, so a crane
#: that starts late hears every other's newest; a depth of several per writer and per reader, so that the
#: cranes' publications close together (a claim, then a hold) are all kept until read.
RUNWAY_OCCUPANCY_QOS = _keep_last(10, reliable=True, latched=True)

#: ``crane_markers``: reliable (RViz2's MarkerArray display subscribes reliable; a best-effort
#: publisher would not match it), volatile, a short queue: a late frame is worth nothing.
MARKERS_QOS = _keep_last(5, reliable=True)

#: ``~/plan_move`` (the service and its clients): the services' default policies with a deeper queue than
#: their default 10. Requests run side by side, but each waits in the service's queue until the
#: executor takes it: a burst of concurrent requests overflows the default queue, and a dropped
#: request is never answered.
PLAN_MOVE_QOS = _keep_last(100, reliable=True)

#: ``/diagnostics``: reliable, and transient local with a short history so a
#: reader that has just joined (a ``PlannerClient`` created right before its
#: first request) still gets the status of a request answered before its
#: subscription matched. Volatile subscribers (diagnostic_aggregator) match it
#: too; a transient-local reader only matches transient-local publishers.
DIAGNOSTICS_QOS = _keep_last(20, reliable=True, latched=True)


def recording(profile: QoSProfile, seconds: float, rate_hz: float) -> QoSProfile:
    """A reader's copy of ``profile`` whose queue holds ``seconds`` of a ``rate_hz`` stream.

    For readers that must not lose a sample of a stream they record (tests,
    benches, the harness behind ``crane-demo``): a Python process can stall
    on a loaded host while DDS keeps receiving on time,
    and a queue of the publisher's depth then drops what arrived meanwhile.
    The depth is the reader's own: the other policies match the publisher's.
    """
    deep = copy.copy(profile)
    deep.depth = max(profile.depth, round(seconds * rate_hz))
    return deep
