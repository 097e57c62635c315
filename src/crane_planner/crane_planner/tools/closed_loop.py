"""A reference and the sway feedback interconnected with crane_sim's plant, offline: what the streamer and the sim do
over ROS, step by step on one clock, with no process, no network and no real time.

Each tick (the streamer's period) the reference's setpoint goes through the
feedback (``streaming.sway_feedback.SwayFeedback``, as the streamer applies
it), and the plant (``crane_sim.simulator.CraneSimulator``, its own
parameters) plays it at its stamp as the sim does: the playout delay shifts
the plant's clock, not the plant. Disturbances act on the load as the sim's
do (``crane_sim.disturbances``: pushes, a steady wind, seeded gusts); every
camera period the plant's angles are measured by the sim's own sensor
(``crane_sim.sensor.Sensor``: noise, dropout, latency) and reach the feedback
its latency plus the playout delay after their stamp, as they reach the
streamer. Open loop is the same run with the feedback left out. Needs
crane_sim (the planner's ``sim`` extra). No ROS import.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from crane_msgs_py.crane.axes import AxisLimits
from crane_msgs_py.crane.params import CraneParams
from crane_msgs_py.messages.names import BRIDGE_JOINT, CART_JOINT

from ..streaming.source import Setpoint
from ..streaming.sway_feedback import SwayFeedback

#: The camera's sample period (s): the sim's joint_states rate.
CAMERA_PERIOD = 0.02


@dataclass(frozen=True)
class Push:
    """The load displaced ``dx`` (and ``dy``, with a bridge) (m) at ``t`` (s), cables in line, released from rest."""

    t: float
    dx: float
    dy: float = 0.0


@dataclass
class Trace:
    """What a run did, per tick: time (s), the published reference and the correction of each travel axis (m:
    columns cart[, bridge]), the plant's axes (m) and the load's horizontal offset from below the suspension point
    (m: x[, y])."""

    t: list = field(default_factory=list)
    reference: list = field(default_factory=list)
    correction: list = field(default_factory=list)
    axes: list = field(default_factory=list)
    offset: list = field(default_factory=list)

    def arrays(self) -> dict:
        """The columns as arrays, and ``load``: the swing (m), signed along x on the planar crane, the norm of the
        offset with a bridge; ``cart``: the plant's cart."""
        a = {name: np.asarray(value) for name, value in vars(self).items()}
        offset = a['offset']
        a['load'] = offset[:, 0] if offset.shape[1] == 1 else np.hypot(offset[:, 0], offset[:, 1])
        a['cart'] = a['axes'][:, 0]
        if a['reference'].shape[1] == 1:  # (one travel axis: its columns as plain arrays)
            a['reference'], a['correction'] = a['reference'][:, 0], a['correction'][:, 0]
        return a


def closed_loop(reference: Callable[[float], Setpoint], duration: float, model: CraneParams, plant: CraneParams,
                feedback: bool = True, sensor=None, pushes=(), disturbances=None, delay: float = 0.1,
                tick: float = 1e-3, limits: AxisLimits | None = None, seed: int = 0, timeout: float = 0.2,
                joints=(CART_JOINT,), calm_after: float = math.inf) -> Trace:
    """Run ``reference`` (its setpoint of ``joints`` at t s) for ``duration`` s on ``plant``, corrected by a
    feedback designed on ``model`` (``feedback``), measured by a ``crane_sim.sensor.SensorSettings``
    (``sensor``; None: ideal), disturbed by ``pushes`` and ``crane_sim.disturbances.Disturbances``; ``delay``
    the playout delay (s); ``limits`` of each travel axis; the wind and gusts stop at ``calm_after`` s (whether a
    swing left then decays is the closed loop's stability, which a gust still blowing would hide)."""
    from crane_msgs_py.crane.geometry import load_offset
    from crane_sim.disturbances import Disturbances, Gust
    from crane_sim.sensor import Sensor, SensorSettings
    from crane_sim.simulator import CraneSimulator, CraneState
    joints = tuple(joints)
    spatial = BRIDGE_JOINT in joints
    sensor = sensor or SensorSettings()
    disturbances = (disturbances or Disturbances()).check_planes(spatial)
    start = reference(0.0).position
    starts = start if isinstance(start, tuple) else (start,)
    sim = CraneSimulator(plant, dt=tick, state=CraneState(y=float(starts[0])), axes=joints)
    fb = SwayFeedback(joints, model, tick, {j: limits for j in joints if limits is not None}, timeout,
                      max(sensor.noise, 1e-4)) if feedback else None
    camera = Sensor(sensor, seed)
    gust = Gust(disturbances.gust, disturbances.gust_time, 2 if spatial else 1, seed)  # (the sim's gusts of seed)
    every = max(1, round(CAMERA_PERIOD / tick))
    pending = sorted(pushes, key=lambda p: p.t)
    travel = [k for k, j in enumerate(joints) if j in (CART_JOINT, BRIDGE_JOINT)]
    trace = Trace()
    for k in range(int(round(duration / tick))):
        t = k * tick
        stamp = round(t * 1e9)
        while pending and pending[0].t <= t + 1e-12:
            push = pending.pop(0)
            if spatial:
                sim.push(push.dx, push.dy)
            else:
                sim.push(push.dx)
        if disturbances.active:
            ax, ay = disturbances.plus(gust.step(tick)) if t < calm_after else (0.0, 0.0)
            sim.disturbance = (ax, ay if spatial else 0.0)
        w = sim.swing
        angles = (w.theta1, w.theta2, w.phi1, w.phi2) if spatial else (w.theta1, w.theta2)
        if k % every == 0:  # the camera's sample of the plant now
            camera.measure(t, stamp, angles)
        for sample in camera.released(t - delay):  # (the plant plays delay behind the streamer's clock)
            if fb is not None:
                fb.measure(sample.stamp, dict(zip(('theta1', 'theta2', 'phi1', 'phi2'), sample.angles)))
        setpoint = reference(t)
        out = fb.correct(k, stamp, setpoint) if fb is not None else setpoint
        positions = out.position if isinstance(out.position, tuple) else (out.position,)
        sources = setpoint.position if isinstance(setpoint.position, tuple) else (setpoint.position,)
        trace.t.append(t)
        trace.reference.append([positions[i] for i in travel])
        trace.correction.append([positions[i] - sources[i] for i in travel])
        trace.axes.append([sim.axis_state(j)[0] for j in joints])
        dx, dy = load_offset(w.theta1, w.theta2, w.phi1, w.phi2, sim.L1, plant.L2)
        trace.offset.append([-dx, -dy] if spatial else [-dx])
        sim.step(out.acceleration)
    return trace


def of_plan(plan, start: float = 0.0) -> Callable[[float], Setpoint]:
    """The setpoint of a ``Plan`` of the cart (relative, from ``start`` m) at t s, held at its end."""
    def setpoint(t: float) -> Setpoint:
        s = plan.evaluate([min(t, plan.duration)])
        if t >= plan.duration:
            return Setpoint(start + float(s.position[0]), 0.0, 0.0)
        return Setpoint(start + float(s.position[0]), float(s.velocity[0]), float(s.acceleration[0]))
    return setpoint


def holding(at=0.0) -> Callable[[float], Setpoint]:
    """The hold at ``at`` (m; a tuple: one per joint)."""
    if isinstance(at, tuple):
        zeros = tuple(0.0 for _ in at)
        return lambda t: Setpoint(at, zeros, zeros)
    return lambda t: Setpoint(at, 0.0, 0.0)


def residual(trace: Trace, after: float, until: float = math.inf) -> float:
    """The largest swing (m) in [after, until] s."""
    a = trace.arrays()
    inside = (a['t'] >= after) & (a['t'] <= until)
    return float(np.max(np.abs(a['load'][inside])))
