"""A running motion braked to rest along each axis's jerk-limited ramp: the streamer's last resort.

A ``~/stop`` during a motion is a stop without swing (``serving.stops``),
planned in a worker process ahead of its handover and planned again further
ahead when its answer comes late. When none can be had in time (the worker
is dead or not ready, or every answer came too late), holding where the
stream is would be an infinite deceleration: the swing the product exists to
avoid, and a step no drive can follow. Instead every axis brakes from its
reference's velocity and acceleration at the handover along its fastest
jerk-limited ramp (``crane_msgs_py.crane.braking.Braking``, the same ramp the sim's
axis controller runs when its reference stream is lost), so the acceleration
never steps by more than the jerk limit allows in a tick. It swings; it is
the controlled stop of IEC 60204-1's category 1, not an anti-sway move.

The ramp's knots sit at every axis's phase boundaries, where the reference
is a cubic in between, so the stream's quintic Hermite interpolation
reproduces it exactly. Pure Python, no ROS import.
"""
from __future__ import annotations

import numpy as np

from crane_msgs_py.crane.braking import Braking

from .reference_stream import ReferenceStream
from .stop_trajectory import StopTrajectory

#: How far ahead (s) of the request the ramp takes over, tried in turn: the stream refuses a stop's handover
#: that reaches it after its stamp, so a busy executor thread gets the next, longer lead.
LEADS = (0.005, 0.02, 0.08)
#: ``StopTrajectory.method`` of a braking.
METHOD = 'braking ramp'


def braking_stop(state: np.ndarray, handover_ns: int, deceleration: float, jerk: float,
                 period: float = 1e-3) -> StopTrajectory:
    """Every axis braked from ``state`` (rows position, velocity, acceleration; a column per joint) at
    ``handover_ns`` within ``deceleration`` (m/s^2) and ``jerk`` (m/s^3); an axis already at rest holds.
    ``period``: the knot spacing of a braking that takes no time (two knots are needed)."""
    state = np.asarray(state, dtype=float).reshape(3, -1)
    ramps = [Braking(v, a, deceleration, jerk) for v, a in zip(state[1], state[2])]
    duration = max(ramp.duration for ramp in ramps)
    t = sorted({0.0, max(duration, period)} | {p.start + p.duration for ramp in ramps for p in ramp.phases})
    columns = np.array([[ramp.state(x) for ramp in ramps] for x in t])  # (knots, joints, p v a)
    position = state[0] + columns[:, :, 0]
    return StopTrajectory(np.array(t), position, columns[:, :, 1], columns[:, :, 2], int(handover_ns), duration,
                          METHOD)


def brake(stream: ReferenceStream, now, deceleration: float, jerk: float) -> StopTrajectory | None:
    """Brake what ``stream`` streams along every axis's ramp: the stop accepted as the stream's handover,
    ``LEADS`` ahead of ``now()`` (ns) in turn; None if the motion ends first (it ends at rest by itself).
    ValueError if no motion streams or the stream refused every lead."""
    refused = None
    for lead in LEADS:
        motion = stream.last_motion
        if motion is None or not stream.streaming:
            raise ValueError('no motion is streaming')
        handover = now() + round(lead * 1e9)
        if handover >= motion.start_ns + round(motion.duration * 1e9):
            return None
        stop = braking_stop(motion.state_at(handover), handover, deceleration, jerk, stream.period_ns * 1e-9)
        try:
            stream.accept(*stop.arrays(), stop.handover_ns, now())
            return stop
        except ValueError as exc:  # late for its handover: further ahead
            refused = exc
    raise ValueError(f'the braking ramp was refused at every lead ({refused})')
