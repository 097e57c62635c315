"""What the two solution routes of NVF and RVF share: settings, model forms, mesh, request checks.

``VariationalSolver`` is the base of ``direct.DirectSolver`` and
``indirect.IndirectSolver``; the planning facade (``planner.Planner``) picks
the route. A subclass implements ``_solve`` on the mesh this base computes.
"""
from __future__ import annotations

import threading

import numpy as np

from crane_msgs_py.axes import AxisLimits
from crane_msgs_py.names import CART_JOINT, HOIST_JOINT
from crane_msgs_py.params import CraneParams

from .limits import axis_limit_error
from .methods import VARIATIONAL_METHODS
from .plan import Plan, PlanError
from .problem import Form, Problem, Weights, displacements, graded_mesh, servo_layer, uniform_mesh


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
    #: Collocation intervals when PlanOptions.intervals is None.
    default_intervals = 30
    #: ... and with a hoist: its NLP costs several times as much per interval, and 24 intervals leave the
    #: same residual swing on the nominal hoisting move as 30, in less time.
    default_hoist_intervals = 24
    weights = Weights()
    #: End intervals of the servo mesh, as a multiple of the boundary-layer width (see ``mesh``).
    layer_resolution = 0.25

    def __init__(self, method: str, options, **overrides):
        if method not in VARIATIONAL_METHODS:
            raise PlanError(f'no variational method {method!r}; choose nvf or rvf')
        for name, value in overrides.items():
            if name.startswith('_') or not hasattr(type(self), name):
                raise TypeError(f'unknown {type(self).__name__} setting {name!r}')
            setattr(self, name, value)
        self.method, self.options, self.overrides = method, options, overrides
        self.intervals = options.intervals or self.default_intervals
        self.hoist_intervals = options.intervals or self.default_hoist_intervals
        self.robust = tuple(options.robust) if method == 'rvf' else ()
        #: the cart's limits, then the hoist's (``AxisLimits``)
        self.limits, self.hoist_limits = options.limits_of(CART_JOINT), options.limits_of(HOIST_JOINT)
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
                tuple(options.robust) if method == 'rvf' else (),
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
        return self.limits.any or self.hoist_limits.any

    def axis_limits(self, hoisting: bool) -> list[AxisLimits]:
        """The ``AxisLimits`` of each axis planned, the cart's first."""
        return [self.limits, self.hoist_limits] if hoisting else [self.limits]

    def problem(self, form) -> Problem:
        """The ``Problem`` of a ``problem.Form`` (or of ``servo``, a bool, without a hoist)."""
        form = Form.coerce(form)
        if form not in self._problems:
            self._problems[form] = Problem(self.robust, form)
        return self._problems[form]

    def mesh(self, duration: float, params: CraneParams, hoisting: bool = False) -> np.ndarray:
        """Interval fractions of T.

        With the servo the optimum has boundary layers of width
        ``problem.servo_layer`` at both ends. A uniform mesh that does not
        resolve them converges only to first order, so the end intervals are
        made ``layer_resolution`` layers wide, growing geometrically into the
        uniform interior.
        """
        taus = [t for t in (params.tau, params.tau_hoist if hoisting else 0.0) if t > 0.0]
        intervals = self.intervals_for(hoisting)
        if not taus:
            return uniform_mesh(intervals)
        layer = servo_layer(min(taus), self.weights) * self.layer_resolution
        return graded_mesh(intervals, layer / duration)

    def intervals_for(self, hoisting: bool) -> int:
        """Collocation intervals of the model without or with a hoist."""
        return self.hoist_intervals if hoisting else self.intervals

    def solve(self, displacement, duration: float, params: CraneParams, start: dict | None = None,
              free_end: bool = False) -> Plan:
        """The plan from 0 to ``displacement`` (m) in ``duration`` (s) for the model ``params``.

        From rest, or from ``start`` (SI values of the problem's states by
        name, ``continuation.problem_start``); with ``free_end`` the end
        position is free (a stop: ``displacement`` then only sets the scale).

        ``displacement`` is the cart's (a number), or the cart's and the
        hoist's (a pair: the hoist from the model's L1 to L1 + the second,
        an ``AxesPlan``). Raises PlanError naming the solver status if the
        solver does not converge, or the axis limit that makes the request
        infeasible.
        """
        D, Dh = displacements(displacement)
        if Dh is not None and not self.handles_hoist:
            raise PlanError(f'the {self.route} solver does not plan a hoist; use the direct solver')
        if start is not None and self.route != 'direct':
            raise PlanError(f'planning from a moving state needs the direct solver, not the {self.route} one')
        if Dh is not None and start is None and not free_end:
            err = axis_limit_error(Dh, duration, self.hoist_limits)
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
        frac = self.mesh(duration, params, Dh is not None)
        with self._lock:
            if start is None and not free_end:
                return self._solve(displacement, duration, params, frac)
            return self._solve(displacement, duration, params, frac, start, free_end)

    def _solve(self, displacement, duration: float, params: CraneParams, frac: np.ndarray,
               start: dict | None = None, free_end: bool = False) -> Plan:
        """Solve one checked request on the mesh ``frac``; called under the solver's lock."""
        raise NotImplementedError

