"""QoS profiles of the crane trajectory server's topics (contract).

Publishers and subscribers of one topic must use compatible profiles; take
them from here rather than spelling them out.
"""
from __future__ import annotations

from rclpy.qos import (DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy,
                       qos_profile_sensor_data)

#: ``trajectory``: the last successful plan is latched, so a streamer that
#: (re)connects gets it, and it is never lost (one message per request, large).
TRAJECTORY_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=1,
    reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)

#: ``reference``: the 1 kHz setpoint stream. Best effort: a setpoint is
#: superseded 1 ms later, so a retransmitted one would arrive stale and be
#: discarded anyway, while reliable delivery would add acknowledgement traffic
#: and head-of-line blocking behind a lost sample (latency spikes where the
#: receiver needs freshness). Volatile: a late joiner must not get old
#: setpoints. Depth 100 (100 ms of samples): with best effort only the
#: reader's queue matters, and a receiver that stalls for a few tens of ms
#: (a busy machine, a virtual CPU descheduled by its host) then still gets
#: every sample, in order, which matters to a plant that integrates each one
#: (the sim) or differentiates positions. A best-effort publisher only
#: matches best-effort subscribers: subscribe with this profile too.
REFERENCE_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=100,
    reliability=ReliabilityPolicy.BEST_EFFORT, durability=DurabilityPolicy.VOLATILE)

#: ``joint_states``: measurements, newest wins (REP 2003 sensor data profile).
JOINT_STATES_QOS = qos_profile_sensor_data

#: ``/diagnostics``: reliable, and transient local with a short history so a
#: reader that has just joined (a ``PlannerClient`` created right before its
#: first request) still gets the status of a request answered before its
#: subscription matched. Volatile subscribers (diagnostic_aggregator) match it
#: too; a transient-local reader only matches transient-local publishers.
DIAGNOSTICS_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=20,
    reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
