"""Motion from any state (beyond the paper): a new goal mid-move, a stop, damping a swinging load.

The variational formulation takes any initial state: its boundary conditions
are just numbers (``Problem.boundary``). A plan from a state starts where the
reference is at the handover (each axis's position, velocity, acceleration:
an ``AxisState``) with the swing there, and ends at rest at a goal, or
anywhere (a stop, ``free_end``), or where it started (a settle). ``MotionState`` is that state;
``problem_start`` turns it into the problem's states (the servo's lag
included); ``predict`` carries a measured state forward along a known
reference to the handover with the planning model.

Every axis the crane has is planned from its state together: with a bridge
on the spatial crane (``dynamics.spatial_swing``), the state's swing then
the eight states (theta1, theta2, phi1, phi2 and their rates) in
``dynamics.crane_ode``'s order, the planar crane's four otherwise
(``signals.Swing``). The cart's swing is theta's, the bridge's phi's
(``Problem.parameters`` scales them so).

Shapers cannot start from a swing they did not cause. What they can do is
shape a *change*: the linear crane's response to sum_i A_i q(t - t_i) is
zero after the shaper for every rest-to-rest q, and a change of the command
at t_h is such a q starting at t_h, so ``Continuation`` (the running
reference, continued, plus the shaped change) still leaves no swing on the
linear model. A stop is such a change too: the base command brought to rest
as fast as the limits allow from where it is at t_h (``shaped_stop``), which
needs the running plan's own base and shaper (a ``ShapedPlan``).

Pure Python, no ROS import.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from crane_msgs_py.crane.axes import AXIS_NAMES, BRIDGE, CART, HOIST, axis
from crane_msgs_py.crane.params import CraneParams

from .dynamics import PARAMETERS, crane_ode
from .model import modal_frequencies
from .plan import Plan, PlanError
from .problem import AXIS_STATES, Form
from .profiles import BaseProfile, ruckig_pieces
from .shaped import ShapedPlan
from .signals import Swing, check_swing


@dataclass(frozen=True)
class AxisState:
    """One axis's reference at one instant, and how far the actual axis lags it (SI, the axis's unit).

    Attributes:
        position: the reference's position (m; the hoist's: the rope length L1).
        velocity, acceleration: the reference's (m/s, m/s^2).
        lag: the actual axis's position less the reference's (m); None = steady
            tracking by the axis's servo tau y' + y = y_ref (Eq. 6), i.e.
            -tau (v - tau a).
    """

    position: float = 0.0
    velocity: float = 0.0
    acceleration: float = 0.0
    lag: float | None = None

    def __post_init__(self):
        for name in ('position', 'velocity', 'acceleration', 'lag'):
            value = getattr(self, name)
            if value is not None or name != 'lag':
                if not math.isfinite(float(value)):
                    raise PlanError('a motion state must be finite')
                object.__setattr__(self, name, float(value))


@dataclass(frozen=True)
class MotionState:
    """The crane at one instant, SI units.

    Attributes:
        axes: each axis's ``AxisState`` by its name (``crane_msgs_py.crane.axes``), kept in
            ``AXES`` order; the cart's always, the others' if the crane has them.
        swing: the load's ``Swing``: the planar crane's, with a bridge the spatial crane's (phi too);
            None = the load hanging still.
    """

    axes: dict[str, AxisState] = field(default_factory=lambda: {CART.name: AxisState()})
    swing: Swing | None = None

    def __post_init__(self):
        axes = dict(self.axes)
        if CART.name not in axes or any(n not in AXIS_NAMES for n in axes) \
                or not all(isinstance(s, AxisState) for s in axes.values()):
            raise PlanError(f'a motion state needs the {CART.name}\'s AxisState, optionally those of '
                            f'{", ".join(AXIS_NAMES[1:])}')
        spatial = BRIDGE.name in axes
        swing = check_swing(self.swing, spatial, f'a motion state {"with" if spatial else "without"} a {BRIDGE.name}')
        object.__setattr__(self, 'axes', {n: axes[n] for n in AXIS_NAMES if n in axes})
        object.__setattr__(self, 'swing', swing)

    def has(self, name: str) -> bool:
        """Whether the crane has the axis ``name`` in this state."""
        return name in self.axes

    def axis(self, name: str) -> AxisState:
        """The axis ``name``'s state; PlanError if the state has none."""
        try:
            return self.axes[name]
        except KeyError:
            raise PlanError(f'the motion state has no {name} axis (it has {", ".join(self.axes)})') from None

    @property
    def at_rest(self) -> bool:
        """Whether every axis and the swing are still (to 1e-9)."""
        moving = [*self.swing.values(), *(x for s in self.axes.values() for x in (s.velocity, s.acceleration))]
        return max(abs(x) for x in moving) < 1e-9


#: Each axis's servo time constant (Eq. 6) among ``CraneParams``' fields (the bridge's servo is the cart's:
#: ``dynamics.crane_ode``).
SERVO_CONSTANTS = {CART.name: 'tau', BRIDGE.name: 'tau', HOIST.name: 'tau_hoist'}


def _servo_start(p_lag: float | None, v: float, a: float, tau: float) -> tuple[float, float, float]:
    """(position less the reference's, velocity, acceleration) of an axis whose reference moves at (v, a).

    The servo tau y' + y = y_ref of Eq. 6 (its derivatives give the model's
    tau a' + a = a_ref): with the lag y - y_ref known the actual velocity is
    -lag / tau and the acceleration (v_ref - velocity) / tau; steady tracking
    (lag None) has the velocity v - tau a.
    """
    if tau == 0.0:
        return 0.0, v, a
    velocity = v - tau * a if p_lag is None else -p_lag / tau
    lag = -tau * velocity if p_lag is None else p_lag
    return lag, velocity, (v - velocity) / tau


def problem_start(state: MotionState, params: CraneParams) -> tuple[dict, CraneParams]:
    """(start, params): the problem's states at the start (SI, by name, ``Problem.boundary``) and the model.

    Each axis's states (``problem.AXIS_STATES``) start as its servo (Eq. 6)
    tracks its reference then; a travelling axis's position is relative to
    its reference's position. The hoist's is the model's L1: the actual rope
    length then (the hoist's h starts at 0), so the plan's hoist reference,
    L1 + h + tau_hoist h', starts at the reference's length.
    """
    start = {}
    for name, s in state.axes.items():
        y, v, a, a_ref = AXIS_STATES[name]
        lag, velocity, acceleration = _servo_start(s.lag, s.velocity, s.acceleration,
                                                   getattr(params, SERVO_CONSTANTS[name]))
        start.update({y: lag, v: velocity, a: acceleration, a_ref: s.acceleration})
        if axis(name).kind == 'hoist':  # the model's L1 is the actual rope length: h starts at 0
            start[y] = 0.0
            if not s.position + lag > 0.0:
                raise PlanError(f'the rope length must be > 0 m, got {s.position + lag:g} m')
            params = params.replace(L1=s.position + lag)
    start.update(state.swing.states())
    return start, params


# -- prediction ----------------------------------------------------------------------------------------------


#: RK4 steps of one CasADi call of the predictor (``_rk4_steps``): a call from Python costs as much as many
#: steps, so the steps are batched per call.
CHUNK = 64


@functools.lru_cache(maxsize=None)
def _rk4_steps(form: Form) -> tuple[ca.Function, tuple]:
    """(steps, state names): ``CHUNK`` classic RK4 steps of the planning model in one call, x0 and the
    reference jerk per axis at each step's t, t + h/2 and t + h (columns) in, the state after them out."""
    ode = crane_ode(form.servo, form.hoist, form.hoist_servo, form.bridge)
    f = ode.function()
    u0, um, u1 = (ca.SX.sym(n, ode.u.shape[0]) for n in ('u0', 'um', 'u1'))
    h = ca.SX.sym('h')
    x, p = ode.x, ode.p
    k1 = f(x, u0, p)
    k2 = f(x + h / 2 * k1, um, p)
    k3 = f(x + h / 2 * k2, um, p)
    k4 = f(x + h * k3, u1, p)
    step = ca.Function('rk4', [x, ca.vertcat(u0, um, u1), p, h], [x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)])
    return step.mapaccum('rk4_steps', CHUNK, [0], [0]), ode.states


def predict(measured: MotionState, reference, t_measured: float, t_handover: float, params: CraneParams,
            step: float = 1e-3) -> MotionState:
    """The state at ``t_handover`` (s) of a crane measured at ``t_measured``, driven meanwhile by ``reference``.

    ``measured`` holds each axis's reference at ``t_measured`` with the
    actual axis (its ``lag``) and the measured swing; ``reference(t)``
    gives the reference's (position, velocity, acceleration, jerk) per axis
    at the times ``t`` (an array), a list in ``measured.axes``' order (the cart's first). The planning model
    (``dynamics.crane_ode``, Eqs. 18-19 with the servo of Eq. 6, the hoist's
    Lagrangian with one) is integrated by RK4 with the reference's jerk as
    input; with a bridge the spatial crane's (``dynamics.spatial_swing``).
    With ``t_handover`` before ``t_measured`` the measured state is taken as it
    is (a measurement newer than the handover).
    """
    bridge = measured.has(BRIDGE.name)
    form = Form.of(params, measured.has(HOIST.name), bridge)
    start, model = problem_start(measured, params)
    rk4, names = _rk4_steps(form)
    values = model.as_dict()
    p = np.array([values[k] for k in PARAMETERS])
    x = np.array([start.get(n, 0.0) for n in names])
    span = t_handover - t_measured
    n = max(0, int(math.ceil(span / step / CHUNK - 1e-9))) * CHUNK  # whole chunks of steps <= step
    h = span / n if n else 0.0
    if n:  # the reference's jerk at every stage time, in one call
        jerk = np.array([r[3] for r in reference(t_measured + h / 2 * np.arange(2 * n + 1))])[:len(measured.axes)]
        u = np.vstack([jerk[:, 0:-1:2], jerk[:, 1::2], jerk[:, 2::2]])  # (3 axes-blocks, n) per step
        for k in range(0, n, CHUNK):
            x = np.asarray(rk4(x, u[:, k:k + CHUNK], p, h))[:, -1]  # (the state after every step: the last)
    s = dict(zip(names, x))
    refs = reference(np.array([t_handover])) if n else None
    swing = Swing.of(s, bridge)
    axes = {}
    for k, (name, was) in enumerate(measured.axes.items()):
        ref = tuple(float(r[0]) for r in refs[k][:3]) if n else (was.position, was.velocity, was.acceleration)
        # the lags only if the measurement gave them: derived from integrated positions they carry the
        # integration's error over tau (velocity) and tau^2 (acceleration); steady tracking does not
        position = s[AXIS_STATES[name][0]]
        if was.lag is None:
            lag = None
        elif axis(name).kind == 'hoist':  # the rope is L1 + h, the model's L1 its actual length at t_measured
            lag = model.L1 + position - ref[0]
        else:  # model positions are relative to the reference at t_measured: the lag is y - (p_h - p_m)
            lag = position - (ref[0] - was.position)
        axes[name] = AxisState(*ref, lag)
    return MotionState(axes, swing)


# -- how long a stop and a settle take --------------------------------------------------------------------


def first_period(params: CraneParams, length: float | None = None) -> float:
    """The first mode's period (s) of the linearized crane (at the rope length ``length``, default L1)."""
    model = params if length is None else params.replace(L1=length)
    return 2.0 * math.pi / modal_frequencies(model)[0]


def _braking(position: float, velocity: float, acceleration: float, max_acceleration: float,
             max_jerk: float | None):
    """Ruckig's ``Trajectory`` bringing a reference at (p, v, a) to rest as fast as |a| <= max_acceleration
    (or the acceleration it has) and |jerk| <= max_jerk allow: its velocity interface, jerk-limited and
    time-optimal."""
    from ruckig import ControlInterface, InputParameter, Result, Ruckig, Trajectory
    inp = InputParameter(1)
    inp.control_interface = ControlInterface.Velocity
    inp.current_position, inp.current_velocity, inp.current_acceleration = [position], [velocity], [acceleration]
    inp.target_velocity, inp.target_acceleration = [0.0], [0.0]
    inp.max_velocity = [1e9]
    inp.max_acceleration = [max(max_acceleration, abs(acceleration))]
    inp.max_jerk = [max_jerk if max_jerk is not None else math.inf]
    trajectory = Trajectory(1)
    result = Ruckig(1).calculate(inp, trajectory)
    if result not in (Result.Working, Result.Finished):
        raise PlanError(f'no stop profile from v={velocity:g} m/s, a={acceleration:g} m/s^2 (ruckig: {result})')
    return trajectory


def braking_time(velocity: float, acceleration: float, max_acceleration: float, max_jerk: float | None) -> float:
    """Shortest time (s) to bring a reference moving at (v, a) to rest within |a| <= max_acceleration and
    |jerk| <= max_jerk (``_braking``)."""
    return float(_braking(0.0, velocity, acceleration, max_acceleration, max_jerk).duration)


# -- shapers: shaping a change ---------------------------------------------------------------------------


@dataclass(kw_only=True)
class Continuation(Plan):
    """A running reference continued from its time ``t0`` (t = 0 here), plus a ``change`` starting then.

    Positions are relative to the running reference's at t0 (like every
    plan's, they start at 0). ``change`` is a rest-to-rest plan (a shaped
    change of the command) or None; the whole lasts until both have ended.
    """

    running: Plan
    t0: float
    change: Plan | None = None
    _origin: float = field(init=False, repr=False)

    def __post_init__(self):
        self._origin = float(self.running.evaluate(self.t0).position[0])

    @classmethod
    def of(cls, method: str, running: Plan, t0: float, change: Plan | None, info: dict | None = None):
        duration = max(running.duration - t0, change.duration if change is not None else 0.0)
        end = running.evaluate(running.duration).position[0]
        plan = cls(method=method, displacement=0.0, duration=float(duration), info=dict(info or {}),
                   running=running, t0=float(t0), change=change)
        plan.displacement = float(end - plan._origin + (change.displacement if change is not None else 0.0))
        return plan

    def breakpoints(self) -> np.ndarray:
        b = [self.running.breakpoints() - self.t0] + ([self.change.breakpoints()] if self.change else [])
        b = np.concatenate(b + [[0.0, self.duration]])
        return np.unique(b[(b >= 0.0) & (b <= self.duration)])

    @property
    def quintic_pieces(self) -> bool:
        return self.running.quintic_pieces and (self.change is None or self.change.quintic_pieces)

    def _evaluate(self, t):
        r = self.running.evaluate(t + self.t0)
        out = [r.position - self._origin, r.velocity, r.acceleration, r.jerk]
        if self.change is not None:
            c = self.change.evaluate(t)
            out = [x + y for x, y in zip(out, (c.position, c.velocity, c.acceleration, c.jerk))]
        return tuple(out)


def shaped_stop(running: ShapedPlan, t0: float, max_acceleration: float, max_jerk: float | None) -> ShapedPlan:
    """The shaped plan whose base is ``running``'s until ``t0`` and then brought to rest as fast as
    |a| <= max_acceleration, |jerk| <= max_jerk allow (ruckig); the same as ``running`` before t0.

    Its reference is sum_i A_i q'(t - t_i) with q' a rest-to-rest base, so it
    leaves no swing on the linear model; it is returned in ``running``'s time
    (``Continuation`` shifts it to the handover).
    """
    base = running.base
    if t0 >= base.duration:  # the base has arrived: the shaper finishes by itself
        return running
    k = int(base.piece(np.array([t0]))[0])
    c = base.taylor(np.array([t0]), np.array([k]))[0]  # position Taylor coefficients at t0 (with 1/k!)
    trajectory = _braking(c[0], c[1], 2.0 * c[2], max_acceleration, max_jerk)
    starts, stop = ruckig_pieces(trajectory)
    before = base.breaks < t0
    end = float(trajectory.at_time(trajectory.duration)[0][0])
    duration = t0 + float(trajectory.duration)
    breaks = np.concatenate([base.breaks[before], t0 + starts])
    coefficients = np.concatenate([base.coefficients[before], stop]) if stop.size else base.coefficients[before]
    if breaks.size == 0 or breaks[0] != 0.0:
        raise PlanError('the shaped base has no piece before the stop')
    new_base = BaseProfile(base.kind, end, duration, breaks, coefficients)
    shaped = ShapedPlan(method=running.method, displacement=end, duration=duration + running.shaper.duration,
                        info=dict(running.info, stop={'at_s': t0, 'base_end_m': end}), shaper=running.shaper,
                        base=new_base)
    return shaped


def shaped_change(plan_change, running: Plan, t0: float, change: float, duration: float,
                  info: dict | None = None) -> Continuation:
    """``running`` continued from ``t0`` plus the shaped change of the goal by ``change`` (m) over
    ``duration`` (s): ``plan_change(change, duration)`` makes the shaped rest-to-rest plan of the change, whose
    info (the shaper's design) the continuation carries with ``info``."""
    shaped = plan_change(change, duration) if change != 0.0 else None
    if shaped is None:
        return Continuation.of(running.method, running, t0, None, info)
    return Continuation.of(shaped.method, running, t0, shaped, dict(shaped.info, **(info or {})))

