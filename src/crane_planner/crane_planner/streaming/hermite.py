"""Quintic Hermite interpolation of trajectory knots (position, velocity, acceleration).

Between two knots the unique quintic matching position, velocity and
acceleration at both ends; exact wherever the sampled motion is a polynomial
of degree <= 5 on the segment (a quintic base profile, any shaped copy of it
between impulse times), and C2 across knots. Like ros2_controllers'
joint_trajectory_controller the sampler is kept apart from the node, but it
is vectorized: the streamer samples a whole motion at its tick times at once.
Pure numpy, no ROS import.
"""
from __future__ import annotations

import numpy as np


def segment(p0, p1, v0, v1, a0, a1, h) -> tuple:
    """The quintic on one segment of length ``h`` (s) matching p, v, a at both ends, as coefficients of
    p(s) = sum c_i s^i with s = (t - t_k) / h in [0, 1] (the quintic Hermite basis); scalars or arrays."""
    dp = p1 - p0
    v0, v1 = h * v0, h * v1
    a0, a1 = h * h * a0, h * h * a1
    return (p0, v0, 0.5 * a0,
            10.0 * dp - 6.0 * v0 - 4.0 * v1 - 1.5 * a0 + 0.5 * a1,
            -15.0 * dp + 8.0 * v0 + 7.0 * v1 + 1.5 * a0 - a1,
            6.0 * dp - 3.0 * (v0 + v1) - 0.5 * (a0 - a1))


def segment_values(c, s, h) -> tuple:
    """Position, velocity, acceleration and jerk of the ``segment`` coefficients ``c`` at fractions ``s``."""
    c0, c1, c2, c3, c4, c5 = c
    p = c0 + s * (c1 + s * (c2 + s * (c3 + s * (c4 + s * c5))))
    v = (c1 + s * (2.0 * c2 + s * (3.0 * c3 + s * (4.0 * c4 + s * 5.0 * c5)))) / h
    a = (2.0 * c2 + s * (6.0 * c3 + s * (12.0 * c4 + s * 20.0 * c5))) / (h * h)
    j = (6.0 * c3 + s * (24.0 * c4 + s * 60.0 * c5)) / (h * h * h)
    return p, v, a, j


class QuinticHermite:
    """Interpolant through knots ``t`` (s, strictly increasing) with p, v, a at each.

    Before the first knot and after the last the end knot's state is held.
    Raises ValueError if the knots are not finite, not increasing or of
    different lengths.
    """

    def __init__(self, t, position, velocity, acceleration):
        t, p, v, a = (np.array(x, dtype=float).ravel() for x in (t, position, velocity, acceleration))
        if not t.size or not (t.size == p.size == v.size == a.size):
            raise ValueError('knots need as many positions, velocities and accelerations as times, at least one')
        if not all(np.isfinite(x).all() for x in (t, p, v, a)):
            raise ValueError('knot times and states must be finite')
        if np.any(np.diff(t) <= 0.0):
            raise ValueError('knot times must increase strictly')
        self.t, self.position, self.velocity, self.acceleration = t, p, v, a
        self._h = np.diff(t)
        self._c = np.stack(segment(p[:-1], p[1:], v[:-1], v[1:], a[:-1], a[1:], self._h))

    def __call__(self, t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position, velocity and acceleration at times ``t`` (array-like)."""
        return self.evaluate(t)[:3]

    def evaluate(self, t) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Position, velocity, acceleration and jerk at times ``t`` (array-like); the jerk is 0 outside the
        knots, and on a knot the next segment's."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        if self.t.size == 1:
            return (np.full(t.shape, self.position[0]), np.full(t.shape, self.velocity[0]),
                    np.full(t.shape, self.acceleration[0]), np.zeros(t.shape))
        # (minimum/maximum: np.clip costs more, and a handover's planning evaluates this a few times)
        tc = np.minimum(np.maximum(t, self.t[0]), self.t[-1])
        k = np.minimum(np.maximum(np.searchsorted(self.t, tc, side='right') - 1, 0), self._h.size - 1)
        h = self._h[k]
        p, v, a, j = segment_values(self._c[:, k], (tc - self.t[k]) / h, h)
        j = np.where((t < self.t[0]) | (t >= self.t[-1]), 0.0, j)
        # knots are met exactly at s = 0; the last one (s = 1) would carry rounding
        end = tc >= self.t[-1]
        if end.any():
            p[end], v[end], a[end] = self.position[-1], self.velocity[-1], self.acceleration[-1]
        return p, v, a, j


def extends(old: QuinticHermite, old_origin_ns: int, new: QuinticHermite, new_origin_ns: int) -> bool:
    """Whether ``new`` (first knot streamed at ``new_origin_ns``) ends no earlier than ``old``: a handover
    that ``splice`` may delay (one ending earlier, a stop, would go on creeping until old's end)."""
    def end(interp, origin_ns):
        return origin_ns + round((interp.t[-1] - interp.t[0]) * 1e9)
    return end(new, new_origin_ns) >= end(old, old_origin_ns)


def splice(old: QuinticHermite, old_origin_ns: int, new: QuinticHermite, new_origin_ns: int,
           at_ns: int) -> QuinticHermite:
    """``old`` with the change that ``new`` makes to it added from ``at_ns`` instead of ``new_origin_ns``.

    A handover ``new`` continues ``old`` from ``new_origin_ns`` (its first knot is old's state there); its
    change ``d(t) = new(t) - old(t)`` (old held at its end after it) starts at rest. Delayed by
    ``shift = at_ns - new_origin_ns`` >= 0 the motion is ``old(t) + d(t - shift)``: continuous with old at
    ``at_ns`` in position, velocity and acceleration, at ``new``'s end state ``shift`` later than new.
    By superposition it leaves no swing on the linear crane when old and new leave none (``d`` is the
    difference of two such references, and a delayed input's response is the delayed response): a late
    handover is delayed this way instead of refused. With ``new`` ending no earlier than ``old`` the result
    lasts exactly as long as ``new``; the sum of piecewise quintics is one between the union of the three
    knot sets, so the result is exact on those knots. Times: each interpolant's first knot is streamed at its
    origin (ROS time, ns); the result's knot times run from 0 (at ``at_ns``) to new's duration.
    """
    shift = (at_ns - new_origin_ns) * 1e-9
    into_old = old.t[0] + (at_ns - old_origin_ns) * 1e-9  # old's own time at at_ns
    duration = float(new.t[-1] - new.t[0])
    knots = np.sort(np.concatenate(([0.0, duration], old.t - into_old, old.t - into_old + shift, new.t - new.t[0])))
    knots = knots[(knots >= 0.0) & (knots <= duration)]
    # a knot met twice (new's knots after the handover are old's) counts once
    knots = knots[np.concatenate(([True], np.diff(knots) > 1e-9))]
    knots[-1] = duration
    now, changed, before = old(into_old + knots), new(new.t[0] + knots), old(into_old - shift + knots)
    return QuinticHermite(knots, *(x + y - z for x, y, z in zip(now, changed, before)))
