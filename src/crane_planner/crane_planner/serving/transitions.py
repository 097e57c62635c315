"""Motion from any state as the planner serves it: a new goal mid-move, a stop, a settle.

The streamer streams a motion as the quintic Hermite interpolant of the knots
it was sent (``streaming.hermite``); ``Running`` is that motion as the planner
sent it, so the state the planner plans from at the handover time is exactly
the one the streamer checks the new trajectory against. The swing there is
predicted from the newest ``joint_states`` (a ``Measurement``) along the
running reference with the planning model (``continuation.predict``), or,
with no measurement, from the motion's start at rest.

Every axis the motion streams is planned from the handover together (NVF/RVF):
with a bridge on the spatial crane, from the swing measured in both
directions (``Measurement.swing``: a spatial ``Swing`` then).

Each function takes ``variational``, what runs a ``dispatch.VariationalRequest``
(``Planner.variational``, or a ``dispatch.SolverCache``). What each method
does (contract "Motion from any state"):

- a new goal: NVF/RVF plan from the handover state to rest at the goal; a
  shaper continues the running reference and adds the shaped change of the
  goal (``continuation.shaped_change``: no swing on the linear model, whatever
  the running reference was, as long as it would have ended without one). A
  shaper cannot follow a hoist's changing rope: with the hoist moving, or
  asked to move, shapers refuse and NVF/RVF serve.
- a stop: NVF (for every variational method: RVF's sensitivities forced to
  zero with a free end position make stops that wander metres) from the
  handover state to rest anywhere (``free_end``), every axis, or,
  for a motion a shaper made from rest, that shaper's base braked by ruckig
  within the axis's acceleration and jerk limits (without them, the base's
  own peaks) and reshaped (``continuation.shaped_stop``). The NVF stop is the shortest
  of a few durations (from half the first swing mode's period, or the
  braking time, ``STOP_STEPS`` apart) whose peak acceleration stays within each axis's
  acceleration limit, or (a travel axis without one) within ``STOP_BRAKING`` times the running
  motion's hardest on any travel axis: as near as the limits allow, never
  braking harder than that.
- a settle: NVF from the measured swing at rest back to the same place, over
  one first-mode period (the same lengthening); with a bridge both travel
  axes move. A shaper retargets and stops each travel axis in its own right
  (the linear crane's two planes are apart: each axis's shaped change, or its
  base braked within its own limits, leaves no swing in its plane).

Pure Python, no ROS import.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from crane_msgs_py.crane.axes import axis
from crane_msgs_py.crane.geometry import load_offset
from crane_msgs_py.crane.params import CraneParams
from crane_msgs_py.messages.names import BRIDGE_JOINT, CART_JOINT, HOIST_JOINT

from ..planning.continuation import (
    AxisState,
    Continuation,
    MotionState,
    braking_time,
    first_period,
    predict,
    problem_start,
    shaped_change,
    shaped_stop,
)
from ..planning.dispatch import PlanOptions, VariationalRequest, hoisting_options, plan
from ..planning.methods import Family, family_of, lacks
from ..planning.model import modal_frequencies
from ..planning.plan import AxesPlan, Plan, PlanError
from ..planning.shaped import ShapedPlan
from ..planning.signals import Swing, check_swing
from ..streaming.hermite import QuinticHermite, extends, splice
from .moves import with_axes_held

#: How many times a settle is lengthened by ``LENGTHEN`` when it does not solve within the limits.
ATTEMPTS = 4
LENGTHEN = 1.25
#: A stop without an acceleration limit brakes at most this many times the running motion's peak acceleration.
STOP_BRAKING = 2.0
#: A stop's durations tried: from this fraction of the first mode's period (or the braking time if longer),
#: ``STOP_STEPS`` times longer each, ``STOP_TRIES`` of them; the first within the braking target is taken.
STOP_SHORTEST = 0.5
STOP_STEPS = 1.15
STOP_TRIES = 10
#: Each of a stop's tries is solved within at most this long (s), whatever ``max_solve_time`` allows: a stop is
#: worth having within its lead, and a try that cannot be solved (too short: IPOPT proves it infeasible only
#: after seconds, with a hoist) must not hold the ones after it.
STOP_SOLVE_TIME = 1.0
#: The newest measurement must be at most this old (s) when a handover is planned (a settle needs one).
MEASUREMENT_AGE = 0.5
#: The swing at a handover is predicted from the newest measurement if that is at most MEASUREMENT_AGE plus
#: this (s) before it, else from the model alone: the handover lies up to its lead ahead (more when planned
#: again further ahead on a loaded host), and the model predicts the measured swing along the reference
#: for seconds (a swing measured falling back to the model's own, none at rest, was left undamped).
HANDOVER_PREDICTION = 2.0


@dataclass(frozen=True)
class JointReading:
    """One actuated joint in ``joint_states``: its position (m; the hoist's: the rope length L1) and its
    velocity (m/s)."""

    position: float
    velocity: float = 0.0


@dataclass(frozen=True)
class Measurement:
    """``joint_states`` at ``stamp_ns``: each actuated joint's ``JointReading`` by its name (the cart's, and
    those of the other axes the crane has) and the load's ``Swing``: the planar crane's, with a bridge the
    spatial crane's (phi too)."""

    stamp_ns: int
    joints: dict[str, JointReading]
    swing: Swing

    def __post_init__(self):
        object.__setattr__(self, 'swing', check_swing(self.swing, BRIDGE_JOINT in self.joints,
                                                      f'a measurement of the joints {", ".join(self.joints)}'))

    @classmethod
    def at_rest(cls, stamp_ns: int, positions: dict) -> 'Measurement':
        """The joints at rest at ``positions`` (m, by name), the load hanging still."""
        joints = {name: JointReading(float(p)) for name, p in positions.items()}
        return cls(stamp_ns, joints, Swing.rest(BRIDGE_JOINT in joints))


class KnotPlan(Plan):
    """A joint's knots as the streamer interpolates them, as a ``Plan`` in the motion's time (t = 0 at the
    first knot), positions absolute (m)."""

    def __init__(self, interp: QuinticHermite, method: str = ''):
        super().__init__(method=method, displacement=float(interp.position[-1]),
                         duration=float(interp.t[-1] - interp.t[0]))
        self.interp = interp

    def breakpoints(self) -> np.ndarray:
        return self.interp.t - self.interp.t[0]

    @property
    def quintic_pieces(self) -> bool:
        return True

    def _evaluate(self, t):
        return self.interp.evaluate(t + self.interp.t[0])


class Running:
    """A motion sent to the streamer: its joints' knots and the ROS time (ns) of its first knot.

    Args:
        joints: the joint names, the cart's first.
        t: knot times (s); position, velocity, acceleration: (knots, joints) absolute (m, m/s, m/s^2).
        origin_ns: when the first knot is streamed (the trajectory's stamp, or the motion's first tick).
        plan: the plan the knots were sampled from (relative), and its method.
    """

    def __init__(self, joints, t, position, velocity, acceleration, origin_ns: int, plan: Plan | None = None):
        self.joints = tuple(joints)
        columns = [np.asarray(x, dtype=float).reshape(len(t), -1) for x in (position, velocity, acceleration)]
        self.interps = [QuinticHermite(t, *(c[:, j] for c in columns)) for j in range(len(self.joints))]
        self.origin_ns, self.plan = int(origin_ns), plan
        self.method = plan.method if plan is not None else ''
        self.confirmed = False  # origin_ns is the streamer's own (stream_state's motion_origin), not the stamp

    @classmethod
    def of_interps(cls, joints, interps, origin_ns: int, plan: Plan | None = None) -> 'Running':
        """The motion of the streamer's interpolants (``reference_stream.Motion.interps``), first knot at
        ``origin_ns``."""
        columns = [np.column_stack([getattr(i, k) for i in interps]) for k in ('position', 'velocity', 'acceleration')]
        return cls(joints, interps[0].t, *columns, origin_ns, plan)

    @classmethod
    def holding(cls, joints, positions, now_ns: int) -> 'Running':
        """The axes held at ``positions`` (at rest) from ``now_ns`` on: what a settle starts from."""
        n = len(positions)
        p = np.array([positions, positions], dtype=float)
        return cls(joints, [0.0, 3600.0], p, np.zeros((2, n)), np.zeros((2, n)), now_ns)

    @classmethod
    def held(cls, hold: dict, joints, now_ns: int) -> 'Running':
        """The streamer's ``hold`` (positions by joint name) of those of ``joints`` it holds, at rest from
        ``now_ns`` on."""
        held = tuple(j for j in joints if j in hold)
        return cls.holding(held, [hold[j] for j in held], now_ns)

    @property
    def duration(self) -> float:
        t = self.interps[0].t
        return float(t[-1] - t[0])

    @property
    def end_ns(self) -> int:
        return self.origin_ns + round(self.duration * 1e9)

    def time_of(self, stamp_ns) -> np.ndarray:
        """The motion's time (s, from its first knot) at ROS time(s) ``stamp_ns``, as the streamer computes it."""
        return (np.asarray(stamp_ns, dtype=np.int64) - self.origin_ns) * 1e-9

    def at(self, stamp_ns) -> list:
        """Per joint (position, velocity, acceleration, jerk) at ROS time(s) ``stamp_ns``."""
        return [interp.evaluate(interp.t[0] + self.time_of(stamp_ns)) for interp in self.interps]

    def knot_plan(self, joint: str = CART_JOINT) -> KnotPlan:
        return KnotPlan(self.interps[self.joints.index(joint)], self.method)

    def moves(self, joint: str) -> bool:
        """Whether ``joint``'s reference moves in this motion (False for a joint it does not have)."""
        if joint not in self.joints:
            return False
        interp = self.interps[self.joints.index(joint)]
        return bool(np.ptp(interp.position) > 1e-9 or np.abs(interp.velocity).max() > 1e-9)

    @property
    def hoist_moves(self) -> bool:
        """Whether the hoist's reference moves in this motion."""
        return self.moves(HOIST_JOINT)


@dataclass(frozen=True)
class Trajectory:
    """A plan as sent on ``trajectory``: per joint its samples (relative, at the same times), the joints'
    start positions (m) they add to, and the stamp (ns; 0: as soon as possible)."""

    joints: tuple
    samples: list
    starts: tuple
    stamp_ns: int

    @property
    def knots(self) -> int:
        return len(self.samples[0].t)

    def running(self, origin_ns: int, plan: Plan | None = None) -> Running:
        """The motion as the streamer will interpolate the message: knot times in whole ns (as the message
        carries them), positions absolute; origin 0 (as soon as possible): learned from stream_state."""
        t = np.rint(np.asarray(self.samples[0].t, dtype=float) * 1e9).astype(np.int64) * 1e-9
        position = np.column_stack([s0 + np.asarray(s.position, dtype=float)
                                    for s, s0 in zip(self.samples, self.starts)])
        velocity, acceleration = (np.column_stack([np.asarray(getattr(s, k), dtype=float) for s in self.samples])
                                  for k in ('velocity', 'acceleration'))
        return Running(self.joints, t, position, velocity, acceleration, origin_ns, plan)


def taken_over(running: Running, new: Running, start_ns: int) -> Running:
    """The motion the streamer streams once it takes the handover ``new`` of ``running`` over at its tick
    ``start_ns`` (``stream_state``'s motion start): a handover ending no earlier than ``running`` is
    ``running`` plus its change delayed to that tick (``hermite.splice``), one ending earlier ``new`` itself
    (the streamer's rules, ``reference_stream``)."""
    if not extends(running.interps[0], running.origin_ns, new.interps[0], new.origin_ns):
        return new
    interps = [splice(old, running.origin_ns, change, new.origin_ns, start_ns)
               for old, change in zip(running.interps, new.interps)]
    return Running.of_interps(new.joints, interps, start_ns, new.plan)


def handover_state(running: Running, handover_ns: int, measured: Measurement | None,
                   params: CraneParams, swing: bool = True) -> MotionState:
    """The crane's state at ``handover_ns``: the running reference there, the swing predicted from
    ``measured`` (if it is recent, ``HANDOVER_PREDICTION``, and not after the handover) along it, else
    from the motion's start at rest (the model's own swing); the axes' servos track the reference
    steadily (``MotionState``). Without ``swing`` (what a shaper needs) the reference alone, at once."""
    if not swing:
        return MotionState(_references(running, handover_ns))
    horizon = (MEASUREMENT_AGE + HANDOVER_PREDICTION) * 1e9
    if measured is not None and 0 <= handover_ns - measured.stamp_ns <= horizon:
        # the measured swing; the axes as their servos track the reference (their lag is tau times the
        # velocity: derived from a measured position it would carry the position's error over tau^2)
        t_m = measured.stamp_ns
        state = MotionState(_references(running, t_m), measured.swing)
    else:  # the model's swing: the motion from its start, where it was at rest
        t_m = min(running.origin_ns, handover_ns)
        state = MotionState(_references(running, t_m))
    # (the model's L1 is the rope's length: the hoist's reference carries it, else the parameter)
    return predict(state, lambda t: running.at(np.round(t * 1e9).astype(np.int64)), t_m * 1e-9,
                   handover_ns * 1e-9, params)


def _references(running: Running, stamp_ns: int) -> dict:
    """Each joint's reference at ``stamp_ns`` as an ``AxisState``, the servo tracking it steadily."""
    return {name: AxisState(*(float(x[0]) for x in ref[:3])) for name, ref in zip(running.joints,
                                                                                  running.at(stamp_ns))}


def _rope(state: MotionState) -> float | None:
    """The hoist reference's rope length (m) in ``state``; None without a hoist."""
    return state.axis(HOIST_JOINT).position if state.has(HOIST_JOINT) else None


def _held(state: MotionState, planned) -> dict:
    """Where a shaper's plan of the axes ``planned`` holds each other axis of ``state``
    (``moves.with_axes_held``): the hoist at its rope length, a travel axis at its reference (0 relative to it)."""
    return {name: (s.position if name == HOIST_JOINT else 0.0) for name, s in state.axes.items()
            if name not in planned}


def _together(plans: dict) -> Plan:
    """The plans of the travel axes (by name, the cart's first) as one: the cart's alone, or an ``AxesPlan``
    lasting as long as the longest (an axis that ends sooner rests there)."""
    if len(plans) == 1:
        return plans[CART_JOINT]
    cart = plans[CART_JOINT]
    return AxesPlan(method=cart.method, displacement=cart.displacement,
                    duration=max(p.duration for p in plans.values()), info=cart.info, axes=dict(plans),
                    starts={name: 0.0 for name in plans})


def _shaped_travel(p: Plan | None) -> dict | None:
    """The shaped plan of each travel axis a shaper moved from rest in the motion ``p`` (``ShapedPlan``s, by
    name; the travel axes it held, ``moves.with_axes_held``, left out), or None if it is not such a motion."""
    axes = p.axes if isinstance(p, AxesPlan) else {CART_JOINT: p}
    travel = {name: q for name, q in axes.items() if axis(name).kind == 'travel' and q.method != 'hold'}
    shaped = CART_JOINT in travel and all(isinstance(q, ShapedPlan) for q in travel.values())
    return travel if shaped else None


def swing_of(state: MotionState, params: CraneParams) -> float:
    """The amplitude (m) of the load's swing in ``state``, as the first mode's: sqrt(|x|^2 + |x'|^2 / omega_1^2)
    of the load's horizontal offset x from below the suspension point (``crane_msgs_py.crane.geometry``'s
    ``load_offset``, whose norm is the contract's residual; the instant's alone is 0 as the load passes below).
    The planar swing is the spatial one with phi = 0. x' = (dx/dq) q' by a complex step along q' (exact to
    rounding, the kinematics written once)."""
    model = _model(params, state)
    q, dq = np.array(state.swing.angles()), np.array(state.swing.rates())
    step = 1e-20
    offset = np.array(load_offset(*(q + 1j * step * dq), model.L1, model.L2))
    rate = offset.imag / step / modal_frequencies(model)[0]
    return float(math.hypot(*offset.real, *rate))


def _model(params: CraneParams, state: MotionState) -> CraneParams:
    rope = _rope(state)
    return params if rope is None else params.replace(L1=rope)


def _variational(variational, method: str, state: MotionState, goal: dict, duration: float, params: CraneParams,
                 options: PlanOptions, free_end: bool = False) -> Plan:
    """An NVF/RVF plan from ``state`` to rest at ``goal`` (per joint, absolute) or anywhere (``free_end``),
    every axis of ``state`` planned together (with a bridge on the spatial crane).

    Each axis's displacement is from where its model starts (``problem_start``): a travelling axis's
    reference, the hoist's actual rope length (the model's L1); a free end's is where the axis's velocity
    would carry it in half the duration (the problem's scale). With a hoist RVF is robust to
    ``hoist_robust`` (``dispatch.hoisting_options``)."""
    start, model = problem_start(state, params)
    ends = {}
    for name, s in state.axes.items():
        origin = model.L1 if name == HOIST_JOINT else s.position
        ends[name] = goal.get(name, s.position) - origin if not free_end else s.velocity * duration / 2
    displacement = ends[CART_JOINT] if len(ends) == 1 else ends
    opts = hoisting_options(options) if HOIST_JOINT in ends else options
    return variational(VariationalRequest('plan', method, displacement, duration, model, opts, start, free_end))


def retarget(variational, running: Running, handover_ns: int, state: MotionState, method: str, goal: dict,
             duration: float, params: CraneParams, options: PlanOptions) -> Plan:
    """The plan from the handover (relative to the cart reference there) to rest at ``goal`` (per joint,
    absolute) in ``duration`` s from the handover; see the module docstring for what each method does."""
    if not duration > 0.0:
        raise PlanError('a goal during a motion needs a duration (> 0 s): the fastest plan is planned from rest '
                        'only')
    if lacks(method, 'start_in_motion'):
        raise PlanError(f'{method} plans from rest only: send the goal once the crane is at rest')
    if family_of(method) is not Family.SHAPER:
        return _variational(variational, method, state, goal, duration, params, options)
    rope = _rope(state)
    hoisting = running.hoist_moves or (rope is not None and abs(goal.get(HOIST_JOINT, rope) - rope) > 1e-9)
    if hoisting and lacks(method, 'retarget_while_hoisting'):
        raise PlanError(f'{method}: a shaper cannot retarget a motion while the rope length changes (its '
                        'delays follow the rope); use nvf or rvf')
    model = _model(params, state)
    t0 = float(running.time_of(handover_ns))
    knots = {name: running.knot_plan(name) for name in state.axes if axis(name).kind == 'travel'}
    # each travel axis's change of goal, from where the running motion ends: one straight shaped move of them
    changes = {name: goal.get(name, k.displacement) - k.displacement for name, k in knots.items()}
    moved = {name: d for name, d in changes.items() if name != CART_JOINT and d != 0.0}
    whole = plan(method, changes[CART_JOINT], duration, model, options, **moved) if any(changes.values()) else None
    parts = whole.axes if isinstance(whole, AxesPlan) else {CART_JOINT: whole}
    # per axis the running reference continued plus its shaped change (the linear crane's planes are apart)
    new = {name: shaped_change(lambda d, T, part=parts.get(name): part, k, t0, changes[name], duration,
                               info={'shaper_change_m': changes[name]}) for name, k in knots.items()}
    return with_axes_held(_together(new), _held(state, new))


def stop(variational, running: Running, handover_ns: int, state: MotionState, method: str, params: CraneParams,
         options: PlanOptions) -> Plan:
    """A stop from the handover to rest as near as the limits allow, without residual swing (relative plan).

    Every axis of ``state`` is planned to rest together (with a bridge both travel axes on the spatial
    crane). A travel axis without an acceleration limit brakes at most ``STOP_BRAKING`` times the running
    motion's hardest (its peak on any travel axis, or an axis's acceleration now): one bound for the
    horizontal axes, so that an axis the motion held (peak 0) may still move to damp its swing."""
    shaped = _shaped_travel(running.plan) if family_of(method) is Family.SHAPER else None
    if shaped is not None:
        t0 = float(running.time_of(handover_ns))
        new = {}
        for name, p in shaped.items():  # each travel axis's base braked within its own limits and reshaped
            _, amax, jmax = options.limits_of(name)
            # without a limit, as hard as the base itself moves (the shaped reference's peaks are lower: a base
            # braked within those from its own harder acceleration ran on far past the motion's goal)
            peaks = p.base.peaks() if amax is None or jmax is None else None
            accel, jerk = amax or peaks[0], jmax or peaks[1]
            braked = shaped_stop(p, t0, accel, jerk) if accel > 0.0 else p  # (an axis the motion holds: held)
            # (the shaped plan is relative to the motion's start, the knots absolute: the continuation, relative
            # to the reference at t0, is the same of both)
            new[name] = Continuation.of(method, braked, t0, None, info={'stop': 'shaped'})
        return with_axes_held(_together(new), _held(state, new))
    # NVF: RVF's sensitivities forced to zero at a free end make it wander (metres past the goal)
    method, options = 'nvf', stop_options(options)
    travel = [name for name in state.axes if axis(name).kind == 'travel']
    hardest = max(max(_peak_acceleration(running, name), abs(state.axis(name).acceleration)) for name in travel)
    # how hard each axis may brake: its limit, else (a travel axis) STOP_BRAKING times the motion's hardest
    braking = {}
    for name, s in state.axes.items():
        _, limit, jerk = options.limits_of(name)
        if limit is None and name in travel:
            limit = STOP_BRAKING * hardest
        if limit is not None:
            braking[name] = (limit, jerk)
    # no sooner than half the first mode's period, nor than every axis can brake within its bound
    shortest = max([STOP_SHORTEST * first_period(_model(params, state))]
                   + [braking_time(state.axis(name).velocity, state.axis(name).acceleration, limit, jerk)
                      for name, (limit, jerk) in braking.items() if limit > 0.0])
    last = None
    for duration in shortest * STOP_STEPS ** np.arange(STOP_TRIES):
        try:
            last = _variational(variational, method, state, {}, duration, params, options, free_end=True)
        except PlanError:
            continue
        if all(_axis_plan(last, name).peaks()[1] <= limit * (1.0 + 1e-6) for name, (limit, _) in braking.items()):
            return last
    if last is None:
        speeds = ', '.join(f'{name} {s.velocity:.3g} m/s' for name, s in state.axes.items())
        raise PlanError(f'{method}: no stop within the axis limits from {speeds}')
    return last  # the longest tried: its peak above the braking target, within the axis limits


def stop_options(options: PlanOptions) -> PlanOptions:
    """``options`` as a stop's tries are solved with: within ``STOP_SOLVE_TIME`` each."""
    budget = min(options.max_solve_time or STOP_SOLVE_TIME, STOP_SOLVE_TIME)
    return options if options.max_solve_time == budget else dataclasses.replace(options, max_solve_time=budget)


def settle(variational, state: MotionState, params: CraneParams, options: PlanOptions, method: str = 'nvf') -> Plan:
    """A short motion from the measured swing at rest (``state``) back to where it started, damping it."""
    if lacks(method, 'settle'):
        raise PlanError(f'{method}: a shaper cannot damp a swing it did not cause; settle with nvf or rvf')
    goal = {name: s.position for name, s in state.axes.items()}
    return _lengthened(lambda T: _variational(variational, method, state, goal, T, params, options),
                       first_period(_model(params, state)))


def _peak_acceleration(running: Running, joint: str = CART_JOINT) -> float:
    """The running motion's peak |acceleration| of ``joint`` (m/s^2), from its knots."""
    interp = running.interps[running.joints.index(joint)]
    t = np.linspace(interp.t[0], interp.t[-1], 400)
    return float(np.abs(interp(t)[2]).max())


def _axis_plan(plan: Plan, joint: str) -> Plan:
    """The plan of ``joint`` in ``plan`` (an ``AxesPlan``'s axis, or the cart's plan itself)."""
    return plan.axes[joint] if isinstance(plan, AxesPlan) else plan


def _lengthened(solve, duration: float) -> Plan:
    """``solve(duration)``, lengthened by ``LENGTHEN`` when it fails (the limits), ``ATTEMPTS`` times."""
    for attempt in range(ATTEMPTS):
        try:
            return solve(duration)
        except PlanError:
            if attempt == ATTEMPTS - 1:
                raise
            duration *= LENGTHEN
    raise AssertionError('unreachable')


def joint_starts(plan: Plan, state: MotionState) -> list:
    """Where the handover trajectory's positions start from, per joint: a travelling axis's reference at the
    handover (the plan is relative to it), and the hoist's plan start (``AxesPlan.starts``: the actual rope
    length then; without one its reference)."""
    starts = plan.starts if isinstance(plan, AxesPlan) else {}
    return [starts.get(name, s.position) if name == HOIST_JOINT else s.position for name, s in state.axes.items()]
