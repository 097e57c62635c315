"""A reference and the sway feedback interconnected with crane_sim's plant, offline: what the streamer and the sim do
over ROS, step by step on one clock, with no process, no network and no real time.

Each tick (the streamer's period) the reference's setpoint goes through the
feedback (``streaming.sway_feedback.SwayFeedback``, as the streamer applies
it), the plant (``crane_sim.simulator.CraneSimulator``, its own parameters)
plays it at its stamp as the sim does (the playout delay shifts the plant's
clock, not the plant), and every camera period the plant's angles are
measured: with ``Sensor`` noise and dropout, and delivered to the feedback
``Sensor.latency`` plus the playout delay after their stamp, as they reach the
streamer. ``simulate`` runs it open and closed loop from the same seed.
Needs crane_sim (the planner's ``sim`` extra). No ROS import.
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from crane_msgs_py.crane.axes import AxisLimits
from crane_msgs_py.crane.params import CraneParams
from crane_msgs_py.messages.names import CART_JOINT

from ..streaming.source import Setpoint
from ..streaming.sway_feedback import SwayFeedback


@dataclass(frozen=True)
class Sensor:
    """The camera: its sample period, latency (s after the stamp, beyond the playout delay), angle noise (rad,
    standard deviation) and the share of samples it drops."""

    period: float = 0.02
    latency: float = 0.0
    noise: float = 0.0
    dropout: float = 0.0


@dataclass(frozen=True)
class Push:
    """The load displaced ``dx`` (m) at ``t`` (s), cables in line, released from rest."""

    t: float
    dx: float


@dataclass
class Trace:
    """What a run did, per tick: time (s), the published reference's cart position (m), the correction (m), the
    cart (m) and the load's horizontal offset from below the cart (m)."""

    t: list = field(default_factory=list)
    reference: list = field(default_factory=list)
    correction: list = field(default_factory=list)
    cart: list = field(default_factory=list)
    load: list = field(default_factory=list)

    def arrays(self) -> dict:
        return {name: np.asarray(value) for name, value in vars(self).items()}


def closed_loop(reference: Callable[[float], Setpoint], duration: float, model: CraneParams, plant: CraneParams,
                feedback: bool = True, sensor: Sensor = Sensor(), pushes=(), delay: float = 0.1, tick: float = 1e-3,
                limits: AxisLimits = AxisLimits(), seed: int = 0, timeout: float = 0.2) -> Trace:
    """Run ``reference`` (its setpoint at t s) for ``duration`` s on ``plant``, corrected by a feedback designed on
    ``model`` (``feedback``), measured by ``sensor``; ``pushes`` as they come; ``delay`` the playout delay (s)."""
    from crane_msgs_py.crane.geometry import load_swing
    from crane_sim.simulator import CraneSimulator, CraneState
    sim = CraneSimulator(plant, dt=tick, state=CraneState(y=float(reference(0.0).position)))
    fb = SwayFeedback((CART_JOINT,), model, tick, {CART_JOINT: limits}, timeout, max(sensor.noise, 1e-4)) \
        if feedback else None
    rng = np.random.default_rng(seed)
    every = max(1, round(sensor.period / tick))
    in_flight: deque = deque()  # (due stamp ns, stamp ns, theta1, theta2)
    pending = sorted(pushes, key=lambda p: p.t)
    trace = Trace()
    steps = int(round(duration / tick))
    for k in range(steps):
        t = k * tick
        stamp = round(t * 1e9)
        while pending and pending[0].t <= t + 1e-12:
            sim.push(pending.pop(0).dx)
        if k % every == 0:  # the camera's sample of the plant now
            w = sim.swing
            noisy = (w.theta1 + sensor.noise * rng.standard_normal(), w.theta2 + sensor.noise * rng.standard_normal())
            if rng.random() >= sensor.dropout:
                in_flight.append((stamp + round((delay + sensor.latency) * 1e9), stamp, *noisy))
        while in_flight and in_flight[0][0] <= stamp:
            _, measured, theta1, theta2 = in_flight.popleft()
            if fb is not None:
                fb.measure(measured, {'theta1': theta1, 'theta2': theta2})
        setpoint = reference(t)
        out = fb.correct(k, stamp, setpoint) if fb is not None else setpoint
        w, y = sim.swing, sim.axis_state(CART_JOINT)[0]
        trace.t.append(t)
        trace.reference.append(out.position)
        trace.correction.append(out.position - setpoint.position)
        trace.cart.append(y)
        trace.load.append(float(load_swing(w.theta1, w.theta2, sim.L1, plant.L2)))
        sim.step(out.acceleration)
    return trace


def of_plan(plan, start: float = 0.0) -> Callable[[float], Setpoint]:
    """The setpoint of a ``Plan`` (relative, from ``start`` m) at t s, held at its end."""
    def setpoint(t: float) -> Setpoint:
        s = plan.evaluate([min(t, plan.duration)])
        if t >= plan.duration:
            return Setpoint(start + float(s.position[0]), 0.0, 0.0)
        return Setpoint(start + float(s.position[0]), float(s.velocity[0]), float(s.acceleration[0]))
    return setpoint


def holding(at: float = 0.0) -> Callable[[float], Setpoint]:
    """The hold at ``at`` m."""
    return lambda t: Setpoint(at, 0.0, 0.0)


def residual(trace: Trace, after: float) -> float:
    """The largest |load offset| (m) after ``after`` s."""
    a = trace.arrays()
    return float(np.max(np.abs(a['load'][a['t'] >= after]))) if math.isfinite(after) else math.nan
