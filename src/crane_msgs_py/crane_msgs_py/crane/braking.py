"""The time-optimal jerk-limited braking of one axis to rest, in closed form.

A drive that loses its setpoints runs its fault reaction: a quick stop
along a deceleration ramp. Here that ramp is the fastest way from velocity
``v0`` and acceleration ``a0`` to ``v = 0, a = 0`` with ``|a| <= D`` and
``|jerk| <= J``. The velocity is then the position of a double integrator
whose velocity (the acceleration) is bounded and whose input (the jerk) is
bounded; its time-optimal control is bang-bang in the jerk with a bounded
arc, so the braking has at most three phases, in this order:

1. **jerk +-J**: the acceleration goes from ``a0`` to the braking
   acceleration ``-s A`` (``s`` the braking direction below, ``A <= D`` the
   peak deceleration). With ``a0`` beyond D against the motion this first
   brings ``|a|`` back to D at the jerk limit; beyond D along the motion the
   same ramp passes D on its way down.
2. **constant acceleration** ``-s D``: only when D is reached (``A = D``);
   absent for a short stop, whose jerk profile is triangular (``A < D``).
3. **jerk s J**: the acceleration returns from ``-s A`` to 0 just as the
   velocity reaches 0.

The direction ``s`` is the sign of ``v0 + a0 |a0| / (2 J)``, the velocity
left after bringing ``a0`` straight to 0 at the jerk limit: that is what the
braking must remove (with ``v0 = 0`` and ``a0 != 0`` it is ``a0``'s own
sign). The phases' lengths follow from the velocity reaching 0 with the
acceleration. This is the profile ruckig computes numerically for its
velocity interface with target velocity and acceleration 0
(Berscheid and Kroeger, "Jerk-limited Real-time Trajectory Generation with
Arbitrary Target States", RSS 2021); the tests compare the two.

SI units (m, s) for a travelling axis; any unit for another (rad, say).
Pure Python, no ROS import: the sim's fault reaction and the streamer both
use it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from crane_msgs_py.crane.params import ParameterError, check_finite, check_positive


@dataclass(frozen=True)
class Phase:
    """One phase of a braking: ``duration`` (s) at constant ``jerk`` (m/s^3), starting at ``start`` (s) in the
    state ``position`` (m, from the braking's start), ``velocity`` (m/s), ``acceleration`` (m/s^2)."""

    start: float
    duration: float
    jerk: float
    position: float
    velocity: float
    acceleration: float

    def at(self, dt: float) -> tuple[float, float, float]:
        """(position, velocity, acceleration) ``dt`` s into the phase: the cubic of constant jerk."""
        j, a, v = self.jerk, self.acceleration, self.velocity
        return (self.position + dt * (v + dt * (a / 2.0 + dt * j / 6.0)),
                v + dt * (a + dt * j / 2.0),
                a + dt * j)


def _phases(v0: float, a0: float, D: float, J: float) -> tuple[tuple[float, float], ...]:
    """The (duration s, jerk m/s^3) of the three phases (module docstring), some possibly of zero length."""
    s = 1.0 if v0 + a0 * abs(a0) / (2.0 * J) >= 0.0 else -1.0  # braking direction: mirrored to s = +1 below
    u, b = s * v0, s * a0  # mirrored: the velocity left after ramping b to 0 is >= 0, braking is b < 0
    if b < -D:  # beyond D against the motion: back to -D at the jerk limit, hold it, ramp to 0
        free = u - b * b / (2.0 * J)  # (>= 0 by the choice of s) removed by the plateau at -D
        durations, jerks = ((-D - b) / J, free / D, D / J), (J, 0.0, J)
    else:
        # triangular: A^2 = J u + b^2 / 2 makes u + (b^2 - A^2) / 2J - A^2 / 2J vanish; it is >= b^2 when b <= 0
        # (s was chosen so), so the first ramp never runs backwards
        peak = math.sqrt(max(0.0, J * u + b * b / 2.0))
        if peak <= D:
            durations = ((b + peak) / J, 0.0, peak / J)
        else:  # D is reached: the plateau removes what the two ramps to and from -D leave
            durations = ((b + D) / J, (u + (b * b - 2.0 * D * D) / (2.0 * J)) / D, D / J)
        jerks = (-J, 0.0, J)
    return tuple((max(0.0, d), s * j) for d, j in zip(durations, jerks))


@dataclass(frozen=True)
class Braking:
    """The fastest stop from velocity ``v0`` (m/s) and acceleration ``a0`` (m/s^2) to rest within
    ``|a| <= D`` (m/s^2) and ``|jerk| <= J`` (m/s^3); the module docstring gives its phases.

    Times are seconds from the braking's start, positions the displacement from where it starts (m). After
    ``duration`` the axis is at rest at ``distance``. A ``ParameterError`` names a limit that is not finite
    and > 0 or a state that is not finite.
    """

    v0: float
    a0: float
    D: float
    J: float
    phases: tuple[Phase, ...] = field(init=False, repr=False)

    def __post_init__(self):
        for name in ('v0', 'a0'):
            object.__setattr__(self, name, check_finite(name, getattr(self, name)))
        for name in ('D', 'J'):
            object.__setattr__(self, name, check_positive(name, getattr(self, name)))
        phases, t, state = [], 0.0, (0.0, self.v0, self.a0)
        for duration, jerk in _phases(self.v0, self.a0, self.D, self.J):
            if duration > 0.0:  # a phase of zero length changes nothing
                phase = Phase(t, duration, jerk, *state)
                phases.append(phase)
                t += duration
                state = phase.at(duration)
        object.__setattr__(self, 'phases', tuple(phases))

    @property
    def duration(self) -> float:
        """How long the braking takes (s)."""
        last = self.phases[-1] if self.phases else None
        return last.start + last.duration if last else 0.0

    @property
    def distance(self) -> float:
        """Where it stops (m from its start): the stopping distance, signed."""
        return self.state(self.duration)[0]

    def state(self, t: float) -> tuple[float, float, float]:
        """(position m, velocity m/s, acceleration m/s^2) at ``t`` s (>= 0) after the start; at rest after
        ``duration`` (velocity and acceleration exactly 0)."""
        if not t >= 0.0:
            raise ParameterError(f'a braking starts at t = 0, got t = {t}')
        if not self.phases:
            return 0.0, 0.0, 0.0
        for phase in self.phases:
            if t < phase.start + phase.duration:
                return phase.at(t - phase.start)
        last = self.phases[-1]
        return last.at(last.duration)[0], 0.0, 0.0

    def acceleration(self, t: float) -> float:
        """Acceleration (m/s^2) at ``t`` s after the start."""
        return self.state(t)[2]

    def velocity(self, t: float) -> float:
        """Velocity (m/s) at ``t`` s after the start."""
        return self.state(t)[1]

    def position(self, t: float) -> float:
        """Displacement (m) from the start at ``t`` s after it."""
        return self.state(t)[0]


def stopping_distance(v0: float, a0: float, D: float, J: float) -> float:
    """The signed distance (m) the fastest jerk-limited stop from (``v0`` m/s, ``a0`` m/s^2) within
    ``|a| <= D`` m/s^2, ``|jerk| <= J`` m/s^3 travels: ``Braking(v0, a0, D, J).distance`` to the last bit, with
    the same arithmetic and no records (a few microseconds: the runway guard asks it every tick)."""
    if not (math.isfinite(v0) and math.isfinite(a0) and 0.0 < D < math.inf and 0.0 < J < math.inf):
        return Braking(v0, a0, D, J).distance  # (raises ParameterError naming what is wrong)
    p, v, a = 0.0, float(v0), float(a0)
    for t, j in _phases(v, a, D, J):
        if t > 0.0:  # (as Phase.at, phase after phase)
            p, v, a = p + t * (v + t * (a / 2.0 + t * j / 6.0)), v + t * (a + t * j / 2.0), a + t * j
    return p
