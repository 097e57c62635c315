"""What every planning method returns: a plan that can be sampled at any period.

A *plan* is the cart reference fed to the axis controller (contract): position,
velocity, acceleration and jerk of the reference as functions of time, from
rest at 0 (t = 0) to rest at ``displacement`` (t = ``duration``). Plans are
relative: the ROS layer adds the start position and start stamp.
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field

import numpy as np

from crane_msgs_py.crane.errors import PlanError  # noqa: F401  (the planner's error type, re-exported)


@dataclass(frozen=True)
class Samples:
    """Reference samples: time (s), position (m), velocity (m/s), acceleration (m/s^2), jerk (m/s^3)."""

    t: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    jerk: np.ndarray


def time_grid(duration: float, period: float) -> np.ndarray:
    """Times 0, period, 2 period, ... and exactly ``duration`` as the last one.

    A regular point closer than period/1000 to the end is dropped so the last
    interval is never degenerate.
    """
    if not period > 0.0:
        raise PlanError(f'sample period must be > 0, got {period}')
    n = int(np.floor(duration / period + 1e-9))
    t = np.arange(n + 1) * period
    t = t[t < duration - 1e-3 * period]
    return np.append(t, duration)


@dataclass(frozen=True)
class ModelPath:
    """The planning model along a plan as its solver predicted it: the states at an NVF/RVF solution's
    collocation points. ``t``: times (s from the plan's start, increasing); ``states``: each state (SI,
    ``dynamics`` names: an axis's relative to its start) by name, arrays as long as ``t``."""

    t: np.ndarray
    states: dict


@dataclass
class Plan(ABC):
    """A rest-to-rest cart reference of one method.

    Attributes:
        method: method name (``nvf``, ``rvf``, ``zv``, ...).
        displacement: D (m), the position reached at ``duration``.
        duration: T (s).
        info: method-specific facts (solver status, iterations, solve time,
            shaper impulses ...), JSON-serialisable.
        model_path: the planning model's states along the plan as its solver
            found them (NVF/RVF), None otherwise or once the plan is changed.
    """

    method: str
    displacement: float
    duration: float
    info: dict = field(default_factory=dict)
    model_path: ModelPath | None = field(default=None, repr=False, compare=False)

    @abstractmethod
    def _evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Position, velocity, acceleration, jerk at times ``t`` within [0, duration]."""

    def breakpoints(self) -> np.ndarray:
        """Times (s) where the plan changes form, 0 and ``duration`` included, increasing.

        Between two the plan is one analytic piece (a polynomial, a spline
        segment): a plan's knots must include these (``streaming.knots``).
        """
        return np.array([0.0, self.duration])

    @property
    def quintic_pieces(self) -> bool:
        """Whether the plan is a polynomial of degree <= 5 between its breakpoints: then the quintic Hermite
        interpolant of its breakpoints' states is the plan itself (``streaming.knots`` needs no other knot)."""
        return False

    def evaluate(self, t) -> Samples:
        """Exact reference at arbitrary times; at rest at 0 before 0 and at D after T."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        tc = np.minimum(np.maximum(t, 0.0), self.duration)  # (np.clip costs more)
        p, v, a, j = (np.asarray(x, dtype=float) for x in self._evaluate(tc))
        outside = (t < 0.0) | (t > self.duration)
        if outside.any():
            p = np.where(t < 0.0, 0.0, np.where(t > self.duration, self.displacement, p))
            v, a, j = (np.where(outside, 0.0, x) for x in (v, a, j))
        return Samples(t, p, v, a, j)

    def sample(self, period: float) -> Samples:
        """Samples every ``period`` seconds, the last exactly at ``duration``."""
        return self.evaluate(time_grid(self.duration, period))

    def peaks(self, per_piece: int = 24) -> tuple[float, float, float]:
        """Peak |velocity|, |acceleration|, |jerk| over [0, T], sampled at ``per_piece`` + 1 evenly spaced
        times of every piece between breakpoints (low-degree polynomials: a few 1e-4 relative low at
        most; a plan type that knows its peaks exactly overrides this)."""
        b = self.breakpoints()
        t = (b[:-1, None] + np.diff(b)[:, None] * np.linspace(0.0, 1.0, per_piece + 1)).ravel()
        s = self.evaluate(t)
        return float(np.abs(s.velocity).max()), float(np.abs(s.acceleration).max()), float(np.abs(s.jerk).max())


@dataclass(kw_only=True)
class AxesPlan(Plan):
    """A plan of several actuated axes moving together (the cart with the bridge and/or the hoist, contract
    "Joints and hoisting", "The spatial crane").

    As a ``Plan`` it is the cart's reference (so everything that reads a
    cart plan reads this one); ``axes`` holds every axis's own plan by joint
    name in ``crane_msgs_py.crane.axes.AXES`` order, ``cart`` first, all of the
    same duration. The bridge's plan is relative like the cart's (``starts``
    0). The hoist's too: its displacement is L1_goal - L1_start, and
    ``starts['hoist']`` is L1_start (m), where the ROS layer and the CSV put it.
    """

    axes: dict
    starts: dict = field(default_factory=dict)

    @property
    def joint_names(self) -> tuple:
        return tuple(self.axes)

    def _evaluate(self, t):
        s = self.axes['cart'].evaluate(t)
        return s.position, s.velocity, s.acceleration, s.jerk

    def breakpoints(self) -> np.ndarray:
        return np.unique(np.concatenate([p.breakpoints() for p in self.axes.values()]))

    def peaks(self, *args) -> tuple[float, float, float]:
        return self.axes['cart'].peaks(*args)

    def evaluate_axis(self, name: str, t) -> Samples:
        """``name``'s samples at ``t``, its start added (the hoist's: the rope length in m)."""
        s = self.axes[name].evaluate(t)
        start = self.starts.get(name, 0.0)
        return Samples(s.t, s.position + start, s.velocity, s.acceleration, s.jerk)
