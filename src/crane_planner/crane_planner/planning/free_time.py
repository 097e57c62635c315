"""The shortest NVF/RVF plan within the axis limits: the free-final-time NLP.

One NLP with the duration as a variable (``collocation.Transcription(free_time=True)``:
T = sigma T_0, minimizing sigma plus a small multiple of the cost of Eqs.
10/15). T* is where a limit binds. ``FreeTimeSearch`` belongs to one
``direct.DirectSolver`` (its transcriptions, bounds, fixed-duration solves
and plans) and keeps its own IPOPT instances and warm starts.
"""
from __future__ import annotations

import time

import numpy as np

from crane_msgs_py.crane.params import CraneParams

from .collocation import CollocationPlan
from .ipopt import Instance
from .limits import check_fastest_request, shortest_duration_bound
from .plan import PlanError
from .problem import PROBLEM_PARAMETERS, Form, axis_displacements, displacements
from .profiles import quintic_duration


class FreeTimeSearch:
    """The fastest plans of one ``direct.DirectSolver`` (``solver``); called under that solver's lock."""

    #: How many free-time NLP attempts a request makes: warm, from the quintic guess, from a fixed solution.
    attempts = 3
    #: The first scale duration T_0, as a multiple of the shortest quintic within the limits.
    quintic_margin = 1.3

    def __init__(self, solver):
        self.solver = solver
        self._instances = {}  # Form -> Instance of the free-time NLP

    def fastest(self, displacement, params: CraneParams) -> CollocationPlan:
        """The shortest plan of ``displacement`` (m; with a hoist the pair of the cart's and the hoist's, or
        by axis name, ``problem.axis_displacements``) within the solver's axis limits (each axis's own).

        It starts from its own last solution; the first time (or if that
        fails) from the quintic guess at T_0 = ``quintic_margin`` times the shortest quintic
        within the limits, and failing that from a fixed-duration solution
        (durations 1.5 times apart until one solves). With a
        ``max_solve_time`` the attempts together (the build of the NLP aside)
        stop at that budget: a PlanError names it.
        """
        solver = self.solver
        moves = axis_displacements(displacement)
        if len(moves) > 1:
            for name, limits in zip(moves, solver.axis_limits(tuple(moves))):
                if name != 'cart' and not limits.bounds_speed:
                    raise PlanError(f'the fastest plan with a {name} needs {limits.names[0]} or {limits.names[1]} '
                                    '(or both)')
            if not any(moves.values()):
                raise PlanError('the fastest plan needs a nonzero displacement')
            displacement = (moves['cart'], moves['hoist']) if tuple(moves) == ('cart', 'hoist') else moves
        else:
            displacement = check_fastest_request(moves['cart'], solver.limits)
        form = Form.of_request(params, displacement)
        bound = max(shortest_duration_bound(d, limits)
                    for d, limits in zip(axis_displacements(displacement).values(), solver.axis_limits(form)))
        t_build = time.perf_counter()
        inst = self._instance(form)
        build_time = time.perf_counter() - t_build
        t0 = time.perf_counter()
        solver.deadline = None if solver.max_solve_time is None else t0 + solver.max_solve_time
        try:
            return self._search(inst, displacement, params, form, bound, build_time, t0)
        finally:
            solver.deadline = None

    def _search(self, inst, displacement, params, form, bound, build_time, t0) -> CollocationPlan:
        """``fastest``'s attempts, under the solver's ``deadline`` (see there)."""
        solver = self.solver
        tr, nlp, pb = inst.transcription, inst.solver, inst.transcription.problem
        fixed_solves = 0
        for attempt in range(self.attempts):
            self._check_deadline(displacement, attempt)
            warm = solver.warm_start(tr, inst.warm, displacement) if inst.warm is not None else None
            if warm is not None:
                T0 = inst.T0
                start = warm
            else:
                quintic = max(quintic_duration(d, *limits) if limits.bounds_speed else 0.0
                              for d, limits in zip(axis_displacements(displacement).values(),
                                                   solver.axis_limits(form)))
                T0 = max(self.quintic_margin * quintic, 1.5 * bound)
                if attempt == 0:  # first: from the quintic's guess, no fixed NLP needed
                    start = {'x0': np.append(tr.guess(displacement, solver.mesh(T0, params, form)), 1.0)}
                else:  # else a fixed-duration solution: durations until one solves
                    T0, solves = self._fixed_solution(displacement, T0, params, attempt)
                    fixed_solves += solves
                    start = {'x0': np.append(np.array(solver.last_solution(form)['x0']).ravel(), 1.0)}
                inst.T0 = T0
            frac = solver.mesh(T0, params, form)
            pvec = np.concatenate([pb.parameters(displacement, T0, params, solver.weights), frac])
            sx, _ = pb.scales(pvec[:len(PROBLEM_PARAMETERS)])
            sx = np.array(sx, dtype=float).ravel()
            args = solver.bounds(tr, displacement, T0, sx, solver.axis_limits(form))
            args['lbx'][-1] = bound / T0 * (1.0 - 1e-9)  # sigma: no motion beats the bound
            with inst.callback.solving(solver.deadline):
                sol = nlp(p=pvec, **args, **start)
            stats = nlp.stats()
            if stats['success']:
                break
            if stats['return_status'] == 'User_Requested_Stop':  # the deadline: the warm start stays good
                self._check_deadline(displacement, attempt + 1)
            if attempt == self.attempts - 1:
                D = displacements(displacement)[0]
                raise PlanError(f'{solver.method}: the fastest plan of {D:g} m did not solve '
                                f'(IPOPT status {stats["return_status"]})')
            inst.warm = None  # not from here: from a fixed-duration solution
        w = np.array(sol['x']).ravel()
        inst.warm = (solver.sign(displacement), dict(x0=sol['x'], lam_x0=sol['lam_x'], lam_g0=sol['lam_g']))
        info = {'solver': 'direct', 'status': stats['return_status'], 'iterations': int(stats['iter_count']),
                'solve_time_s': time.perf_counter() - t0, 'build_time_s': build_time,
                'intervals': tr.intervals, 'robust': list(solver.robust), 'sensitivities': list(pb.robust),
                'servo_model': form.servo, 'fastest': {'scale_duration_s': T0, 'fixed_solves': fixed_solves,
                                                  'lower_bound_s': bound}}
        return solver.plan_of(tr, w, sx, displacement, float(w[-1]) * T0, frac, params, info)

    def _fixed_solution(self, displacement, T0, params, attempt) -> tuple[float, int]:
        """(T_0, solves): the first of durations 1.5 times apart from ``T0`` whose fixed-duration plan solves."""
        for solves in range(1, 31):
            self._check_deadline(displacement, attempt)
            try:
                form = Form.of_request(params, displacement)
                self.solver._solve(displacement, T0, params, self.solver.mesh(T0, params, form))  # under its lock
                return T0, solves
            except PlanError:
                T0 *= 1.5
        D = displacements(displacement)[0]
        raise PlanError(f'{self.solver.method}: no plan of {D:g} m within the limits found')

    def _check_deadline(self, displacement: float, attempts: int) -> None:
        """A PlanError naming ``max_solve_time`` once a fastest request's budget is spent."""
        solver = self.solver
        if solver.deadline is not None and time.perf_counter() > solver.deadline:
            D = displacements(displacement)[0]
            raise PlanError(f'{solver.method}: no fastest plan of {D:g} m within max_solve_time '
                            f'{solver.max_solve_time:g} s ({attempts} attempt{"s" if attempts != 1 else ""} '
                            'of the free-time NLP did not finish); raise max_solve_time')

    def _instance(self, form: Form) -> Instance:
        inst = self._instances.get(form)
        if inst is None:
            solver = self.solver
            tr = solver.transcription(form, free_time=True)
            callback = solver.iteration_callback(tr.nw, tr.ng, tr.nlp['p'].shape[0])
            # a warm start sits at its optimum: a small barrier parameter keeps IPOPT there, and the
            # adaptive barrier update leaves it in fewer iterations than the monotone one (for the same
            # request again and for a new displacement alike, NVF and RVF)
            options = dict(solver.ipopt_options(), iteration_callback=callback,
                           **{'ipopt.mu_init': 1e-6, 'ipopt.mu_strategy': 'adaptive'})
            inst = self._instances[form] = Instance.new(tr, options, callback)
        return inst.refresh()
