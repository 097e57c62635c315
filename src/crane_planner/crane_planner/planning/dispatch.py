"""One entry point for every method: check a request, pick the shaper or the variational route, plan.

``plan`` and ``fastest`` validate a request and make a shaped plan here, or
hand a ``VariationalRequest`` to a ``variational`` callable that runs it on
an NVF/RVF solver: by default a new solver each time, started cold, whose
NLP is built once per structure and shared (a repeated call costs a solve,
not a build, and plans exactly as a newly built solver); ``SolverCache`` keeps
them (one caller at a time, e.g. a worker process); the serving layer
(``crane_planner.serving.Planner``) lends them from pools and worker
processes. So the CLI, the planner node and every worker accept and refuse
exactly the same requests with the same messages. Pure Python, no ROS import.
"""
from __future__ import annotations

import dataclasses
import math
import threading
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Callable

from crane_msgs_py.crane.axes import AXES, AXIS_NAMES, AxisLimits, axis
from crane_msgs_py.crane.params import (
    CraneParams,
    ParameterError,
    check_choice,
    check_finite,
    check_nonnegative,
    check_positive,
)
from crane_msgs_py.messages.names import CART_JOINT, HOIST_JOINT

from .hoisting import HOIST_SHAPER_DESIGNS, check_hoist, shaped_hoisting_plan, travel_displacements
from .limits import axis_limit_error, check_fastest_request
from .methods import ROBUST_PARAMETERS, Family, MethodSpec, method_spec
from .model import modal_properties
from .plan import AxesPlan, Plan, PlanError
from .profiles import BASES
from .shaped import fastest_shaped, fastest_shaped_axes, shaped_axes, shaped_plan


@dataclass(frozen=True)
class PlanOptions:
    """Method options beyond the model (contract: ``crane-plan`` model options).

    Attributes:
        omega: shaper design frequencies (rad/s), one per mode; None = from the
            linearized model.
        damping: shaper design damping ratio (>= 0, < 1); None = the model's
            modal damping ratios (``model.modal_properties``) when ``omega``
            is None too, else 0.
        robust: parameters RVF is made insensitive to.
        intervals: collocation intervals for NVF/RVF; None = solver default.
        solver: ``direct`` (CasADi collocation + IPOPT) or ``indirect``
            (the paper's TPBVP, scipy solve_bvp).
        max_velocity: the cart's limit |v| (m/s), None (or 0) = no limit.
        max_acceleration: the cart's limit |a_ref| (m/s^2), None = no limit.
        max_jerk: the cart's limit on the reference's jerk (m/s^3), None = no limit.
        base: the motion shapers shape: ``quintic`` (the paper's) or
            ``limits`` (the jerk-limited time-optimal profile under the limits,
            ``profiles.limited_base``).
        max_solve_time: budget (s) of one NVF/RVF request, > 0: a plan, or
            a fastest plan's attempts together, not solved within it is refused
            (direct route only; building a solver is not counted, except by
            the caller's wait on a worker process); None = the route's own cap.
        max_hoist_velocity, max_hoist_acceleration, max_hoist_jerk: the hoist
            axis's limits on its reference (m/s, m/s^2, m/s^3), None = no limit.
        limits: the axes' limits as ``AxisLimits`` by axis name, in place of (or agreeing with) the
            flat keywords above, which remain how the cart's and the hoist's are given; after
            construction the ``AxisLimits`` of every axis in ``crane_msgs_py.crane.axes.AXES`` order (read
            them with ``limits_of``), the flat fields the same values.
        hoist_robust: the parameters RVF is made insensitive to while
            hoisting (it replaces ``robust`` then): the payload's cable ``L2``
            by default, since the upper cable's length is what the hoist sets.
        max_bridge_velocity, max_bridge_acceleration, max_bridge_jerk: the
            bridge axis's limits on its reference (m/s, m/s^2, m/s^3), None =
            no limit (or ``limits['bridge']``).
        hoist_shaper: how a shaper follows the rope length while hoisting
            (``hoisting.HOIST_SHAPER_DESIGNS``): ``adaptive`` (default) or
            designed at the ``start``, ``middle`` or ``end`` length.
    """

    omega: tuple[float, ...] | None = None
    damping: float | None = None
    robust: tuple[str, ...] = ('L1',)
    intervals: int | None = None
    solver: str = 'direct'
    max_velocity: float | None = None
    max_acceleration: float | None = None
    max_jerk: float | None = None
    base: str = 'quintic'
    max_solve_time: float | None = None
    max_hoist_velocity: float | None = None
    max_hoist_acceleration: float | None = None
    max_hoist_jerk: float | None = None
    hoist_robust: tuple[str, ...] = ('L2',)
    hoist_shaper: str = 'adaptive'
    limits: Mapping[str, AxisLimits] | tuple[AxisLimits, ...] = ()
    max_bridge_velocity: float | None = None
    max_bridge_acceleration: float | None = None
    max_bridge_jerk: float | None = None

    def __post_init__(self):
        self._set_limits()
        if self.omega is not None:
            omega = tuple(check_positive('omega', w) for w in self.omega)
            if len(omega) == 0:
                raise ParameterError('omega needs at least one frequency')
            object.__setattr__(self, 'omega', omega)
        if self.damping is not None:
            damping = check_nonnegative('damping', self.damping)
            if damping >= 1.0:
                raise ParameterError(f'damping must be < 1, got {damping}')
            object.__setattr__(self, 'damping', damping)
        for name in ('robust', 'hoist_robust'):
            robust = tuple(getattr(self, name))
            bad = [r for r in robust if r not in ROBUST_PARAMETERS]
            if bad:
                raise ParameterError(
                    f'{name} parameter(s) {", ".join(bad)} not among {", ".join(ROBUST_PARAMETERS)}')
            if len(set(robust)) != len(robust) or not robust:
                raise ParameterError(f'{name} needs one or more distinct parameters')
            object.__setattr__(self, name, robust)
        if self.intervals is not None:
            if int(self.intervals) != self.intervals or not 4 <= int(self.intervals) <= 2000:
                raise ParameterError(f'intervals must be an integer in [4, 2000], got {self.intervals}')
            object.__setattr__(self, 'intervals', int(self.intervals))
        if self.solver not in ('direct', 'indirect'):
            raise ParameterError(f"solver must be 'direct' or 'indirect', got {self.solver!r}")
        check_choice('base', self.base, BASES)
        if self.base == 'limits' and not self.limits_of(CART_JOINT).bounds_speed:
            raise ParameterError('the limits base needs max_velocity or max_acceleration (or both)')
        check_choice('hoist_shaper', self.hoist_shaper, HOIST_SHAPER_DESIGNS)
        if self.max_solve_time is not None:
            object.__setattr__(self, 'max_solve_time', check_positive('max_solve_time', self.max_solve_time))

    def _set_limits(self):
        """``limits`` as a tuple of every axis's checked ``AxisLimits``, from the mapping and the flat keywords."""
        given = self.limits if isinstance(self.limits, Mapping) else dict(zip(AXIS_NAMES, self.limits))
        for name in given:
            axis(name)  # ParameterError for an unknown one
        limits = []
        for a in AXES:
            flat = [getattr(self, n, None) for n in a.limit_names]  # the axes with keywords of their own
            mine = a.limits(*flat)
            if a.name in given:
                theirs = a.limits(*given[a.name])
                if mine.any and mine != theirs:
                    raise ParameterError(f'the {a.name} limits are given twice, differently: '
                                         f'{", ".join(a.limit_names)} and limits[{a.name!r}]')
                mine = theirs
            for n, v in zip(a.limit_names, mine):
                if hasattr(self, n):
                    object.__setattr__(self, n, v)
            limits.append(mine)
        object.__setattr__(self, 'limits', tuple(limits))

    def limits_of(self, axis_name: str) -> AxisLimits:
        """The ``AxisLimits`` of the axis ``axis_name``."""
        return self.limits[AXIS_NAMES.index(axis_name)]


def check_request(method: str, displacement, duration) -> tuple[float, float]:
    """Validate the method name and a (D, T) pair; return them as floats."""
    method_spec(method)  # PlanError naming the methods for an unknown one
    try:
        displacement = float(displacement)
        duration = float(duration)
    except (TypeError, ValueError):
        raise PlanError('displacement and duration must be numbers') from None
    if not math.isfinite(displacement):
        raise PlanError(f'displacement must be finite, got {displacement}')
    if not math.isfinite(duration):
        raise PlanError(f'duration must be finite, got {duration}')
    if duration <= 0.0:
        raise PlanError(f'duration must be > 0, got {duration}')
    return displacement, duration


def check_axis_limits(plan, options: PlanOptions, axis_name: str = CART_JOINT) -> None:
    """PlanError naming the limit if the shaped plan's |v|, |a_ref| or |jerk| peak exceeds the options' limit
    of its axis ``axis_name``.

    A shaper cannot trade time for peaks: the shaped profile is fixed by the
    method and the duration, so an exceeded limit is an error, not a constraint.
    """
    limits = options.limits_of(axis_name)
    if not limits.any:
        return
    units = axis(axis_name).limit_units
    for name, unit, limit, peak in zip(limits.names, units, limits, plan.peaks()):
        if limit is not None and peak > limit * (1.0 + 1e-6):
            raise PlanError(f'{plan.method} plan exceeds {name} {limit:g} {unit} (peak {peak:.4g}); '
                            'lengthen the duration or raise the limit')


@dataclass(frozen=True)
class VariationalRequest:
    """A checked NVF/RVF request, as a solver runs it (and a worker process receives it).

    ``operation`` ``plan``: from 0 to ``displacement`` (m; a number, the cart's; the pair of the cart's and
    the hoist's; or by axis name, ``problem.axis_displacements``) in ``duration`` (s),
    from rest or from ``start`` (SI values of the problem's states by name,
    ``continuation.problem_start``), with ``free_end`` to rest anywhere (a stop);
    ``fastest``: the shortest plan within the options' limits (``duration`` None); with a ``route``, the
    plan past the ``keep_out`` boxes that way; with ``vias``, through them (``direct.DirectSolver.solve_constrained``).
    """

    operation: str
    method: str
    displacement: float | tuple | Mapping
    duration: float | None
    params: CraneParams
    options: PlanOptions
    start: dict | None = None
    free_end: bool = False
    #: a route past keep-out boxes (``routing.Route``), with the boxes (``keep_out.KeepOut``) and where the
    #: travel axes start (m, by joint name): rest to rest with the keep-out path constraints
    route: object | None = None
    keep_out: object | None = None
    origin: dict | None = None
    #: via points the reference passes in order: per via each axis's position relative to its start (m, by name)
    vias: tuple = ()

    def run(self, solver) -> Plan:
        """This request on ``solver`` (a ``variational.VariationalSolver`` for this method and options)."""
        if self.route is not None or self.vias:
            return solver.solve_constrained(self.displacement, self.duration, self.params, self.origin or {},
                                            self.keep_out, self.route, self.vias)
        if self.operation == 'fastest':
            return solver.fastest(self.displacement, self.params)
        if self.start is None and not self.free_end:
            return solver.solve(self.displacement, self.duration, self.params)
        return solver.solve(self.displacement, self.duration, self.params, self.start, self.free_end)


#: Runs a VariationalRequest on some solver and returns its plan.
Variational = Callable[[VariationalRequest], Plan]


def plan(method: str, displacement: float, duration: float, params: CraneParams | None = None,
         options: PlanOptions | None = None, variational: Variational | None = None,
         hoist: tuple[float, float] | None = None, bridge: float | None = None) -> Plan:
    """A rest-to-rest plan from 0 to ``displacement`` (m) in ``duration`` (s).

    With ``hoist`` = (L1_start, L1_goal) (m) the rope length moves too: an
    ``AxesPlan`` of the cart and the hoist, planned on the model with L1 =
    L1_start (contract "Joints and hoisting"). With ``bridge`` (m, its
    displacement) the bridge moves too (contract "The spatial crane"): an
    ``AxesPlan`` of every axis moved; NVF/RVF plan all axes together on the
    spatial crane, a shaper shapes each travel axis's share of one straight
    move (``shaped.shaped_axes``). Shapers are planned here;
    NVF/RVF by ``variational`` (default: a new solver, see the module
    docstring). Raises PlanError (or its ParameterError sibling, both
    ValueError) with a message naming the problem.
    """
    params = params or CraneParams()
    options = options or PlanOptions()
    displacement, duration = check_request(method, displacement, duration)
    bridge = bridge_request(bridge)
    spec = supported(method, hoist, bridge)
    if hoist is not None:
        params, hoist_displacement = hoisting_request(params, options, hoist)
        if spec.family is Family.SHAPER:
            if options.base != 'quintic':
                raise PlanError('while hoisting the shapers shape the quintic base only (base quintic)')
            err = axis_limit_error(hoist_displacement, duration, options.limits_of(HOIST_JOINT))
            if err is not None:
                raise err
            zeta = options.damping
            return checked(shaped_hoisting_plan(method, displacement, hoist_displacement, duration, params, zeta,
                                                options.hoist_shaper, bridge), options)
        displacement, options = (displacement, hoist_displacement), hoisting_options(options)
    elif spec.family is Family.SHAPER:
        omegas, zetas = shaper_design(params, options)
        if bridge is not None:
            travel = travel_displacements(displacement, bridge)
            return checked(travel_plan(shaped_axes(method, travel, duration, omegas, zetas, options.base,
                                                   {name: options.limits_of(name) for name in travel})), options)
        shaped = shaped_plan(method, displacement, duration, omegas, zetas, options.base,
                             options.limits_of(CART_JOINT))
        check_axis_limits(shaped, options)
        return shaped
    if bridge is not None:
        displacement = with_bridge(displacement, bridge)
    # the variational solvers bound v and a_ref everywhere as path constraints
    return (variational or _new_solver)(VariationalRequest('plan', method, displacement, duration, params, options))


def fastest(method: str, displacement: float, params: CraneParams | None = None,
            options: PlanOptions | None = None, variational: Variational | None = None,
            hoist: tuple[float, float] | None = None, bridge: float | None = None) -> Plan:
    """The shortest rest-to-rest plan of ``displacement`` (m) within the options' axis limits.

    Needs max_velocity or max_acceleration (a motion without either could
    be arbitrarily fast). Shapers: ``shaped.fastest_shaped`` (with a bridge
    ``shaped.fastest_shaped_axes``: every axis within its limits, all ending
    together); NVF/RVF: the free-final-time NLP (``free_time``) by ``variational``.
    """
    params = params or CraneParams()
    options = options or PlanOptions()
    check_request(method, displacement, 1.0)
    bridge = bridge_request(bridge)
    spec = supported(method, hoist, bridge, fastest=True)
    if hoist is not None:
        params, hoist_displacement = hoisting_request(params, options, hoist)
        if not spec.supports.fastest_hoisting:
            raise PlanError('the fastest shaped plan with a hoist is not offered: give a duration, or use nvf/rvf')
        displacement, options = (float(displacement), hoist_displacement), hoisting_options(options)
    elif bridge is not None:
        displacement = float(displacement)
        if spec.family is Family.SHAPER:
            travel = travel_displacements(displacement, bridge)
            return travel_plan(fastest_shaped_axes(method, travel, *shaper_design(params, options),
                                                   {name: options.limits_of(name) for name in travel}, options.base))
    else:
        limits = options.limits_of(CART_JOINT)
        displacement = check_fastest_request(displacement, limits)  # before a solver is asked
        if spec.family is Family.SHAPER:
            return fastest_shaped(method, displacement, *shaper_design(params, options), limits, options.base)
    if options.solver != 'direct':
        raise PlanError('the fastest NVF/RVF plan needs the direct solver (free final time)')
    if bridge is not None:
        displacement = with_bridge(displacement, bridge)
    return (variational or _new_solver)(VariationalRequest('fastest', method, displacement, None, params, options))


def supported(method: str, hoist, bridge, fastest: bool = False) -> MethodSpec:
    """The entry of ``method``, or PlanError if it plans no hoist, bridge or fastest plan a request asks for."""
    spec = method_spec(method)
    asked = {'hoisting': hoist is not None, 'bridge': bridge is not None, 'fastest': fastest}
    missing = [what for what, wanted in asked.items() if wanted and not getattr(spec.supports, what)]
    if missing:
        raise PlanError(f'{method} does not plan {" or ".join(missing)}')
    return spec


def bridge_request(bridge) -> float | None:
    """The bridge's displacement (m) of a request, checked; None without one."""
    return None if bridge is None else check_finite('the bridge displacement (m)', bridge, PlanError)


def travel_plan(axes: dict) -> AxesPlan:
    """The ``AxesPlan`` of the travel axes' shaped plans ``axes`` (by name, the cart's first): one straight
    move, relative like the cart's."""
    cart = axes[CART_JOINT]
    return AxesPlan(method=cart.method, displacement=cart.displacement, duration=cart.duration, info=cart.info,
                    axes=dict(axes), starts={name: 0.0 for name in axes})


def checked(plan: AxesPlan, options: PlanOptions) -> AxesPlan:
    """``plan`` if every axis's peaks are within its limits (``check_axis_limits``), else that PlanError."""
    for name, one in plan.axes.items():
        check_axis_limits(one, options, name)
    return plan


def with_bridge(displacement, bridge: float) -> dict:
    """``displacement`` (the cart's, or the pair of the cart's and the hoist's) with the bridge's, by axis name.

    Only variational requests have one (imported here: CasADi loads with them, see ``variational_solver``).
    """
    from .problem import axis_displacements
    return {**axis_displacements(displacement), 'bridge': bridge}


def hoisting_request(params: CraneParams, options: PlanOptions, hoist) -> tuple[CraneParams, float]:
    """The model at the start length and the hoist's displacement (m) of ``hoist`` = (L1_start, L1_goal)."""
    try:
        start, goal = (float(x) for x in hoist)
    except (TypeError, ValueError):
        raise PlanError(f'hoist needs the start and goal rope lengths (m), got {hoist!r}') from None
    if not (math.isfinite(start) and start > 0.0):
        raise PlanError(f'hoist start length must be finite and > 0 m, got {start}')
    check_hoist(start, goal - start)
    if options.omega is not None:
        raise PlanError('shaper frequencies (omega) cannot be given with a hoist: they change with the rope '
                        'length, which the model gives')
    return params.replace(L1=start), goal - start


def hoisting_options(options: PlanOptions) -> PlanOptions:
    """``options`` as a hoisting request is solved with: RVF robust to ``hoist_robust``."""
    return dataclasses.replace(options, robust=options.hoist_robust)


#: The NLPs (transcriptions and their derivatives, most of a solver's build) of the solvers ``plan`` and
#: ``fastest`` make when given no ``variational``, by NLP structure: a later call of the same structure builds
#: only its own IPOPT instance and starts cold, as a new solver does, so its plan is the same.
_SHARED_NLPS: dict = {}
_SHARED_NLPS_LOCK = threading.Lock()


def _new_solver(request: VariationalRequest) -> Plan:
    solver = variational_solver(request.method, request.options)
    if hasattr(solver, 'share'):  # the direct route's
        with _SHARED_NLPS_LOCK:
            store = _SHARED_NLPS.setdefault(solver.structure, ({}, threading.Lock()))
        solver.share(*store)
    return request.run(solver)


class SolverCache:
    """NVF/RVF solvers kept per ``VariationalSolver.key``, with their warm starts: a ``Variational``
    for one caller at a time (a worker process, a script).

    Args:
        overrides: solver settings given to every solver it makes (``variational_solver``).
    """

    def __init__(self, **overrides):
        self.overrides = overrides
        self._solvers: dict = {}

    def __call__(self, request: VariationalRequest) -> Plan:
        from .variational import VariationalSolver
        key = VariationalSolver.key(request.method, request.options)
        solver = self._solvers.get(key)
        if solver is None:
            solver = self._solvers[key] = variational_solver(request.method, request.options, **self.overrides)
        return request.run(solver)


def shaper_design(params: CraneParams, options: PlanOptions) -> tuple:
    """(frequencies rad/s, damping ratios) the shapers are designed for: the options' or the model's modes."""
    if options.omega is not None:
        return options.omega, options.damping or 0.0
    omegas, zetas = modal_properties(params)
    return omegas, (zetas if options.damping is None else options.damping)


def variational_solver(method: str, options: PlanOptions, **overrides):
    """A new NVF/RVF solver of the route ``options.solver`` picks: ``direct`` (CasADi
    collocation + IPOPT, the fast path) or ``indirect`` (the paper's TPBVP).

    Imported here, not at the top: CasADi loads only when a variational plan is asked for.
    """
    if options.solver == 'indirect':
        from .indirect import IndirectSolver
        return IndirectSolver(method, options, **overrides)
    from .direct import DirectSolver
    return DirectSolver(method, options, **overrides)
