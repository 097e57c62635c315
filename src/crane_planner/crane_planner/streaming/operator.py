"""The streamer's operator mode: a joystick's velocity command, jerk-limited and shaped online at every tick.

Each tick the newest command (a velocity per axis: the cart's, the bridge's,
the hoist's, + = the rope longer) goes to ruckig's velocity interface, which
gives every axis a jerk-limited time-optimal profile within its limits: the
*base*. A command older than ``cmd_timeout`` counts as zero, so a lost
joystick stops the crane. Each travel axis's base is then shaped online (the
same shaper: the swing's modes are the same in both horizontal directions):
the published reference is
sum_i A_i b(t - t_i) over the impulses of ``design(shaper, omegas)``, read
from a buffer of the base's past ticks (quintic Hermite between two ticks,
so a delay need not be a whole number of ticks). The shaper follows the
rope: its frequencies are the linearized crane's at the hoist's length
every tick (length-adaptive), and the hoist's own base is not shaped (at
rest, hoisting does not excite the swing of the linear model). A shaper
whose first impulse is at 0 changes the reference on the tick after the
command arrives.

``OperatorStream`` is the operator mode's ``source.Source``: ``sample`` is
called by the streamer's loop; ``command`` and ``stop`` from its executor
(a tuple assignment: no lock). The runway guard, in the loop, asks how far an
axis would travel were the stick released now (``stopping_travel``: the base's
braking within the axis's limits plus what the shaper still owes, exactly)
and holds the command of an axis at zero towards a crane it refuses
(``refuse``). Pure Python, no ROS import.
"""
from __future__ import annotations

import math
import time
from operator import attrgetter

import numpy as np

from crane_msgs_py.crane.axes import CART, HOIST, axis, check_axes
from crane_msgs_py.crane.braking import stopping_distance
from crane_msgs_py.crane.params import CraneParams

from ..planning.model import modal_properties
from ..planning.plan import PlanError
from ..planning.shapers import SHAPERS, design
from .hermite import segment, segment_values
from .source import Setpoint

#: ``operator_shaper`` values: a shaper of ``planning.shapers``, or ``none`` (rate limits only).
OPERATOR_SHAPERS = ('none', *SHAPERS)
#: Seconds of base history kept: more than any shaper of a rope up to 100 m long needs.
HISTORY = 60.0
#: The rope length (m) is redesigned for when it has changed by more than this.
LENGTH_STEP = 1e-4


def twist_velocities(twist, joints) -> tuple:
    """The velocity of each of ``joints`` a ``geometry_msgs/Twist`` commands: its axis's ``cmd_vel`` field times
    its ``cmd_vel_sign`` (the hoist's position is the rope's length: + up shortens it)."""
    return tuple(axis(j).cmd_vel_sign * float(attrgetter(axis(j).cmd_vel)(twist)) for j in joints)


class OperatorStream:
    """Velocity commands to a shaped, jerk-limited reference, one tick at a time.

    Args:
        period: tick period (s).
        start: the axes' positions (m) to start from at rest, in ``joints`` order (the hoist's: its length).
        limits: an ``AxisLimits`` per axis (``crane_msgs_py.crane.axes``), each with a finite velocity and
            acceleration limit (ruckig needs them); no jerk limit = none.
        joints: the axes' names (``crane_msgs_py.crane.axes``, in its order); default (cart,) or (cart, hoist)
            by the length of ``start``.
        shaper: one of ``OPERATOR_SHAPERS``.
        params: the crane model the shaper is designed on (L1 = the rope length without a hoist).
        cmd_timeout: a command older than this (s) counts as zero.
        hoist_range: (shortest, longest) rope length (m) the hoist may reach.
        clock: the time (s) commands are stamped with (monotonic by default).
    """

    def __init__(self, period: float, start, limits, shaper: str, params: CraneParams, cmd_timeout: float = 0.5,
                 hoist_range: tuple = (0.05, math.inf), clock=time.monotonic, joints=None):
        from ruckig import ControlInterface, InputParameter, OutputParameter, Ruckig
        if shaper not in OPERATOR_SHAPERS:
            raise PlanError(f'operator_shaper must be one of {", ".join(OPERATOR_SHAPERS)}, got {shaper!r}')
        self.period, self.shaper, self.params, self.cmd_timeout = float(period), shaper, params, float(cmd_timeout)
        self.clock, self.hoist_range = clock, hoist_range
        start = tuple(float(x) for x in start)
        self.joints = check_axes((CART.name, HOIST.name)[:len(start)] if joints is None else joints,
                                 'operator joints')
        self.axes = len(start)
        if len(limits) != self.axes or len(self.joints) != self.axes:
            raise PlanError(f'{len(self.joints)} axes ({", ".join(self.joints)}) need a start and limits each')
        for name, lim in zip(self.joints, limits):
            lim = axis(name).limits(*lim)  # named as the axis names them
            lim.require(('max_velocity', 'max_acceleration'), 'operator mode', PlanError)
        #: the shaped axes (travel) and the hoist's index (None: no hoist)
        self._travel = [k for k, name in enumerate(self.joints) if axis(name).kind == 'travel']
        self._hoist = self.joints.index(HOIST.name) if HOIST.name in self.joints else None
        self.limits = tuple(limits)
        self._otg = Ruckig(self.axes, self.period)
        inp = self._input = InputParameter(self.axes)
        inp.control_interface = ControlInterface.Velocity
        inp.current_position, inp.current_velocity, inp.current_acceleration = list(start), [0.0] * self.axes, \
            [0.0] * self.axes
        inp.target_velocity, inp.target_acceleration = [0.0] * self.axes, [0.0] * self.axes
        inp.max_velocity = [lim.max_velocity for lim in self.limits]
        inp.max_acceleration = [lim.max_acceleration for lim in self.limits]
        inp.max_jerk = [math.inf if lim.max_jerk is None else lim.max_jerk for lim in self.limits]
        self._output = OutputParameter(self.axes)
        self._command = (0.0, (0.0,) * self.axes)  # (time s, velocity per axis)
        n = int(math.ceil(HISTORY / self.period)) + 2
        self._base = np.zeros((n, len(self._travel), 3))  # each travel axis's base (p, v, a) per tick, a ring
        self._base[:, :, 0] = [start[k] for k in self._travel]
        self._n, self._k = n, 0  # ring size, ticks sampled
        self._length = None
        self._impulses = (np.ones(1), np.zeros(1))  # amplitudes, delays (ticks)
        self._blocked = 0  # the direction the hoist is stopped in at a bound of its range (-1, 0, 1)
        self._moved = -(10 ** 9)  # the last tick a travel axis's base moved (never yet)
        self._now = (list(start), [0.0] * self.axes, [0.0] * self.axes)  # the base's (p, v, a) at the last tick
        self._refused: tuple = ()  # (axis, directions) whose command is held at zero (``refuse``)
        self.position = start

    # -- inputs (the executor) ---------------------------------------------------------------

    def command(self, *velocity: float, now: float | None = None) -> None:
        """The joystick's velocity per axis of ``joints`` (m/s; the hoist's: its length's rate)."""
        v = tuple(float(x) if math.isfinite(float(x)) else 0.0 for x in velocity)[:self.axes]
        self._command = (self.clock() if now is None else now, v + (0.0,) * (self.axes - len(v)))

    def stop(self) -> None:
        """Zero velocity from now on (until the next command)."""
        self._command = (self.clock(), (0.0,) * self.axes)

    # -- the runway guard (the loop) -------------------------------------------------------------

    def refuse(self, index: int, directions) -> None:
        """Hold axis ``index``'s command at zero while it points along one of ``directions`` (+1.0, -1.0: the
        signs of its velocity), from the next tick on; none: every command taken again."""
        self._refused = (index, directions) if directions else ()

    def stopping_travel(self, index: int) -> float:
        """How far (m, signed) axis ``index``'s reference travels from its last tick if the command of that
        axis became zero now: what the shaper still owes of the base (the base less the shaped reference: the
        shaper's amplitudes sum to 1) and the base's braking within the axis's limits, the time-optimal
        jerk-limited stop ruckig runs (``crane_msgs_py.crane.braking``)."""
        p, v, a = self._now
        limit = self.limits[index]
        jerk = limit.max_jerk or 1e9  # (ruckig without a jerk limit: a step of the acceleration)
        return p[index] - self.position[index] + stopping_distance(v[index], a[index], limit.max_acceleration, jerk)

    # -- the loop ---------------------------------------------------------------------------------

    def target(self, now: float) -> list:
        """The velocity each axis is steered to: the command, zero once stale; the hoist kept in its range."""
        stamp, velocity = self._command
        if now - stamp > self.cmd_timeout:
            return [0.0] * self.axes
        target = [max(-lim.max_velocity, min(lim.max_velocity, v)) for v, lim in zip(velocity, self.limits)]
        if self._refused:
            index, directions = self._refused
            if target[index] and math.copysign(1.0, target[index]) in directions:
                target[index] = 0.0
        h = self._hoist
        if h is not None:  # stop the rope where braking from its rate ends at the range's bound
            inp = self._input
            length, rate = inp.current_position[h], abs(inp.current_velocity[h])
            limit = self.limits[h]
            # braking from the rate at the acceleration limit, reached at the jerk limit; once braking for a
            # bound, the hoist stays stopped until the stick points away from it (else it would creep on)
            accel, jerk = limit.max_acceleration, limit.max_jerk or math.inf
            margin = rate * (rate / accel + accel / jerk) / 2 + rate * self.period * 2
            direction = (target[h] > 0.0) - (target[h] < 0.0)
            at_bound = (direction < 0 and length - margin <= self.hoist_range[0]) or (
                direction > 0 and length + margin >= self.hoist_range[1])
            if direction and (at_bound or direction == self._blocked):
                target[h], self._blocked = 0.0, direction
            else:
                self._blocked = 0
        return target

    def sample(self, tick: int | None = None, now: float | None = None) -> Setpoint:
        """The next tick's reference: (position, velocity, acceleration), floats with one axis, else tuples in
        ``joints`` order. Every call is the tick after the last (``tick``, the loop's, is not needed);
        ``now``: the time (s) of the commands' clock (default: now)."""
        inp, out = self._input, self._output
        inp.target_velocity = self.target(self.clock() if now is None else now)
        self._otg.update(inp, out)
        out.pass_to_input(inp)
        p, v, a = out.new_position, out.new_velocity, out.new_acceleration
        self._now = (p, v, a)
        k = self._k = self._k + 1
        ring = self._base[k % self._n]
        for i, j in enumerate(self._travel):
            ring[i] = (p[j], v[j], a[j])
            if abs(v[j]) > 1e-12 or abs(a[j]) > 1e-12:
                self._moved = k
        if self._hoist is not None:
            self._redesign(p[self._hoist])
        shaped = self._shaped(k)
        out = [(p[j], v[j], a[j]) for j in range(self.axes)]  # the hoist's base as it is
        for i, j in enumerate(self._travel):
            out[j] = shaped[i]
        self.position = tuple(o[0] for o in out)
        if self.axes == 1:
            return Setpoint(*out[0])
        return Setpoint(*zip(*out))

    @property
    def at_rest(self) -> bool:
        """Whether the base is at rest and the shaper has played it out (the reference is still); O(1), the
        loop asks it every state tick."""
        inp = self._input
        if any(abs(x) > 1e-12 for x in (*inp.current_velocity, *inp.current_acceleration)):
            return False
        return self._k - self._moved > self._impulses[1][-1] + 2

    @property
    def moving(self) -> bool:
        """Whether the reference moves (not at rest)."""
        return not self.at_rest

    def delay(self) -> float:
        """The shaper's length now (s): how long after the base the reference comes to rest."""
        return float(self._impulses[1][-1]) * self.period

    # -- the shaper ---------------------------------------------------------------------------------

    def design_for(self, length: float) -> None:
        """Design the shaper for the rope length ``length`` (m) (done every tick with a hoist)."""
        self._length = length
        if self.shaper == 'none':
            self._impulses = (np.ones(1), np.zeros(1))
            return
        omegas, zetas = modal_properties(self.params.replace(L1=length))
        s = design(self.shaper, omegas, zetas)
        self._impulses = (np.array(s.amplitudes), np.array(s.times) / self.period)

    def _redesign(self, length: float) -> None:
        if self._length is None or abs(length - self._length) > LENGTH_STEP:
            self.design_for(length)

    def _shaped(self, k: int) -> list:
        """Each travel axis's shaped (p, v, a) at tick ``k``."""
        if self._length is None:
            self.design_for(self.params.L1)
        return [self._shaped_axis(k, i) for i in range(len(self._travel))]

    def _shaped_axis(self, k: int, i: int) -> tuple:
        amplitudes, delays = self._impulses
        p = v = a = 0.0
        base, n, h = self._base[:, i], self._n, self.period
        first = k - n + 2  # the oldest tick kept
        for A, d in zip(amplitudes, delays):
            t = k - d  # the base's time (ticks) this impulse reads
            j = math.floor(t)
            if j < first:  # before what is kept: the oldest (the base was at rest there)
                x = base[first % n]
                p, v, a = p + A * x[0], v + A * x[1], a + A * x[2]
                continue
            s = t - j
            x0 = base[j % n]
            if s < 1e-9:
                p, v, a = p + A * x0[0], v + A * x0[1], a + A * x0[2]
                continue
            x1 = base[(j + 1) % n]
            hp, hv, ha, _ = segment_values(segment(x0[0], x1[0], x0[1], x1[1], x0[2], x1[2], h), s, h)
            p, v, a = p + A * hp, v + A * hv, a + A * ha
        return p, v, a

