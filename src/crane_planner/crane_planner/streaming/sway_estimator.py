"""The swing of one horizontal plane, estimated through what was streamed from late, noisy measurements.

The estimate runs tick by tick on the estimation model (``sway_model.estimation``),
driven by the reference acceleration the streamer published at each tick: the
plant plays each sample at its stamp (a playout delay behind the clock) and
``joint_states`` are stamped with the same plant time, so a measurement stamped
t compares with the estimate of tick t, however late it arrives (the camera's
processing, the playout delay, the transport). Its correction there, L (y - C
z(t)), is carried to every later tick by the model's own transition (Phi^k L
nu: the model is linear and its inputs since are known), so a late
measurement corrects the present exactly as an early one would have; the
stored past is corrected too, for the next measurement. The plan's own swing
(the same model driven by the plan's acceleration alone, no disturbance) runs
beside it: what the feedback acts on is the difference. Pure numpy, no ROS import.
"""
from __future__ import annotations

import numpy as np

from .sway_law import PlaneDesign


class SwayEstimator:
    """One plane's swing estimate at the newest tick (``z``: ``sway_model.ESTIMATION_STATES``), its past over
    ``capacity`` ticks, and the plan's own swing (``plan``)."""

    def __init__(self, capacity: int):
        self.z = np.zeros(6)
        self.plan = np.zeros(6)
        self._past = np.zeros((capacity, 6))  # z at each tick's stamp, before its step
        self._stamps = np.full(capacity, -1, dtype=np.int64)
        self._next = 0  # ring index of the next tick
        self.taken = self.too_old = 0

    def reset(self) -> None:
        """Back to the load hanging still (the past forgotten)."""
        self.z[:] = 0.0
        self.plan[:] = 0.0
        self._stamps[:] = -1
        self._next = 0

    def step(self, design: PlaneDesign, stamp_ns: int, accel: float, plan_accel: float) -> None:
        """Tick ``stamp_ns``: its estimate kept, then stepped over the tick with the acceleration published there
        (``accel``) and the plan's alone (``plan_accel``)."""
        k = self._next
        self._past[k] = self.z
        self._stamps[k] = stamp_ns
        self._next = (k + 1) % len(self._stamps)
        self.z = design.Phi @ self.z + design.Gamma[:, 0] * accel
        self.plan = design.Phi @ self.plan + design.Gamma[:, 0] * plan_accel

    def measure(self, design: PlaneDesign, stamp_ns: int, theta1: float, theta2: float) -> bool:
        """Take the measured angles stamped ``stamp_ns``: the estimate of that tick corrected and the correction
        carried to every tick since; False (ignored) if that tick is no longer kept or not yet reached."""
        n = len(self._stamps)
        newest = (self._next - 1) % n
        if self._stamps[newest] < 0 or stamp_ns < 0:
            return False
        age = (int(self._stamps[newest]) - stamp_ns) // max(1, round(design.tick * 1e9))
        if age < 0:  # (stamped after the newest tick: a clock ahead; taken as the newest)
            age = 0
        if age >= min(n, len(design.powers)) or self._stamps[(newest - age) % n] < 0:
            self.too_old += 1
            return False
        k = (newest - age) % n
        innovation = np.array([theta1, theta2]) - self._past[k, 1:3]
        delta = design.L @ innovation
        rows = (k + np.arange(age + 1)) % n  # tick k and every later one kept
        self._past[rows] += design.powers[:age + 1] @ delta
        self.z += design.powers[age + 1] @ delta if age + 1 < len(design.powers) else 0.0
        self.taken += 1
        return True

    def deviation(self, design: PlaneDesign) -> np.ndarray:
        """What the plan did not foresee, as the control model's swing part: [a, theta1, theta2, theta1', theta2']
        of the estimate less the plan's own, the angles about the lean a steady disturbance gives them."""
        d = self.z[:5] - self.plan[:5]
        d[1:3] -= design.lean * self.z[5]
        return d
