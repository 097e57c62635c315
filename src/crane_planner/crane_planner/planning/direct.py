"""The direct solution route of NVF and RVF: the ``collocation.Transcription`` solved by IPOPT.

``DirectSolver`` solves a fixed-duration request with warm starts and
returns a ``collocation.CollocationPlan``; it names the axis limit that makes
a request infeasible. The shortest duration within the limits (free final
time) is ``free_time.FreeTimeSearch``, which ``DirectSolver.fastest`` runs.
Each IPOPT instance (``ipopt.Instance``) calls an ``ipopt.IterationCallback``
of the type ``iteration_callback`` after each iteration.
"""
from __future__ import annotations

import math
import threading
import time

import numpy as np

from crane_msgs_py.crane.axes import AxisLimits
from crane_msgs_py.crane.params import CraneParams

from .collocation import CollocationPlan, Transcription, keep_out_values
from .free_time import FreeTimeSearch
from .ipopt import Instance, IterationCallback
from .keep_out import KeepOut
from .plan import AxesPlan, ModelPath, Plan, PlanError
from .problem import AXIS_SCALES, AXIS_STATES, PROBLEM_PARAMETERS, Form, axis_displacements, breakpoints, displacements
from .routing import NLP_EXTRA, Route, route_guess, via_nodes
from .straight import applies as in_plane_applies
from .straight import on_line, planar_displacement, planar_start
from .variational import VariationalSolver

#: IPOPT's statuses for a solve stopped by its time cap (``max_solve_time``, else ``DirectSolver.max_cpu_time``).
TIME_CAPPED = ('Maximum_WallTime_Exceeded', 'Maximum_CpuTime_Exceeded')


class DirectSolver(VariationalSolver):
    """NVF or RVF by Radau collocation + IPOPT; thread-safe.

    The NLP of each model form (ideal tracking, tau = 0; servo, tau > 0) is
    built on first use and kept; requests differ only in NLP parameters and
    bounds, and each solve is warm-started from this solver's last solution
    of the same form. Reference velocity and acceleration are bounded as
    path constraints (axis limits). ``spawn`` makes more solvers that share
    the built NLPs, to solve side by side (``pool.SolverPool``).
    """

    route = 'direct'
    handles_bridge = True
    #: The type of IPOPT's per-iteration callback (``IterationCallback`` or a subclass).
    iteration_callback = IterationCallback
    #: IPOPT iteration cap: high, so that time is what bounds a solve.
    max_iter = 3000
    #: IPOPT's cap on the CPU time (s) of one attempt when the options set no ``max_solve_time``:
    #: a guard against a runaway solve that counts the solver's work, not the host's load,
    #: so the same request fails or succeeds the same way on a busy machine.
    max_cpu_time = 10.0
    #: With a ``max_solve_time``, a further attempt (a cold start after a failed warm
    #: one, the probes that name an infeasible limit) only starts within this long (s)
    #: of the first: each attempt may use the whole budget, so the solve ends within
    #: ``max_solve_time`` + ``retry_window``.
    retry_window = 0.05
    #: IPOPT's tolerance on the NLP error (the variables are O(1), see ``problem``),
    #: and the level accepted after two iterations that stall above it on rounding noise
    #: (the servo's 1/tau makes the KKT system stiff for small tau).
    tol = 1e-10
    acceptable_tol = 1e-8

    def __init__(self, method: str, options, **overrides):
        super().__init__(method, options, **overrides)
        self._transcriptions = {}  # Form -> Transcription, shared with spawned solvers
        self._transcriptions_lock = threading.Lock()
        self._instances = {}  # Form -> Instance, this solver's own
        self._warm_source = None  # the solver this one was spawned from: its first warm start
        #: while a fastest request runs: when its budget ends (perf_counter s)
        self.deadline = None
        self._free_time = None  # the FreeTimeSearch of ``fastest``, made on first use

    def spawn(self, options=None) -> 'DirectSolver':
        """Another solver like this one (for ``options``, default this one's).

        If the options keep the NLP's structure (``VariationalSolver.structure``:
        limit values and the time budget may differ) it shares this solver's
        transcriptions and their derivatives: it costs a small fraction of a
        build per model form, keeps its own IPOPT instances and warm starts (the
        first taken from this one's last solution), and solves side by side with
        this one.
        """
        other = super().spawn(options)
        if other.structure == self.structure:
            other._transcriptions, other._transcriptions_lock = self._transcriptions, self._transcriptions_lock
            other._warm_source = self  # a cold start takes many times the iterations of a warm one
        return other

    def share(self, transcriptions: dict, lock) -> 'DirectSolver':
        """Build this solver's NLPs into ``transcriptions`` (guarded by ``lock``) and take those already there:
        a store kept for solvers of one ``structure`` and no overrides (``dispatch.plan`` without a cache).
        Its IPOPT instances and warm starts stay its own: it solves as a newly built solver does. Itself."""
        self._transcriptions, self._transcriptions_lock = transcriptions, lock
        return self

    def transcription(self, form, free_time: bool = False, boxes: int = 0, vias: int = 0) -> Transcription:
        """The NLP of one model form (``problem.Form``, or ``servo`` without a hoist; of fixed or free final
        time; with ``boxes`` keep-out boxes and ``vias`` via points), built on first use, shared with spawned
        solvers."""
        form = Form.coerce(form)
        key = ('free', form) if free_time else self._key(form, boxes, vias)
        with self._transcriptions_lock:
            tr = self._transcriptions.get(key)
            if tr is None:
                tr = self._transcriptions[key] = Transcription(self.problem(form), self.intervals_for(form),
                                                               free_time or self.has_limits, free_time=free_time,
                                                               boxes=boxes, vias=vias)
        return tr

    @staticmethod
    def _key(form: Form, boxes: int = 0, vias: int = 0):
        """What a fixed-duration NLP and its IPOPT instance are kept under: the form, with path constraints
        the numbers of keep-out boxes and via points too."""
        return (form, 'constrained', boxes, vias) if boxes or vias else form

    def _instance(self, form: Form, boxes: int = 0, vias: int = 0) -> Instance:
        key = self._key(form, boxes, vias)
        inst = self._instances.get(key)
        if inst is None:
            tr = self.transcription(form, boxes=boxes, vias=vias)
            source = self._warm_source._instances.get(key) if self._warm_source is not None else None
            callback = self.iteration_callback(tr.nw, tr.ng, tr.nlp['p'].shape[0])
            options = dict(self.ipopt_options(), iteration_callback=callback)
            if boxes or vias:  # started from a guess without multipliers: the adaptive barrier
                # parameter takes fewer iterations than the monotone one from it (on bench/route.py's requests,
                # around the column and over the wall alike)
                options.update({'ipopt.warm_start_init_point': 'no', 'ipopt.mu_strategy': 'adaptive'})
            inst = self._instances[key] = Instance.new(tr, options, callback,
                                                       source.warm if source is not None else None)
        return inst.refresh()

    def ipopt_options(self) -> dict:
        # A budget is a promise to a caller, so it is wall time; without one, only the work is capped.
        cap = ({'ipopt.max_cpu_time': self.max_cpu_time} if self.max_solve_time is None
               else {'ipopt.max_wall_time': self.max_solve_time})
        opts = {'print_time': False, 'ipopt.print_level': 0, 'ipopt.sb': 'yes',
                'ipopt.tol': self.tol, 'ipopt.max_iter': self.max_iter,
                'ipopt.acceptable_tol': self.acceptable_tol, 'ipopt.acceptable_iter': 2,
                **cap,
                'ipopt.nlp_scaling_method': 'none',  # scaled by construction
                'ipopt.warm_start_init_point': 'yes',
                # MUMPS analyses the KKT matrix on every solve; on these banded,
                # well-scaled systems QAMD ordering without scaling does it fastest
                'ipopt.mumps_pivot_order': 6, 'ipopt.mumps_scaling': 0,
                'ipopt.mumps_permuting_scaling': 0}
        if self.has_limits:
            opts.update({'ipopt.warm_start_bound_push': 1e-8, 'ipopt.warm_start_mult_bound_push': 1e-8})
        return opts

    def solve_constrained(self, displacement, duration: float, params: CraneParams, origin: dict,
                          keep_out: KeepOut | None = None, route: Route | None = None, vias=()) -> Plan:
        """The rest-to-rest plan of ``solve`` with path constraints: past ``keep_out``'s boxes by ``route``
        (``routing``: both masses the margin and ``routing.NLP_EXTRA`` out of every box at every collocation
        point, started from the route's geometric guess), and through ``vias`` (per via point, each axis's
        position relative to its start, m, by joint name: the reference passes them in order, each at the
        collocation point nearest the time the straight path's timing gives it, ``via_nodes``). From this
        solver's last solution of the same constraints if there is one. ``origin``: where the travel axes
        start (m, by joint name). ``info['route']`` says the route. PlanError if IPOPT finds none."""
        form = Form.of_request(params, displacement)
        if route is not None and route.axis not in form.axes:
            raise PlanError(f'a route {route.kind} a box needs the {route.axis} in the move')
        boxes = len(keep_out.boxes) if keep_out is not None and route is not None else 0
        frac = self.mesh(duration, params, form)
        with self._lock:
            t_build, built = time.perf_counter(), self._key(form, boxes, len(vias)) not in self._instances
            inst = self._instance(form, boxes, len(vias))
            build_time = time.perf_counter() - t_build if built else 0.0
            tr, solver, pb = inst.transcription, inst.solver, inst.transcription.problem
            problem_p = pb.parameters(displacement, duration, params, self.weights)
            if route is not None:  # the detour's size scales its axis
                scale = PROBLEM_PARAMETERS.index(AXIS_SCALES[route.axis])
                problem_p[scale] = max(problem_p[scale], abs(route.excursion))
            scales = {axis: problem_p[PROBLEM_PARAMETERS.index(AXIS_SCALES[axis])] for axis in pb.axes}
            targets = [[via.get(axis, 0.0) / scales[axis] for axis in pb.axes] for via in vias]
            nodes = via_nodes(tr, frac, displacement, vias)
            pvec = np.concatenate([problem_p, frac, keep_out_values(keep_out, origin, NLP_EXTRA) if boxes else [],
                                   tr.via_values(targets, nodes)])
            sx, su = (np.array(v, dtype=float).ravel() for v in pb.scales(problem_p))
            args = dict(p=pvec, **self.bounds(tr, displacement, duration, sx, self.axis_limits(form)))
            kept, same = getattr(inst, 'warm', None), (route, tuple(nodes), self.sign(displacement))
            guess = (route_guess(tr, displacement, frac, route, pvec) if boxes
                     else tr.guess(displacement, frac))
            starts = ([kept[1]] if kept is not None and kept[0] == same else []) + [dict(x0=guess)]
            t0 = time.perf_counter()
            for k, initial in enumerate(starts):
                if k and not self._may_retry(t0):
                    break
                with inst.callback.solving(self.deadline):
                    sol = solver(**args, **initial)
                stats = solver.stats()
                if stats['success']:
                    break
            solve_time = time.perf_counter() - t0
            if not stats['success']:
                what = f'route {route.kind} the keep_out boxes' if route is not None else 'plan through the via points'
                raise PlanError(f'{self.method}: no {what} for this move (IPOPT status {stats["return_status"]} after '
                                f'{stats["iter_count"]} iterations)')
            inst.warm = (same, dict(x0=sol['x'], lam_x0=sol['lam_x'], lam_g0=sol['lam_g']))
            info = {'solver': 'direct', 'status': stats['return_status'], 'iterations': int(stats['iter_count']),
                    'solve_time_s': solve_time, 'build_time_s': build_time,
                    'objective': float(sol['f']) * duration * su[0] ** 2, 'intervals': tr.intervals,
                    'robust': list(self.robust), 'sensitivities': list(pb.robust), 'servo_model': form.servo}
            if route is not None:
                info['route'] = route.kind
            if vias:
                info['route'] = info.get('route') or 'via'
                info['via_times_s'] = [float(duration * tr.node_times(frac)[1 + k]) for k in nodes]
            return self.plan_of(tr, np.array(sol['x']).ravel(), sx, displacement, duration, frac, params, info)

    def fastest(self, displacement: float, params: CraneParams) -> CollocationPlan:
        """The shortest plan of ``displacement`` (m) within this solver's axis limits
        (``free_time.FreeTimeSearch.fastest``)."""
        with self._lock:
            if self._free_time is None:
                self._free_time = FreeTimeSearch(self)
            return self._free_time.fastest(displacement, params)

    def last_solution(self, form: Form) -> dict:
        """x0 / lam_x0 / lam_g0 of this solver's last fixed-duration solution of the model form ``form``."""
        return self._instances[form].warm[1]

    def costates(self, displacement: float, duration: float, params: CraneParams, frac: np.ndarray):
        """Solve on the mesh ``frac`` and return the costate estimate (``Transcription.costate_estimate``).

        The indirect route can start from it.
        """
        with self._lock:
            self._solve(displacement, duration, params, frac)
            form = Form.of(params, False)
            return self.transcription(form).costate_estimate(frac, self.last_solution(form))

    def _may_retry(self, t0: float) -> bool:
        """Whether a further attempt may start, the first having started at ``t0`` (see ``retry_window``)."""
        return self.max_solve_time is None or time.perf_counter() - t0 <= self.retry_window

    def bounds(self, tr: Transcription, displacement, duration: float, sx: np.ndarray, limits,
               start: dict | None = None, free_end: bool = False) -> dict:
        """IPOPT's bounds: the ends (``Problem.boundary``: rest, or ``start``; a free end position with
        ``free_end``), and ``limits``: (v, a, j) of each of the problem's axes."""
        pb = tr.problem
        x0, xT = pb.boundary(displacement, sx, start, free_end)
        lbx = np.full(tr.nw, -np.inf)
        ubx = np.full(tr.nw, np.inf)
        lbx[:pb.nx] = ubx[:pb.nx] = x0
        lbg, ubg = np.zeros(tr.ng), np.zeros(tr.ng)
        end = tr.nres + pb.nx
        free = np.isnan(xT)
        lbg[tr.nres:end] = np.where(free, -np.inf, xT)
        ubg[tr.nres:end] = np.where(free, np.inf, xT)
        if tr.limits:
            d = tr.degree
            bounds = []
            for (vmax, amax, jmax), axis in zip(limits, pb.axes, strict=True):
                _, v_state, a_state, _ = AXIS_STATES[axis]
                sa = sx[pb.states.index(a_state)]
                vmax = np.inf if vmax is None else vmax / sx[pb.states.index(v_state)]
                amax = np.inf if amax is None else amax / sa
                jmax = np.inf if jmax is None else jmax / (sa / duration)
                # less IPOPT's bound relaxation (1e-8 relative), so the limit itself holds
                bounds.append(np.repeat([vmax, amax, jmax], tr.intervals * np.array([d + 2, d + 1, d])) * (1 - 2e-8))
            bound = np.concatenate(bounds)
            lbg[end:end + tr.limit_rows], ubg[end:end + tr.limit_rows] = -bound, bound
        if tr.boxes:  # the keep-out rows after the limits'
            lo, hi = tr.keep_out_bounds()
            rows = slice(tr.keep_out_start, tr.keep_out_start + len(lo))
            lbg[rows], ubg[rows] = lo, hi  # (the via points' rows after them: = 0)
        return dict(lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)

    def _solve(self, displacement, duration, params, frac, start: dict | None = None, free_end: bool = False):
        form = Form.of_request(params, displacement)
        if (form.bridge and self.straight_moves_in_their_plane
                and in_plane_applies(params, self.has_limits, self.weights.bridge)):
            if start is None and not free_end:
                line, planar = planar_displacement(axis_displacements(displacement))
                planar_form = Form.of_request(params, planar)
                return on_line(self._solve(planar, duration, params, self.mesh(duration, params, planar_form)),
                               line)
            reduced = None if start is None else planar_start(axis_displacements(displacement), start)
            if reduced is not None:  # (a stop or a retarget from a state in one vertical plane)
                line, planar, planar_from = reduced
                frac_planar = self.mesh(duration, params, Form.of_request(params, planar))
                return on_line(self._solve(planar, duration, params, frac_planar, planar_from, free_end), line)
        t_build, built = time.perf_counter(), form not in self._instances
        inst = self._instance(form)
        build_time = time.perf_counter() - t_build if built else 0.0
        tr, solver = inst.transcription, inst.solver
        pb = tr.problem
        pvec = np.concatenate([pb.parameters(displacement, duration, params, self.weights, start), frac])
        sx, su = pb.scales(pvec[:len(PROBLEM_PARAMETERS)])
        sx, su = np.array(sx, dtype=float).ravel(), np.array(su, dtype=float).ravel()
        args = dict(p=pvec, **self.bounds(tr, displacement, duration, sx, self.axis_limits(form), start, free_end))
        t0 = time.perf_counter()
        # plans from a state keep their own warm start: a rest-to-rest solution is a poor start for a
        # stop, and a stop's would spoil the next rest-to-rest request; stops keep theirs apart from the
        # other plans from a state (on the spatial crane a retarget's solution led IPOPT to a stop with the
        # bridge running 28 m, a local optimum of the pendulum swinging wide)
        slot = 'warm_stop' if free_end else 'warm_state' if start is not None else 'warm'
        x0, xT = (pb.boundary(displacement, sx, start, free_end) if slot != 'warm' else (None, None))

        def cold():  # the initial guess; only computed when needed
            return dict(x0=tr.guess(displacement, frac, x0, xT))

        kept = getattr(inst, slot, None)
        warm = self.warm_start(tr, kept, displacement) if kept is not None else None
        attempts = ([lambda: warm] if warm is not None else []) + [cold]
        for k, initial in enumerate(attempts):
            if k and not self._may_retry(t0):
                break
            with inst.callback.solving(self.deadline):
                sol = solver(**args, **initial())
            stats = solver.stats()
            if stats['success'] or stats['return_status'] in TIME_CAPPED:
                break
        solve_time = time.perf_counter() - t0
        if not stats['success']:
            raise PlanError(self._failure_message(stats, inst, displacement, duration, pvec, sx, cold(), t0,
                                                  start, free_end))
        setattr(inst, slot, (self.sign(displacement), dict(x0=sol['x'], lam_x0=sol['lam_x'], lam_g0=sol['lam_g'])))
        info = {'solver': 'direct', 'status': stats['return_status'], 'iterations': int(stats['iter_count']),
                'solve_time_s': solve_time, 'build_time_s': build_time,
                'objective': float(sol['f']) * duration * su[0] ** 2, 'intervals': tr.intervals,
                'robust': list(self.robust), 'sensitivities': list(pb.robust), 'servo_model': form.servo}
        if form.hoist:
            info['hoist_servo_model'] = form.hoist_servo
        if start is not None:
            info['from_state'] = True
        return self.plan_of(tr, np.array(sol['x']).ravel(), sx, displacement, duration, frac, params, info, free_end)

    def plan_of(self, tr, w, sx, displacement, duration, frac, params, info,
                free_end: bool = False) -> CollocationPlan | AxesPlan:
        """The CollocationPlan of the solution ``w`` (states scaled by ``sx``) lasting ``duration`` s; with a
        bridge or a hoist an AxesPlan of every axis's. With ``free_end`` (a stop) each axis's displacement
        is where the solution ends."""
        pb = tr.problem
        nodes = tr.interval_nodes(w) * sx  # (N, d+1, nx), SI units
        x = {n: nodes[:, :, i] for i, n in enumerate(pb.states)}
        plans = {}
        for axis, D in pb.displacements_of(displacement).items():
            pos, vel, acc = pb.reference(x, params.tau, axis, params.tau_hoist)
            if free_end:
                D = pos[-1, -1]
            plans[axis] = CollocationPlan(self.method, float(D), float(duration), info,
                                          mesh=duration * breakpoints(frac), coef=acc @ tr.basis,
                                          start=np.stack([pos[:, 0], vel[:, 0]], axis=1))
        # the model as solved, at every collocation point: where the masses go, without integrating again
        path = ModelPath(duration * tr.node_times(frac), dict(zip(pb.states, tr.states(w) * np.reshape(sx, (-1, 1)))))
        if len(plans) == 1:
            plans['cart'].model_path = path
            return plans['cart']
        return AxesPlan(method=self.method, displacement=plans['cart'].displacement, duration=float(duration),
                        info=info, model_path=path, axes=plans,
                        starts={axis: params.L1 if axis == 'hoist' else 0.0 for axis in plans})

    @staticmethod
    def sign(displacement):
        """What a warm start is kept with: the signs of every axis's displacement (``axis_displacements``' order)."""
        return tuple(math.copysign(1.0, d) for d in axis_displacements(displacement).values())

    @staticmethod
    def warm_start(tr: Transcription, warm: tuple, displacement) -> dict | None:
        """The last solution of ``tr``, mirrored in each travel axis whose displacement changed sign; None if
        the hoist's did (it has no mirror: lowering is not hoisting mirrored).

        The crane is symmetric in each travel axis (``Transcription.mirror``):
        the solution for a request mirrored in some axes is the solution
        with those axes' states, inputs and driven swing negated, multipliers
        included; in scaled variables such a request is then as warm as one
        of the same signs. (Exact rest to rest; from a state it mirrors the
        start too, so it is a start point only, as a same-sign warm start is.)
        """
        sign, start = warm
        now = DirectSolver.sign(displacement)
        if sign == now:
            return start
        flipped = [axis for axis, was, new in zip(tr.problem.axes, sign, now, strict=True) if was != new]
        if 'hoist' in flipped:
            return None
        w, g = tr.mirror(flipped)
        return {'x0': w * np.asarray(start['x0']).ravel(), 'lam_x0': w * np.asarray(start['lam_x0']).ravel(),
                'lam_g0': g * np.asarray(start['lam_g0']).ravel()}

    def _failure_message(self, stats, inst: Instance, displacement, duration, pvec, sx, cold, t0,
                         start=None, free_end=False) -> str:
        tr, solver = inst.transcription, inst.solver
        D, Dh = displacements(displacement)
        Db = axis_displacements(displacement).get('bridge')
        where = (('a stop, ' if free_end else '') + f'D={D:g} m, '
                 + (f'bridge {Db:+g} m, ' if Db is not None else '')
                 + (f'hoist {Dh:+g} m, ' if Dh is not None else '') + f'T={duration:g} s')
        status = stats['return_status']
        if status in TIME_CAPPED:
            cap = (f'max_solve_time {self.max_solve_time:g} s' if self.max_solve_time is not None
                   else f"the solver's cap of {self.max_cpu_time:g} s of CPU time")
            return (f'{self.method}: no plan for {where} within {cap} (IPOPT stopped after '
                    f'{stats["iter_count"]} iterations); lengthen the duration, shorten the move '
                    'or raise max_solve_time')
        if not self.has_limits:
            return f'{self.method} solver did not converge for {where} (IPOPT status {status})'
        # Name the limit: the ones that fail on their own, else all of them.
        values = {n: v for limits in self.axis_limits(tr.problem.axes) for n, v in zip(limits.names, limits)
                  if v is not None}
        present, failing = list(values), []
        if tr.problem.axes == ('cart',) and len(present) > 1:  # several axes not probed one by one: all named
            for name in present:
                if not self._may_retry(t0):
                    break
                alone = AxisLimits.named(self.limits.names, (v if n == name else None
                                                             for n, v in zip(self.limits.names, self.limits)))
                with inst.callback.solving(self.deadline):  # counted and timed like every solve
                    solver(p=pvec, **self.bounds(tr, displacement, duration, sx, [alone], start, free_end), **cold)
                if not solver.stats()['success']:
                    failing.append(name)
        culprits = failing or present
        named = ' and '.join(f'{n} {values[n]:g}' for n in culprits)
        return (f'{self.method}: no plan for {where} within {named} (IPOPT status {status}); '
                f'the limit{"s are" if len(culprits) > 1 else " is"} infeasible or too tight to solve')
