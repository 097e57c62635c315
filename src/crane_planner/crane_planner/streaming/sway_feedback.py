"""Closed-loop sway control: the streamer's correction of whatever it streams from the measured swing.

A ``source.Correction``: each tick it adds to the source's setpoint (a
trajectory, the hold, operator mode) a correction of each travel axis (the
cart's in the x plane, the bridge's in the y plane), so that swing the plan
did not foresee (wind, a push, a cable of another length than the model's) is
damped while the axes end where the plan ends. Per plane:

- ``sway_estimator.SwayEstimator`` estimates the swing through what was
  streamed from the measurements (``measure``, from the executor: ``joint_states``
  at their stamps), however late they come;
- the law (``sway_law``) turns the correction's own state and the estimate's
  deviation from the plan's own swing into the correction's jerk, the design
  of the cable length the hoist's reference has now;
- the jerk is held within each axis's limits on the published reference
  (``crane.axes.AxisLimits``), and the correction integrated over the tick.

With nothing to correct the correction is nothing: the plan is the
feed-forward. When no finite measurement has come for ``timeout`` the state is
``LOST``: the correction fades to zero within the limits (a law on its own
state alone) and the plan streams on open loop, until measurements return.
The executor writes measurements into a deque the loop drains each tick (one
realtime inbox); nothing else is shared. Pure Python, no ROS import.
"""
from __future__ import annotations

import enum
import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from crane_msgs_py.crane.axes import AxisLimits
from crane_msgs_py.crane.params import CraneParams
from crane_msgs_py.messages.names import BRIDGE_JOINT, CART_JOINT, HOIST_JOINT

from .source import Setpoint
from .sway_estimator import SwayEstimator
from .sway_law import HISTORY, Schedule

#: The measured angles of each travel axis's plane, by the joint_states names, and the sign that makes them the
#: plane's model's (``sway_model``: positive when the load lags a positive acceleration of the axis): theta is
#: (towards -x), phi is not (``crane_msgs_py.crane.geometry``: towards +y).
PLANE_ANGLES = {CART_JOINT: (('theta1', 'theta2'), 1.0), BRIDGE_JOINT: (('phi1', 'phi2'), -1.0)}
#: The fade's law: the correction's (position, velocity, acceleration) brought to zero with a triple pole at
#: -FADE_RATE (1/s): a few seconds, smooth, well within any axis's limits for a correction of centimetres.
FADE_RATE = 3.0


class FeedbackState(enum.Enum):
    """Whether the correction follows the measurements."""

    OFF = 'off'          # switched off: measurements ignored, a correction left fades to zero
    WAITING = 'waiting'  # on, no measurement yet: no correction
    ACTIVE = 'active'    # measurements come: the law corrects
    LOST = 'lost'        # none finite for feedback_timeout: the correction fades to zero, open loop


S = FeedbackState
#: state -> the states it may change to.
TRANSITIONS = {
    S.OFF: {S.WAITING},
    S.WAITING: {S.ACTIVE, S.OFF},
    S.ACTIVE: {S.LOST, S.WAITING, S.OFF},
    S.LOST: {S.ACTIVE, S.WAITING, S.OFF},
}
#: Below these (m, m/s, m/s^2) a faded correction is nothing (a tenth of a micrometre): switched off, it is
#: dropped and the loop leaves setpoints alone.
FADED = (1e-7, 1e-6, 1e-5)


@dataclass
class PlaneCorrection:
    """One travel axis's correction: its position, velocity and acceleration (m, m/s, m/s^2), the measured angles
    of its plane (and the sign that makes them its model's), its limits and its estimator."""

    joint: str
    index: int
    angles: tuple
    sign: float
    limits: AxisLimits
    estimator: SwayEstimator
    p: float = 0.0
    v: float = 0.0
    a: float = 0.0
    peak: float = 0.0
    applied: float = 0.0  # the correction in the newest setpoint corrected
    last_plan_accel: float = math.nan

    def state(self) -> np.ndarray:
        return np.array([self.p, self.v, self.a])

    def zero(self) -> None:
        """No correction left."""
        self.p = self.v = self.a = self.applied = 0.0


class SwayFeedback:
    """The correction (see the module docstring).

    Args:
        joints: the streamed joints, in the setpoint's order.
        params: the planning model (L1 the cable when there is no hoist).
        tick: the streamer's period (s).
        limits: the limits on the published reference by joint (``crane.axes.AxisLimits``; a joint not given:
            none). A correction never takes the reference beyond one, nor further beyond one the plan exceeds.
        timeout: ``feedback_timeout`` (s).
        noise: the angles' noise the estimator expects (rad).
        lengths: (shortest, longest) cable L1 the hoist may give (m), for the schedule; None: ``params.L1``.
        on: switched on (``enable``).
    """

    def __init__(self, joints, params: CraneParams, tick: float, limits: dict | None = None, timeout: float = 0.2,
                 noise: float = 1e-3, lengths: tuple | None = None, on: bool = True):
        self.joints = tuple(joints)
        self.params, self.tick, self.timeout = params, float(tick), float(timeout)
        shortest, longest = lengths or (params.L1, params.L1)
        self.schedule = Schedule(params, tick, noise, shortest, longest)
        capacity = int(round(HISTORY / tick)) + 1
        self.planes = [PlaneCorrection(j, self.joints.index(j), *PLANE_ANGLES[j], (limits or {}).get(j, AxisLimits()),
                                       SwayEstimator(capacity)) for j in PLANE_ANGLES if j in self.joints]
        self._hoist = self.joints.index(HOIST_JOINT) if HOIST_JOINT in self.joints else None
        self._inbox: deque = deque()
        self.state = S.WAITING if on else S.OFF
        self._switch: bool | None = None  # an enable() for the loop to take
        self._reset = False  # a reset() for the loop to take
        self._heard_ns: int | None = None  # the tick stamp at which the last finite measurement was taken
        self.ignored = 0  # measurements not finite, or of a tick no longer kept

    # -- the executor's side -----------------------------------------------------------

    def measure(self, stamp_ns: int, angles: dict) -> None:
        """A measurement stamped ``stamp_ns`` (plant time): the angles (rad) by their joint_states names."""
        self._inbox.append((int(stamp_ns), angles))

    # -- the loop's side -----------------------------------------------------------------

    def enable(self, on: bool) -> None:
        """Switch the feedback on (it waits for measurements, its estimate started afresh) or off (a correction
        left fades to zero within the limits; measurements are ignored), from the loop's next tick: the executor
        writes the request, the loop takes it."""
        self._switch = bool(on)

    def _switched(self) -> None:
        on, self._switch = self._switch, None
        if on is None:
            return
        if on and self.state is S.OFF:
            for plane in self.planes:
                plane.estimator.reset()
            self._inbox.clear()
            self._heard_ns = None
            self._change(S.WAITING)
        elif not on and self.state is not S.OFF:
            self._change(S.OFF)

    @property
    def faded(self) -> bool:
        """Nothing left of a correction."""
        return all(abs(plane.p) < FADED[0] and abs(plane.v) < FADED[1] and abs(plane.a) < FADED[2]
                   for plane in self.planes)

    @property
    def switching_on(self) -> bool:
        """Switched on, and the loop has not taken it yet."""
        return self._switch is True

    def reset(self) -> None:
        """Forget the correction and the estimate from the loop's next tick: the stream starts again from a new
        hold (where a fault reaction held the axes): no correction is carried over to it."""
        self._reset = True

    def _reset_now(self) -> None:
        self._reset = False
        for plane in self.planes:
            plane.zero()
            plane.last_plan_accel = math.nan
            plane.estimator.reset()
        if self.state in (S.ACTIVE, S.LOST):
            self._change(S.WAITING)
        self._heard_ns = None

    def correct(self, tick: int, stamp_ns: int, setpoint: Setpoint) -> Setpoint:
        """``setpoint`` plus the correction of each travel axis at this tick (``source.Correction``)."""
        if self._reset:
            self._reset_now()
        if self._switch is not None:
            self._switched()
        if self.state is S.OFF:
            self._inbox.clear()
            if self.faded:
                for plane in self.planes:
                    plane.zero()
                return setpoint
        design = self.schedule.at(self._rope(setpoint))
        self._take(design, stamp_ns)
        if self.state is S.ACTIVE and stamp_ns - self._heard_ns > self.timeout * 1e9:
            self._change(S.LOST)
        positions, velocities, accelerations = (list(x) if isinstance(x, tuple) else [x] for x in setpoint)
        for plane in self.planes:
            i = plane.index
            p_plan, v_plan, a_plan = positions[i], velocities[i], accelerations[i]
            if self.state is S.ACTIVE:
                x = np.concatenate((plane.state(), plane.estimator.deviation(design)))
                jerk = -float(design.K[0] @ x)
            else:  # fade (or nothing yet): the correction's own state to zero
                jerk = -(FADE_RATE ** 3 * plane.p + 3 * FADE_RATE ** 2 * plane.v + 3 * FADE_RATE * plane.a)
            jerk_plan = 0.0 if math.isnan(plane.last_plan_accel) else (a_plan - plane.last_plan_accel) / self.tick
            plane.last_plan_accel = a_plan
            jerk = self._limited(plane, jerk, v_plan, a_plan, jerk_plan)
            plane.applied = plane.p
            positions[i] = p_plan + plane.p
            velocities[i] = v_plan + plane.v
            accelerations[i] = a_plan + plane.a
            plane.estimator.step(design, stamp_ns, a_plan + plane.a, a_plan)
            h = self.tick
            plane.p += plane.v * h + plane.a * h * h / 2 + jerk * h ** 3 / 6
            plane.v += plane.a * h + jerk * h * h / 2
            plane.a += jerk * h
            plane.peak = max(plane.peak, abs(plane.p))
        if len(positions) == 1:
            return Setpoint(positions[0], velocities[0], accelerations[0])
        return Setpoint(tuple(positions), tuple(velocities), tuple(accelerations))

    def correction(self) -> dict:
        """Each corrected joint's correction in the newest setpoint (m), by name."""
        return {plane.joint: plane.applied for plane in self.planes}

    def take_peak(self) -> dict:
        """Each corrected joint's largest |correction| (m) since the last call, by name."""
        peaks = {plane.joint: plane.peak for plane in self.planes}
        for plane in self.planes:
            plane.peak = abs(plane.p)
        return peaks

    # -- inside ----------------------------------------------------------------------------

    def _rope(self, setpoint: Setpoint) -> float:
        if self._hoist is None:
            return self.params.L1
        return float(setpoint.position[self._hoist])

    def _take(self, design, stamp_ns: int) -> None:
        while self._inbox:
            measured_ns, angles = self._inbox.popleft()
            values = [[plane.sign * angles.get(name, math.nan) for name in plane.angles] for plane in self.planes]
            if not all(math.isfinite(x) for pair in values for x in pair):
                self.ignored += 1
                continue
            taken = [plane.estimator.measure(design, measured_ns, *pair) for plane, pair in zip(self.planes, values)]
            if not all(taken):
                self.ignored += 1
                continue
            self._heard_ns = stamp_ns
            if self.state is not S.ACTIVE:
                self._change(S.ACTIVE)

    def _change(self, new: FeedbackState) -> None:
        if new not in TRANSITIONS[self.state]:
            raise RuntimeError(f'sway feedback: {self.state.value} -> {new.value} is not a legal change')
        self.state = new

    def _limited(self, plane: PlaneCorrection, jerk: float, v_plan: float, a_plan: float, jerk_plan: float) -> float:
        """``jerk`` held so that the published reference keeps within the axis's limits over the next tick (or
        gets no further beyond one the plan itself exceeds)."""
        (max_v, max_a, max_j), h = plane.limits, self.tick
        if max_j is not None:
            bound = max(max_j, abs(jerk_plan))
            jerk = min(max(jerk, -bound - jerk_plan), bound - jerk_plan)
        if max_a is not None:
            bound = max(max_a, abs(a_plan))
            a_next = a_plan + jerk_plan * h + plane.a + jerk * h
            if a_next > bound:
                jerk -= (a_next - bound) / h
            elif a_next < -bound:
                jerk += (-bound - a_next) / h
        if max_v is not None:
            # the velocity the reference would reach if its acceleration were ramped to zero from the next tick
            # on (at the jerk limit; without one, at once): past the bound, the correction ramps it down now
            bound = max(max_v, abs(v_plan))
            total = a_plan + plane.a + (jerk_plan + jerk) * h
            v_next = v_plan + plane.v + (a_plan + plane.a) * h
            ramp = max(max_j, abs(jerk_plan)) if max_j is not None else math.inf
            v_stop = v_next + total * abs(total) / (2.0 * ramp)
            if (v_stop > bound and total > 0.0) or (v_stop < -bound and total < 0.0):
                direction = math.copysign(1.0, total)
                jerk = -direction * ramp - jerk_plan if math.isfinite(ramp) else -(a_plan + plane.a) / h - jerk_plan
        return jerk
