"""What the two solution routes of NVF and RVF share: settings, model forms, mesh, request checks.

``VariationalSolver`` is the base of ``direct.DirectSolver`` and
``indirect.IndirectSolver``; the planning facade (``planner.Planner``) picks
the route. A subclass implements ``_solve`` on the mesh this base computes.
"""
from __future__ import annotations

import threading

import numpy as np

from crane_msgs_py.crane.axes import AxisLimits
from crane_msgs_py.crane.params import CraneParams
from crane_msgs_py.messages.names import CART_JOINT, HOIST_JOINT

from .limits import axis_limit_error
from .methods import Family, family_of, find_method
from .plan import Plan, PlanError
from .problem import Form, Problem, Weights, axis_displacements, graded_mesh, servo_layer, uniform_mesh


def robust_set(method: str, options) -> tuple:
    """The parameters ``method``'s plan is made insensitive to: the options' for a robust method (RVF), else none."""
    spec = find_method(method)
    return tuple(options.robust) if spec is not None and spec.robust else ()


class VariationalSolver:
    """NVF or RVF plans for one (method, intervals, robust set, limits); thread-safe.

    Each model form (ideal tracking, tau = 0; servo, tau > 0) has its own
    ``Problem``, built on first use and kept. The class attributes are the
    tuning; the constructor's keywords override them per instance.
    """

    #: Name of the solution route ('direct' or 'indirect'), set by each subclass.
    route = ''
    #: Whether the route bounds reference velocity and acceleration (axis limits).
    handles_limits = True
    #: Whether the route can stop a solve at ``max_solve_time``.
    handles_time_budget = True
    #: Whether the route plans a hoist axis beside the cart.
    handles_hoist = True
    #: Whether the route plans the bridge beside the cart (the spatial crane); a route says so itself.
    handles_bridge = False
    #: Collocation intervals when PlanOptions.intervals is None.
    default_intervals = 30
    #: ... and with a hoist: its NLP costs several times as much per interval, and fewer intervals leave the
    #: same residual swing on the nominal hoisting move, in less time (docs/benchmarks.md).
    default_hoist_intervals = 24
    #: ... and on the spatial crane (a bridge, with or without the hoist): twice the states of the planar crane.
    default_bridge_intervals = 24
    #: Whether a straight rest-to-rest move of the travel axes is solved on its vertical plane, as the planar
    #: crane along the line, where the spatial crane's symmetry makes that its exact optimum (``straight``);
    #: False solves every move of the bridge on the coupled model.
    straight_moves_in_their_plane = True
    weights = Weights()
    #: End intervals of the servo mesh, as a multiple of the boundary-layer width (see ``mesh``).
    layer_resolution = 0.25

    def __init__(self, method: str, options, **overrides):
        if family_of(method) is not Family.VARIATIONAL:
            raise PlanError(f'no variational method {method!r}; choose nvf or rvf')
        for name, value in overrides.items():
            if name.startswith('_') or not hasattr(type(self), name):
                raise TypeError(f'unknown {type(self).__name__} setting {name!r}')
            setattr(self, name, value)
        self.method, self.options, self.overrides = method, options, overrides
        self.intervals = options.intervals or self.default_intervals
        self.hoist_intervals = options.intervals or self.default_hoist_intervals
        self.bridge_intervals = options.intervals or self.default_bridge_intervals
        self.robust = robust_set(method, options)
        #: the cart's limits, the hoist's and the bridge's (``AxisLimits``)
        self.limits, self.hoist_limits = options.limits_of(CART_JOINT), options.limits_of(HOIST_JOINT)
        self.bridge_limits = options.limits_of('bridge')
        #: the budget (s) of one solve, None = the route's own cap
        self.max_solve_time = options.max_solve_time
        self._problems = {}
        self._lock = threading.Lock()

    @staticmethod
    def key(method: str, options) -> tuple:
        """Everything that makes two solvers differ: the NLP structure, the limit values and the time budget."""
        return (*VariationalSolver.structure_of(method, options), options.limits, options.max_solve_time)

    @staticmethod
    def structure_of(method: str, options) -> tuple:
        """What a solver builds depends on: the route, the method, intervals, robust set, whether limits are set."""
        return (options.solver, method, options.intervals or VariationalSolver.default_intervals,
                robust_set(method, options),
                any(limits.any for limits in options.limits))

    @property
    def structure(self) -> tuple:
        return self.structure_of(self.method, self.options)

    def spawn(self, options=None) -> 'VariationalSolver':
        """Another solver of this kind for ``options`` (default: this one's), with the same overrides.

        A route may share what it has built with it (``DirectSolver.spawn``).
        """
        return type(self)(self.method, options or self.options, **self.overrides)

    @property
    def has_limits(self) -> bool:
        return self.limits.any or self.hoist_limits.any or self.bridge_limits.any

    def axis_limits(self, axes) -> list[AxisLimits]:
        """The ``AxisLimits`` of each axis planned, in ``axes``' order: axis names, a ``problem.Form``, or
        ``hoisting`` (a bool: the cart's, then the hoist's with a hoist)."""
        if isinstance(axes, Form):
            axes = axes.axes
        elif isinstance(axes, bool):
            axes = ('cart', 'hoist') if axes else ('cart',)
        by_axis = {CART_JOINT: self.limits, 'bridge': self.bridge_limits, HOIST_JOINT: self.hoist_limits}
        return [by_axis[a] for a in axes]

    def problem(self, form) -> Problem:
        """The ``Problem`` of a ``problem.Form`` (or of ``servo``, a bool, without a hoist)."""
        form = Form.coerce(form)
        if form not in self._problems:
            self._problems[form] = Problem(self.robust, form)
        return self._problems[form]

    def mesh(self, duration: float, params: CraneParams, form=False) -> np.ndarray:
        """Interval fractions of T for the model ``form`` (a ``problem.Form``, or ``hoisting``, a bool).

        With the servo the optimum has boundary layers of width
        ``problem.servo_layer`` at both ends. A uniform mesh that does not
        resolve them converges only to first order, so the end intervals are
        made ``layer_resolution`` layers wide, growing geometrically into the
        uniform interior.
        """
        form = form if isinstance(form, Form) else Form.of(params, bool(form))
        taus = [t for t in (params.tau, params.tau_hoist if form.hoist else 0.0) if t > 0.0]
        intervals = self.intervals_for(form)
        if not taus:
            return uniform_mesh(intervals)
        layer = servo_layer(min(taus), self.weights) * self.layer_resolution
        return graded_mesh(intervals, layer / duration)

    def intervals_for(self, form) -> int:
        """Collocation intervals of the model ``form`` (a ``problem.Form``, or ``hoisting``, a bool)."""
        if isinstance(form, Form) and form.bridge:
            return self.bridge_intervals
        return self.hoist_intervals if (form.hoist if isinstance(form, Form) else form) else self.intervals

    def solve(self, displacement, duration: float, params: CraneParams, start: dict | None = None,
              free_end: bool = False) -> Plan:
        """The plan from 0 to ``displacement`` (m) in ``duration`` (s) for the model ``params``.

        From rest, or from ``start`` (SI values of the problem's states by
        name, ``continuation.problem_start``); with ``free_end`` the end
        position is free (a stop: ``displacement`` then only sets the scale).

        ``displacement`` is the cart's (a number), or the cart's and the
        hoist's (a pair: the hoist from the model's L1 to L1 + the second,
        an ``AxesPlan``), or a mapping by axis name (``problem.axis_displacements``:
        with a ``bridge`` the spatial crane, an ``AxesPlan``). Raises PlanError
        naming the solver status if the solver does not converge, or the axis
        limit that makes the request infeasible.
        """
        try:
            moves = axis_displacements(displacement)
        except ValueError as exc:
            raise PlanError(str(exc)) from None
        D, Dh = moves['cart'], moves.get('hoist')
        if Dh is not None and not self.handles_hoist:
            raise PlanError(f'the {self.route} solver does not plan a hoist; use the direct solver')
        if 'bridge' in moves and not self.handles_bridge:
            raise PlanError(f'the {self.route} solver does not plan the bridge; use the direct solver')
        if start is not None and self.route != 'direct':
            raise PlanError(f'planning from a moving state needs the direct solver, not the {self.route} one')
        if start is None and not free_end:
            for name, limits in (('hoist', self.hoist_limits), ('bridge', self.bridge_limits)):
                err = axis_limit_error(moves[name], duration, limits) if name in moves else None
                if err is not None:
                    raise err
        if 'tau' in self.robust and params.tau == 0.0:
            raise PlanError('robust parameter tau needs a model with tau > 0 (the servo of Eq. 6); '
                            'with tau = 0 the model has no servo dynamics to be insensitive to')
        if self.has_limits and not self.handles_limits:
            raise PlanError(f'the {self.route} solver does not handle axis limits '
                            '(max_velocity, max_acceleration, max_jerk); use the direct solver')
        if self.max_solve_time is not None and not self.handles_time_budget:
            raise PlanError(f'the {self.route} solver cannot bound its solve time (max_solve_time); '
                            'use the direct solver')
        err = axis_limit_error(D, duration, self.limits) if start is None and not free_end else None
        if err is not None:  # (from a state the rest-to-rest conditions do not apply: IPOPT decides)
            raise err
        frac = self.mesh(duration, params, Form.of_request(params, displacement))
        with self._lock:
            if start is None and not free_end:
                return self._solve(displacement, duration, params, frac)
            return self._solve(displacement, duration, params, frac, start, free_end)

    def solve_constrained(self, displacement, duration: float, params: CraneParams, origin: dict, keep_out=None,
                          route=None, vias=()) -> Plan:
        """A plan past keep-out boxes by ``route`` (``routing``) or through via points; only the direct
        solver plans one."""
        raise PlanError(f'the {self.route} solver does not plan routes past keep_out boxes nor via points; use the '
                        'direct solver')

    def _solve(self, displacement, duration: float, params: CraneParams, frac: np.ndarray,
               start: dict | None = None, free_end: bool = False) -> Plan:
        """Solve one checked request on the mesh ``frac``; called under the solver's lock."""
        raise NotImplementedError

