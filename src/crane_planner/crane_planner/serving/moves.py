"""A ``crane_interfaces/Move`` as the planner serves it: checked field by field, planned, described.

The planner node translates the message into a ``Move`` (plain values) and
back; everything it decides about a request lives here, so the rules are
tested without ROS: which joints a move names (``joint_names`` among the
node's ``joints``; empty = all), where it starts (``start``; empty = where
the streamer holds the axes), its duration (> 0; 0 = the fastest within the
axis limits) and the node's bounds (``max_displacement``, ``max_duration``).
A refusal is a ``MoveError`` whose message names the field and the bound,
e.g. ``move.duration: 90 s exceeds max_duration 60 s``. Pure Python, no ROS
import.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from crane_msgs_py.crane.params import CraneParams
from crane_msgs_py.messages.names import ACTUATED_JOINTS, BRIDGE_JOINT, CART_JOINT, HOIST_JOINT

from ..planning.dispatch import PlanOptions, VariationalRequest, check_request, checked, hoisting_options, shaper_design
from ..planning.hoisting import QuinticPlan
from ..planning.keep_out import KeepOut, KeepOutError
from ..planning.mass_path import plan_axes, predict_mass_path, rest_positions, solved_mass_path
from ..planning.methods import Family, method_spec
from ..planning.plan import AxesPlan, Plan, PlanError
from ..planning.routing import route_candidates
from ..planning.shaped_route import shaped_route
from .workers import WorkerDied


class MoveError(PlanError):
    """A move refused; the message starts with the field it concerns (``move.<field>: ...``)."""

    def __init__(self, field_name: str, reason: str):
        super().__init__(f'move.{field_name}: {reason}')
        self.field, self.reason = field_name, reason


@dataclass(frozen=True)
class Move:
    """A rest-to-rest move of the actuated joints, as the ``Move`` message gives it (SI units).

    Attributes:
        method: '' = the node's ``method`` parameter.
        joint_names: joints of ``start`` and ``goal``; empty = all of the node's joints.
        start: start positions (m); empty = where the streamer holds the axes.
        goal: goal positions (m).
        duration: s, > 0; 0 = the fastest within the node's axis limits.
        start_ns: start time (ns of ROS time); 0 = as soon as possible.
        via: points the reference passes in order without stopping, each positions per joint of
            ``joint_names`` (m).
    """

    method: str = ''
    joint_names: tuple = ()
    start: tuple = ()
    goal: tuple = ()
    duration: float = 0.0
    start_ns: int = 0
    via: tuple = ()


@dataclass(frozen=True)
class MoveBounds:
    """What a planner node serves: its joints, default method and the bounds of its parameters."""

    joints: tuple = (CART_JOINT,)
    method: str = 'rvf'
    max_displacement: float = 10.0
    max_duration: float = 60.0
    via_tolerance: float = 0.01  # m: how near a shaper's straight path must pass a via point


@dataclass(frozen=True)
class AxisMove:
    """One axis of a checked move: where its reference starts and where it goes (m; the hoist's: the rope
    length L1). An axis the move leaves out has its goal at its start: held."""

    start: float
    goal: float

    @property
    def displacement(self) -> float:
        return self.goal - self.start


@dataclass(frozen=True)
class CheckedMove:
    """A move that may be planned: the method, the joints the move named, every axis of the planner by its
    name (``AxisMove``, kept in ``ACTUATED_JOINTS`` order: the cart's first), the duration (None: fastest)
    and the start time (ns of ROS time; 0 = as soon as possible)."""

    method: str
    joint_names: tuple
    axes: dict[str, AxisMove]
    duration: float | None
    start_ns: int
    vias: tuple = ()  # per via point, every axis's position (m, by name; an axis the move leaves out: its start)

    def __post_init__(self):
        if CART_JOINT not in self.axes or any(n not in ACTUATED_JOINTS for n in self.axes):
            raise PlanError(f'a checked move needs the {CART_JOINT} and axes among {", ".join(ACTUATED_JOINTS)}, '
                            f'got {", ".join(self.axes)}')
        object.__setattr__(self, 'axes', {n: self.axes[n] for n in ACTUATED_JOINTS if n in self.axes})

    @property
    def displacement(self) -> float:
        """The cart's displacement (m): what ``dispatch.plan`` plans (the other axes beside it)."""
        return self.axes[CART_JOINT].displacement

    @property
    def relative_vias(self) -> tuple:
        """Each via point as the planning core takes it: every axis's position relative to its start (m)."""
        return tuple({name: via[name] - m.start for name, m in self.axes.items()} for via in self.vias)

    @property
    def joints(self) -> tuple:
        """Every joint the plan moves or holds: each axis of the planner."""
        return tuple(self.axes)

    @property
    def starts(self) -> tuple:
        """The start position of each of ``joints`` (m)."""
        return tuple(m.start for m in self.axes.values())

    @property
    def goals(self) -> dict:
        """The goal of each of ``joints`` (m), by name."""
        return {name: m.goal for name, m in self.axes.items()}

    def starting(self, starts: dict, start_ns: int) -> 'CheckedMove':
        """The same move from ``starts`` (m, by joint; a joint not among them starts where it did) at
        ``start_ns``: a goal during a motion, once its handover is known."""
        axes = {name: AxisMove(starts.get(name, m.start), m.goal) for name, m in self.axes.items()}
        return CheckedMove(self.method, self.joint_names, axes, self.duration, start_ns)


def check_move(move: Move, bounds: MoveBounds, hold: dict | None, L1: float = CraneParams.L1) -> CheckedMove:
    """The move checked field by field (MoveError names the first bad one).

    ``hold``: where the streamer holds each joint now (m), None if no
    streamer is heard; an empty ``start`` starts there, or (a preview with no
    streamer) at 0 for the cart and the model's ``L1`` for the hoist. A joint
    of the planner the move leaves out stays where it starts.
    """
    method = move.method or bounds.method
    try:
        method_spec(method)
    except PlanError as exc:
        raise MoveError('method', str(exc)) from None
    names = tuple(move.joint_names) or tuple(bounds.joints)
    unknown = [n for n in names if n not in bounds.joints]
    if unknown:
        raise MoveError('joint_names', f'unknown joint {unknown[0]!r}; this planner\'s joints are '
                                       f'{", ".join(bounds.joints)}')
    if len(set(names)) != len(names):
        raise MoveError('joint_names', f'a joint is named twice: {", ".join(names)}')
    if len(move.goal) != len(names):
        raise MoveError('goal', f'{len(move.goal)} value(s) for {len(names)} joint(s) ({", ".join(names)})')
    if move.start and len(move.start) != len(names):
        raise MoveError('start', f'{len(move.start)} value(s) for {len(names)} joint(s) ({", ".join(names)}); '
                                 'empty = where the streamer holds them')
    rest = {HOIST_JOINT: L1}  # (a travel axis: 0)
    goal = dict(zip(names, (float(x) for x in move.goal)))
    start = dict(zip(names, (float(x) for x in move.start))) if move.start else {
        n: (hold or {}).get(n, rest.get(n, 0.0)) for n in names}
    for name in bounds.joints:  # the planner's joints the move leaves out: where they are held
        if name not in start:
            start[name] = (hold or {}).get(name, rest.get(name, 0.0))
            goal[name] = start[name]
    for label, values in (('start', start), ('goal', goal)):
        for name, value in values.items():
            if not math.isfinite(value):
                raise MoveError(label, f'{name} must be finite, got {value}')
    duration = float(move.duration)
    if not math.isfinite(duration) or duration < 0.0:
        raise MoveError('duration', f'must be finite and > 0 s (0 = the fastest within the axis limits), '
                                    f'got {duration}')
    for name in bounds.joints:
        displacement = goal[name] - start[name]
        if abs(displacement) > bounds.max_displacement:
            raise MoveError('goal', f'{name} displacement {displacement:g} m from the start exceeds max_displacement '
                                    f'{bounds.max_displacement:g} m')
    if HOIST_JOINT in goal:
        for label, values in (('start', start), ('goal', goal)):
            if not values[HOIST_JOINT] > 0.0:
                raise MoveError(label, f'hoist {values[HOIST_JOINT]:g} m: the rope length (L1) must be > 0')
    displacement = goal[CART_JOINT] - start[CART_JOINT]
    if duration > bounds.max_duration:
        raise MoveError('duration', f'{duration:g} s exceeds max_duration {bounds.max_duration:g} s')
    if duration > 0.0:
        check_request(method, displacement, duration)
    axes = {name: AxisMove(start[name], goal[name]) for name in start}
    vias = []
    for k, point in enumerate(move.via, 1):
        if len(point) != len(names):
            raise MoveError('via', f'point {k}: {len(point)} value(s) for {len(names)} joint(s) ({", ".join(names)})')
        via = {**start, **dict(zip(names, (float(x) for x in point)))}
        if not all(math.isfinite(v) for v in via.values()):
            raise MoveError('via', f'point {k}: positions must be finite, got {", ".join(f"{v}" for v in point)}')
        if HOIST_JOINT in via and not via[HOIST_JOINT] > 0.0:
            raise MoveError('via', f'point {k}: hoist {via[HOIST_JOINT]:g} m: the rope length (L1) must be > 0')
        vias.append(via)
    if vias and not duration > 0.0:
        raise MoveError('via', 'a move through via points needs a duration (> 0 s): the fastest move goes straight')
    return CheckedMove(method, names, axes, duration or None, int(move.start_ns), tuple(vias))


def plan_move(planner, move: CheckedMove, bounds: MoveBounds, params: CraneParams, options: PlanOptions) -> Plan:
    """The plan of a checked move (``planner``: a ``serving.Planner``), or MoveError naming the field.

    A refusal of the planning core concerns the duration (too short for the
    shaper, a limit the plan would break, no solution in time) unless it is
    about the displacement; the fastest plan must also fit ``max_duration``.
    An axis the move does not move is held beside the others (a bridge that
    moves is planned with the cart on the spatial crane, ``bridge=``).
    """
    hoist, rope = None, move.axes.get(HOIST_JOINT)
    params = model_at_rope(move, params)
    if rope is not None and rope.goal != rope.start:
        hoist = (rope.start, rope.goal)  # (dispatch.plan's hoist=)
    bridge = move.axes.get(BRIDGE_JOINT)
    moving = {'bridge': bridge.displacement} if bridge is not None and bridge.displacement != 0.0 else {}
    try:
        if move.duration is None:
            plan = planner.fastest(move.method, move.displacement, params, options, hoist=hoist, **moving)
        else:
            plan = planner.plan(move.method, move.displacement, move.duration, params, options, hoist=hoist,
                                **moving)
    except (MoveError, WorkerDied):  # (a dead solver process is not the request's fault: said as it is)
        raise
    except PlanError as exc:  # ParameterError too: a bad request, named by the field it concerns
        raise MoveError('duration' if move.duration is not None else 'duration (fastest)', str(exc)) from None
    if move.duration is None and plan.duration > bounds.max_duration:
        raise MoveError('duration', f'the fastest {move.method} plan lasts {plan.duration:g} s, beyond '
                                    f'max_duration {bounds.max_duration:g} s')
    # the axes the plan does not move, held where they are: the hoist at its rope length, the bridge at 0 (relative)
    planned = plan_axes(plan)
    return with_axes_held(plan, {name: m.start if name == HOIST_JOINT else 0.0 for name, m in move.axes.items()
                                 if name not in planned})


def model_at_rope(move: CheckedMove, params: CraneParams) -> CraneParams:
    """The planning model of ``move``: ``params`` with L1 the rope's length at its start, if it has a hoist."""
    rope = move.axes.get(HOIST_JOINT)
    return params.replace(L1=rope.start) if rope is not None else params


def check_rests_keep_out(move: CheckedMove, params: CraneParams, keep_out: KeepOut) -> None:
    """MoveError (``move.start`` or ``move.goal``) naming the box if a mass at rest at the move's start or goal
    is within ``keep_out``'s margin of one of its boxes."""
    for label in ('start', 'goal'):
        at = {name: getattr(m, label) for name, m in move.axes.items()}
        reason = keep_out.rest_violation(rest_positions(at[CART_JOINT], at.get(BRIDGE_JOINT, 0.0),
                                                        at.get(HOIST_JOINT, params.L1), params.L2))
        if reason is not None:
            raise MoveError(label, reason)


#: How far (m) a solved path's point may come within the margin before the plan is refused from it alone: far
#: more than the collocation's own error (~1e-6 m); nearer, the step-by-step prediction decides.
SOLVED_TOLERANCE = 1e-4
#: What a solved path's straight steps may miss of the curved path between them (m): a step's sagitta L^2/8R,
#: 0.7 mm for the longest step of the contract's routes (23 mm; 5 mm typical) on a bend of 0.1 m radius,
#: tighter than a mass's path takes past a box.
CHORD_ALLOWANCE = 1e-3


def keep_out_clearance(plan: Plan, origin: dict, params: CraneParams, keep_out: KeepOut,
                       start: dict | None = None) -> float:
    """The smallest distance (m) of a mass to a ``keep_out`` box along ``plan`` and its settle window, predicted
    on the planning model ``params`` (``mass_path.predict_mass_path``: ``origin`` where each travel axis's
    reference starts, ``start`` the model's state there, None = at rest); inf without boxes; also in the plan's
    ``info`` as ``min_clearance`` (``summarize``). MoveError (``keep_out``) naming the box, the mass and when
    if it is below the margin.

    An NVF/RVF plan from rest carries the model's own prediction at its collocation points
    (``mass_path.solved_mass_path``): if a point is within the margin (by more than ``SOLVED_TOLERANCE``)
    the plan is refused from there; if the points keep out by the margin and the longest step its clearance
    is theirs, else if the straight steps between the points keep out by the margin and ``CHORD_ALLOWANCE``
    (``KeepOut.between_points``) theirs; either way the request costs next to nothing more than one without
    boxes. Any other is predicted step by step."""
    if not keep_out:
        return math.inf
    solved = solved_mass_path(plan, params, origin) if start is None else None
    if solved is not None:
        at_points = keep_out.clearance(solved).distance
        if at_points < keep_out.margin - SOLVED_TOLERANCE:
            _checked(keep_out, solved, plan)  # (raises)
        if at_points - solved.largest_step() >= keep_out.margin:  # no step reaches the margin: done
            plan.info['min_clearance'] = at_points
            return at_points
        along = keep_out.between_points(solved).distance
        if along - CHORD_ALLOWANCE >= keep_out.margin:
            plan.info['min_clearance'] = along
            return along
    distance = _checked(keep_out, predict_mass_path(plan, params, origin, start=start), plan)
    plan.info['min_clearance'] = distance
    return distance


def _checked(keep_out: KeepOut, path, plan: Plan) -> float:
    """``keep_out.check`` of ``plan``'s mass ``path``: its clearance, or MoveError (``keep_out``)."""
    try:
        return keep_out.check(path, f'the {plan.method} plan').distance
    except KeepOutError as exc:
        raise MoveError('keep_out', str(exc)) from None


def origin_of(move: CheckedMove) -> dict:
    """Where each travel axis of ``move`` starts (m, by name): what its relative plan is added to."""
    return {name: m.start for name, m in move.axes.items() if name != HOIST_JOINT}


def plan_keeping_out(planner, move: CheckedMove, bounds: MoveBounds, params: CraneParams, options: PlanOptions,
                     keep_out: KeepOut) -> Plan:
    """The plan of a checked move (``plan_move``) through its via points, whose masses keep out of
    ``keep_out``'s boxes, or MoveError.

    Via points: NVF/RVF pass them exactly (``direct.DirectSolver.solve_constrained``); a shaper's straight
    path must pass within ``bounds.via_tolerance`` of each, else ``move.via`` names the point. Boxes: the
    plan if it keeps out (its clearance in its ``info``). Else, at a given duration, the routes the served
    axes allow (``routing.route_candidates``: over a box with a hoist, around it with a bridge, the smaller
    detour first), each planned (NVF/RVF with the keep-out path constraints; a shaper's straight move with
    the route's axis stepping aside and back, ``shaped_route``) and checked again on the prediction: the
    first that keeps out (``info['route']`` says which). A fastest move, a shaper's with via points, or one
    no route gets past is refused naming the box (``move.keep_out``), with each route's reason.
    """
    spec, vias = method_spec(move.method), move.relative_vias
    variational = spec.family is Family.VARIATIONAL
    if vias and spec.supports.exact_vias:
        plan = _constrained(planner, move, params, options, vias=vias)
    else:
        plan = plan_move(planner, move, bounds, params, options)
    if vias and not spec.supports.exact_vias:
        check_shaper_vias(plan, move, bounds.via_tolerance)
    origin = origin_of(move)
    try:
        keep_out_clearance(plan, origin, params, keep_out)
        return plan
    except MoveError as exc:
        if move.duration is None:
            raise MoveError('keep_out', f'{exc.reason}; the fastest move is planned direct only: give a duration '
                                        'and nvf or rvf route past the boxes') from None
        if vias and not spec.supports.routes_with_vias:
            raise MoveError('keep_out', f'{exc.reason}; a shaper routes past boxes without via points: nvf and rvf '
                                        'route through them') from None
        if not spec.supports.routes:
            raise MoveError('keep_out', f'{exc.reason}; {move.method} does not route past boxes') from None
        direct = exc
    model = model_at_rope(move, params)
    moves = {name: m.displacement for name, m in move.axes.items()}
    routes = route_candidates(keep_out, origin, moves, model.L1, model.L2, tuple(move.axes))
    reasons = []
    if routes and not variational:  # its straight move, the route's axis stepping aside and back (``shaped_route``)
        straight_path, design = predict_mass_path(plan, model, origin, settle=0.0), shaper_design(model, options)
    for route in routes:
        try:
            if variational:
                routed = _constrained(planner, move, params, options, route=route, keep_out=keep_out, vias=vias)
            else:
                routed = checked(shaped_route(plan, route, straight_path, keep_out, *design), options)
            keep_out_clearance(routed, origin, model, keep_out)
            return routed
        except WorkerDied:
            raise
        except PlanError as exc:  # (MoveError too: a route that did not keep out after all)
            reasons.append(f'{route.kind} ({route.axis} {route.excursion:+.3f} m): {exc}')
    why = '; '.join(reasons) if reasons else ('the served axes allow none (a hoist lifts the load over a box, a '
                                              'bridge takes it around one)')
    raise MoveError('keep_out', f'{direct.reason}; no route past it: {why}')


def _constrained(planner, move: CheckedMove, params: CraneParams, options: PlanOptions, route=None,
                 keep_out: KeepOut | None = None, vias=()) -> Plan:
    """An NVF/RVF plan of every axis of ``move`` with path constraints (``dispatch.VariationalRequest``:
    ``route`` past ``keep_out``, through ``vias``), on the model at the rope's length now."""
    moves = {name: m.displacement for name, m in move.axes.items()}
    request = VariationalRequest('plan', move.method, moves, move.duration, model_at_rope(move, params),
                                 hoisting_options(options) if HOIST_JOINT in moves else options, route=route,
                                 keep_out=keep_out, origin=origin_of(move), vias=tuple(vias))
    try:
        return planner.variational(request)
    except (MoveError, WorkerDied):
        raise
    except PlanError as exc:
        if route is None:  # the via points' plan: said of the duration, as every plan's refusal
            raise MoveError('duration', str(exc)) from None
        raise


def check_shaper_vias(plan: Plan, move: CheckedMove, tolerance: float) -> None:
    """MoveError (``move.via``) naming the first via point a shaper's straight path does not pass within
    ``tolerance`` (m) of, in order: each is looked for after the previous one was passed."""
    t = np.linspace(0.0, plan.duration, max(2, int(plan.duration / 1e-3) + 1))
    axes = plan_axes(plan)
    path = np.stack([axes[name].evaluate(t).position + m.start for name, m in move.axes.items()], axis=1)
    after = 0
    for k, via in enumerate(move.vias, 1):
        point = np.array([via[name] for name in move.axes])
        distance = np.linalg.norm(path[after:] - point, axis=1)
        nearest = int(np.argmin(distance))
        if distance[nearest] > tolerance:
            where = ', '.join(f'{name} {via[name]:g}' for name in move.axes)
            raise MoveError('via', f'point {k} ({where} m) is {distance[nearest] * 1e3:.0f} mm from the '
                                   f'{plan.method} plan\'s straight path, beyond via_tolerance {tolerance * 1e3:g} mm: '
                                   'a shaper moves straight to its goal; nvf and rvf pass via points exactly')
        after += nearest


def with_hoist_held(plan: Plan, length: float | None) -> Plan:
    """``plan`` of the cart with the hoist held at ``length`` (m) beside it; ``plan`` itself without a hoist
    (``length`` None)."""
    return with_axes_held(plan, {} if length is None else {HOIST_JOINT: length})


def with_axes_held(plan: Plan, held: dict) -> Plan:
    """``plan`` (of the cart, or an ``AxesPlan``) with each axis of ``held`` held beside it, at its start there
    (``AxesPlan.starts``: the hoist's rope length in m, a travel axis's 0, its plan relative like the cart's);
    ``plan`` itself if none. The solver's model path is kept: an axis held adds no motion to it."""
    if not held:
        return plan
    axes = plan_axes(plan)
    starts = dict(plan.starts) if isinstance(plan, AxesPlan) else {CART_JOINT: 0.0}
    axes.update({name: QuinticPlan(method='hold', displacement=0.0, duration=plan.duration) for name in held})
    starts.update(held)
    order = [name for name in ACTUATED_JOINTS if name in axes]
    return AxesPlan(method=plan.method, displacement=plan.displacement, duration=plan.duration, info=plan.info,
                    axes={name: axes[name] for name in order}, starts={name: starts.get(name, 0.0) for name in order},
                    model_path=plan.model_path)


def axis_samples(plan: Plan, times) -> list:
    """The plan's samples at ``times`` per joint (relative positions), the cart's first."""
    if isinstance(plan, AxesPlan):
        return [axis.evaluate(times) for axis in plan.axes.values()]
    return [plan.evaluate(times)]


@dataclass(frozen=True)
class PlanSummary:
    """What ``PlanInfo`` says of a plan: per joint peaks of the reference, solve facts."""

    method: str
    duration: float
    solve_time: float
    iterations: int
    joint_names: tuple
    peak_velocity: tuple
    peak_acceleration: tuple
    peak_jerk: tuple
    predicted_residual: float = math.nan
    min_clearance: float = math.inf
    route: str = ''  # how the plan gets past the keep-out boxes: '' direct, over, around
    runway_delay: float = 0.0  # s later than asked, to keep clear of another crane on a shared runway
    runway_waited_for: str = ''  # the crane it waited for


def summarize(plan: Plan, joint_names=(CART_JOINT,), solve_time: float | None = None) -> PlanSummary:
    """The ``PlanInfo`` of a plan; ``solve_time`` defaults to the solver's own figure (0 for shapers); the
    smallest predicted distance of a mass to a keep-out box if it was checked (``keep_out_clearance``); on a
    shared runway its delay and the crane it waited for (``preview.placed``).

    Peaks per joint of ``joint_names`` (an ``AxesPlan``'s axes by name).
    """
    axes = plan_axes(plan)
    peaks = [axes[name].peaks() for name in joint_names]
    info = plan.info
    return PlanSummary(plan.method, float(plan.duration),
                       float(info.get('solve_time_s', 0.0) if solve_time is None else solve_time),
                       int(info.get('iterations', 0)), tuple(joint_names), *(tuple(p[k] for p in peaks)
                                                                            for k in range(3)),
                       min_clearance=float(info.get('min_clearance', math.inf)), route=str(info.get('route', '')),
                       runway_delay=float(info.get('runway_delay', 0.0)),
                       runway_waited_for=str(info.get('runway_waited_for', '')))
