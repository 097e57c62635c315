"""The direct solution route of NVF and RVF: Radau collocation of the ``Problem`` + IPOPT.

``Transcription`` discretizes a ``problem.Problem`` once into a CasADi NLP
whose parameters carry each request (D, T, model, mesh), so nothing is rebuilt
per request; ``DirectSolver`` solves it with warm starts and returns a
``CollocationPlan``, evaluated exactly from the collocation polynomials.
"""
from __future__ import annotations

import contextlib
import math
import os
import threading
import time
from dataclasses import dataclass, field

# CasADi's OpenBLAS (under MUMPS) would start a thread per core that spins between
# calls: on matrices this small one thread is faster alone and far faster beside
# other solves. Set before CasADi loads it; an explicit setting is kept.
os.environ.setdefault('OPENBLAS_NUM_THREADS', '1')

import casadi as ca  # noqa: E402
import numpy as np

from crane_msgs_py.params import CraneParams

from .plan import Plan, PlanError
from .problem import PROBLEM_PARAMETERS, Problem, breakpoints
from .variational import VariationalSolver


def radau_coefficients(degree: int):
    """Nodes (0 and the Radau points), derivative matrix C, quadrature weights B and
    the monomial coefficients of the Lagrange basis on those nodes.

    C[r, j] = l_r'(tau_j), B[j] = int_0^1 l_j; B[0] = 0 because the Radau
    rule of ``degree`` points integrates l_0 (of degree ``degree``) exactly.
    """
    nodes = np.array([0.0] + list(ca.collocation_points(degree, 'radau')))
    n = degree + 1
    V = np.vander(nodes, n, increasing=True)
    basis = np.linalg.solve(V, np.eye(n)).T  # basis[r, k]: coefficient of s^k in l_r
    dbasis = basis[:, 1:] * np.arange(1, n)
    C = np.array([[np.polyval(dbasis[r, ::-1], t) for t in nodes] for r in range(n)])
    B = basis @ (1.0 / np.arange(1, n + 1))
    return nodes, C, B, basis


def bernstein_matrix(degree: int) -> np.ndarray:
    """Matrix from a polynomial's monomial coefficients on [0, 1] to its Bernstein coefficients.

    The polynomial lies within the hull of its Bernstein coefficients.
    """
    return np.array([[math.comb(i, k) / math.comb(degree, k) if k <= i else 0.0 for k in range(degree + 1)]
                     for i in range(degree + 1)])


@dataclass
class CollocationPlan(Plan):
    """A plan evaluated from the collocation polynomial of the reference acceleration.

    On mesh interval k, [mesh[k], mesh[k+1]] of length h, the reference
    acceleration is the collocation polynomial A_k(s) = sum_i coef[k, i] s^i
    (s in [0, 1]) of a_ref (servo) or a (tau = 0); velocity and position
    are its integrals from the interval's start values start[k] = (position,
    velocity), and the jerk is A_k'/h. So the four samples are exactly one
    trajectory; the integrals end exactly on the next interval's start
    values because the Radau rule integrates these polynomials exactly, the
    same way the collocation equations do.
    """

    mesh: np.ndarray = field(default=None, repr=False)
    coef: np.ndarray = field(default=None, repr=False)
    start: np.ndarray = field(default=None, repr=False)

    def breakpoints(self) -> np.ndarray:
        return np.asarray(self.mesh, dtype=float)

    def _evaluate(self, t):
        k = np.clip(np.searchsorted(self.mesh, t, side='right') - 1, 0, len(self.mesh) - 2)
        h = self.mesh[k + 1] - self.mesh[k]
        s = ((t - self.mesh[k]) / h)[:, None]
        c = self.coef[k]
        i = np.arange(c.shape[1])
        acc = np.sum(c * s ** i, axis=1)
        jerk = np.sum((c * i)[:, 1:] * s ** i[:-1], axis=1) / h
        vel = self.start[k, 1] + h * np.sum(c * s ** (i + 1) / (i + 1), axis=1)
        pos = (self.start[k, 0] + h * s[:, 0] * self.start[k, 1]
               + h ** 2 * np.sum(c * s ** (i + 2) / ((i + 1) * (i + 2)), axis=1))
        return pos, vel, acc, jerk


class Transcription:
    """Radau collocation of a ``Problem`` on ``intervals`` mesh intervals, built once.

    Radau IIA is stiffly accurate, which the servo's fast mode (rate 1/tau)
    and the boundary layers it causes need. Degree 4 (order 7 at the mesh
    points) is more accurate per NLP variable than degree 3 here.

    NLP variables: the scaled state at s = 0, then per interval the states and
    input at the ``degree`` Radau points; the last point is the interval's
    end, which starts the next one. NLP parameters: the problem parameters
    and the mesh interval fractions, so a new request (D, T, model) never
    rebuilds anything. Rest at s = 0 is a bound on the first variables,
    rest at s = 1 a constraint on the last state.
    """

    degree = 4
    #: Weight of the cost of Eqs. 10/15 beside the duration in the free-time NLP: enough
    #: to make the optimum unique (the limits alone leave the inside of the motion free).
    free_time_cost_weight = 1e-9

    def __init__(self, problem: Problem, intervals: int, limits: bool, free_time: bool = False):
        t0 = time.perf_counter()
        self.problem, self.intervals, self.limits, self.free_time = problem, intervals, limits, free_time
        nx, N, d = problem.nx, intervals, self.degree
        self.tau_nodes, C, self.B, self.basis = radau_coefficients(d)
        npar = len(PROBLEM_PARAMETERS)
        P = ca.SX.sym('P', npar + N)
        Pp, frac = P[:npar], P[npar:]
        w = ca.SX.sym('w', nx + N * d * (nx + 1) + (1 if free_time else 0))
        # free final time: T = sigma T_0 with sigma the last variable and T_0 the parameter T, which
        # keeps scaling the states; every interval length is then sigma frac[k] of T_0
        sigma = w[-1] if free_time else 1
        frac = frac * sigma
        body = ca.reshape(w[nx:nx + N * d * (nx + 1)], nx + 1, N * d)
        Xc, Uc = body[:nx, :], body[nx, :]
        Pm = ca.repmat(Pp, 1, N * d)
        Fc, Gc = problem.F.map(N * d)(Xc, Uc, Pm), problem.G.map(N * d)(Xc, Uc, Pm)
        res, J, xs = [], 0, [w[:nx]]
        for k in range(N):
            xs = [xs[-1]] + [Xc[:, k * d + j] for j in range(d)]
            for j in range(1, d + 1):
                xp = sum(C[r, j] * xs[r] for r in range(d + 1))
                res.append(xp - frac[k] * Fc[:, k * d + j - 1])
                J += frac[k] * self.B[j] * Gc[k * d + j - 1]
        g = [ca.vertcat(*res), xs[-1]]
        if limits:
            # Bound the plan's reference velocity, acceleration and jerk polynomials
            # (CollocationPlan) on whole intervals through their Bernstein
            # coefficients (a polynomial lies in their hull), not just at the
            # nodes: near-bang-bang solutions overshoot between nodes. Jerk is
            # dA/ds / frac in units of P/T^3 (A the acceleration in P/T^2).
            nodes = ca.horzcat(w[:nx], Xc)
            v, a = problem.reference_va.map(N * d + 1)(nodes, ca.repmat(Pp, 1, N * d + 1))
            to_bv, to_ba, to_bj = bernstein_matrix(d + 1), bernstein_matrix(d), bernstein_matrix(d - 1)
            bv, ba, bj = [], [], []
            for k in range(N):
                coef = ca.mtimes(self.basis.T, a[0, k * d:k * d + d + 1].T)  # acceleration, monomials in s
                vel = ca.vertcat(v[0, k * d], frac[k] * coef / np.arange(1, d + 2))
                bv.append(ca.mtimes(to_bv, vel))
                ba.append(ca.mtimes(to_ba, coef))
                bj.append(ca.mtimes(to_bj, coef[1:] * np.arange(1, d + 1)) / frac[k])
            g += [ca.vertcat(*bv), ca.vertcat(*ba), ca.vertcat(*bj)]
        objective = sigma + self.free_time_cost_weight * J if free_time else J
        self.nlp = {'x': w, 'p': P, 'f': objective, 'g': ca.vertcat(*g)}
        self.ng = self.nlp['g'].shape[0]
        self.nres = nx * N * d
        self.nw = w.shape[0]
        self._derivatives = None
        self._lock = threading.Lock()
        self.build_time = time.perf_counter() - t0

    def nlpsol(self, options: dict) -> ca.Function:
        """A new IPOPT instance of this NLP with ``options``.

        The first one generates the NLP's derivatives (most of a solver's
        build time: 0.3 s for NVF, 0.8 s for RVF); later ones reuse them and
        cost about 15 ms. Instances share only those functions, which each
        instance calls with its own work arrays, so instances solve side by
        side in different threads; one instance keeps per-call state and must
        serve one call at a time.
        """
        options = dict(options, no_nlp_grad=True, calc_lam_p=False)  # the multipliers of p are never used
        with self._lock:
            if self._derivatives is None:
                t0 = time.perf_counter()
                solver = ca.nlpsol('variational', 'ipopt', self.nlp, options)
                self._derivatives = {'grad_f': solver.get_function('nlp_grad_f'),
                                     'jac_g': solver.get_function('nlp_jac_g'),
                                     'hess_lag': solver.get_function('nlp_hess_l')}
                self.build_time += time.perf_counter() - t0
                return solver
        return ca.nlpsol('variational', 'ipopt', self.nlp, dict(options, **self._derivatives))

    # views of the variable vector
    def states(self, w: np.ndarray) -> np.ndarray:
        """Scaled states at s = 0 and at every collocation point, shape (nx, N*d + 1)."""
        nx, N, d = self.problem.nx, self.intervals, self.degree
        body = w[nx:nx + N * d * (nx + 1)].reshape(N * d, nx + 1).T
        return np.hstack([w[:nx, None], body[:nx]])

    def interval_nodes(self, w: np.ndarray) -> np.ndarray:
        """Scaled states at the nodes (start, Radau points) of each interval, (N, d+1, nx)."""
        N, d = self.intervals, self.degree
        X = self.states(w)
        idx = np.arange(N)[:, None] * d + np.arange(d + 1)
        return X[:, idx].transpose(1, 2, 0)

    def node_times(self, frac: np.ndarray) -> np.ndarray:
        """Normalized times of the nodes returned by ``states``."""
        s = (breakpoints(frac)[:-1, None] + np.outer(frac, self.tau_nodes[1:])).ravel()
        return np.concatenate([[0.0], s])

    def costate_estimate(self, frac: np.ndarray, solution: dict):
        """(s, X, Lambda) of ``solution`` (x0 and lam_g0 of a warm start): scaled states and costates at every node.

        Stationarity of the NLP Lagrangian in the input at collocation point
        (k, j) reads h B_j G_u - h mu_kj^T F_u = 0, the discrete form of
        dH/du = G_u + lambda^T F_u = 0, so lambda(t_kj) ~ -mu_kj / B_j. The
        node s = 0 takes the costate of the first collocation point.
        """
        w = np.array(solution['x0']).ravel()
        mu = np.array(solution['lam_g0']).ravel()[:self.nres].reshape(-1, self.problem.nx).T
        lam = -mu / np.tile(self.B[1:], self.intervals)
        return self.node_times(frac), self.states(w), np.hstack([lam[:, :1], lam])

    def guess(self, displacement: float, frac: np.ndarray) -> np.ndarray:
        s = self.node_times(frac)
        X, U = self.problem.initial_guess(displacement, s)
        body = np.vstack([X[:, 1:], U[None, 1:]])
        return np.concatenate([X[:, 0], body.T.ravel()])


class _Yielding(ca.Callback):
    """IPOPT's per-iteration callback: a long solve pauses between its iterations.

    IPOPT guards every MUMPS call of the process with one mutex, which a solve
    that factors without pause re-takes before a waiting thread wakes: beside
    one that runs to its time budget, a typical solve would wait for most of
    it. Once a solve has run ``after`` s while another solve of this process
    is running (``solving``), it sleeps half as long as its last iteration
    took after each one (it then gets at most 2/3 of the time), so short
    solves get the linear solver in between. Typical solves never get there.
    A solve alone in its process (a worker's) pauses only past ``alone_after``
    s, and then as long as its last iteration took: by then it is likely one
    that runs to its budget, and it leaves half its core to the other
    processes' typical requests; a warm fastest request (60-120 ms on a slow
    host) is not slowed down.
    Past a ``deadline`` it stops IPOPT at its next iteration (status
    ``User_Requested_Stop``): a request made of several solves (``fastest``)
    ends within its budget.
    """

    after = 0.05
    alone_after = 0.2
    _active = 0  # solves running in this process (all instances)
    _active_lock = threading.Lock()

    def __init__(self, nx: int, ng: int, np_: int):
        ca.Callback.__init__(self)
        self._sizes = {'x': nx, 'lam_x': nx, 'g': ng, 'lam_g': ng, 'f': 1, 'lam_p': np_}
        self.start = self._last = 0.0
        self.deadline = math.inf
        self.construct('yielding', {})

    @contextlib.contextmanager
    def solving(self, deadline: float | None = None):
        """Around one IPOPT call: marks its start, counts it as running, stops it past ``deadline``
        (``time.perf_counter`` s), if given."""
        self.start = self._last = time.perf_counter()
        self.deadline = math.inf if deadline is None else deadline
        with _Yielding._active_lock:
            _Yielding._active += 1
        try:
            yield
        finally:
            with _Yielding._active_lock:
                _Yielding._active -= 1

    def get_n_in(self):
        return ca.nlpsol_n_out()

    def get_n_out(self):
        return 1

    def get_name_in(self, i):
        return ca.nlpsol_out(i)

    def get_name_out(self, i):
        return 'ret'

    def get_sparsity_in(self, i):
        return ca.Sparsity.dense(self._sizes[ca.nlpsol_out(i)])

    def eval(self, arg):
        now = time.perf_counter()
        if now > self.deadline:
            return [1]
        if _Yielding._active > 1 and now - self.start > self.after:
            time.sleep(min(0.5 * (now - self._last), 0.02))
        elif now - self.start > self.alone_after:
            time.sleep(min(now - self._last, 0.02))
        self._last = time.perf_counter()
        return [0]


@dataclass
class _Instance:
    """One IPOPT instance of a transcription, its iteration callback and the warm start it keeps."""

    transcription: Transcription
    solver: ca.Function
    callback: _Yielding
    warm: tuple | None = None  # (sign of D, x0 / lam_x0 / lam_g0 of the solution)
    T0: float | None = None  # free-time instances: the duration T = sigma T0 is scaled by


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
    #: IPOPT iteration cap: high, so that time is what bounds a solve.
    max_iter = 3000
    #: IPOPT's wall-time cap (s) per attempt when the options set no ``max_solve_time``.
    max_wall_time = 10.0
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
        self._transcriptions = {}  # servo -> Transcription, shared with spawned solvers
        self._transcriptions_lock = threading.Lock()
        self._instances = {}  # servo -> _Instance, this solver's own
        self._warm_source = None  # the solver this one was spawned from: its first warm start
        self._deadline = None  # while a fastest request runs: when its budget ends (perf_counter s)

    def spawn(self, options=None) -> 'DirectSolver':
        """Another solver like this one (for ``options``, default this one's).

        If the options keep the NLP's structure (``VariationalSolver.structure``:
        limit values and the time budget may differ) it shares this solver's
        transcriptions and their derivatives: it costs about 15 ms per model form
        instead of a build, keeps its own IPOPT instances and warm starts (the
        first taken from this one's last solution), and solves side by side with
        this one.
        """
        other = super().spawn(options)
        if other.structure == self.structure:
            other._transcriptions, other._transcriptions_lock = self._transcriptions, self._transcriptions_lock
            other._warm_source = self  # a cold start takes 10x the iterations of a warm one
        return other

    def transcription(self, servo: bool) -> Transcription:
        """The NLP of one model form, built on first use, shared with spawned solvers."""
        with self._transcriptions_lock:
            tr = self._transcriptions.get(servo)
            if tr is None:
                tr = self._transcriptions[servo] = Transcription(self.problem(servo), self.intervals,
                                                                 self.has_limits)
        return tr

    def _instance(self, servo: bool) -> _Instance:
        inst = self._instances.get(servo)
        if inst is None:
            tr = self.transcription(servo)
            source = self._warm_source._instances.get(servo) if self._warm_source is not None else None
            callback = _Yielding(tr.nw, tr.ng, tr.nlp['p'].shape[0])
            inst = self._instances[servo] = _Instance(tr, tr.nlpsol(dict(self._ipopt_options(),
                                                                         iteration_callback=callback)),
                                                      callback, source.warm if source is not None else None)
        return inst

    def _ipopt_options(self) -> dict:
        budget = self.max_wall_time if self.max_solve_time is None else self.max_solve_time
        opts = {'print_time': False, 'ipopt.print_level': 0, 'ipopt.sb': 'yes',
                'ipopt.tol': self.tol, 'ipopt.max_iter': self.max_iter,
                'ipopt.acceptable_tol': self.acceptable_tol, 'ipopt.acceptable_iter': 2,
                'ipopt.max_wall_time': budget,
                'ipopt.nlp_scaling_method': 'none',  # scaled by construction
                'ipopt.warm_start_init_point': 'yes',
                # MUMPS analyses the KKT matrix on every solve; on these banded,
                # well-scaled systems QAMD ordering without scaling does it fastest
                'ipopt.mumps_pivot_order': 6, 'ipopt.mumps_scaling': 0,
                'ipopt.mumps_permuting_scaling': 0}
        if self.has_limits:
            opts.update({'ipopt.warm_start_bound_push': 1e-8, 'ipopt.warm_start_mult_bound_push': 1e-8})
        return opts

    def costates(self, displacement: float, duration: float, params: CraneParams, frac: np.ndarray):
        """Solve on the mesh ``frac`` and return the costate estimate (``Transcription.costate_estimate``).

        The indirect route can start from it.
        """
        with self._lock:
            self._solve(displacement, duration, params, frac)
            inst = self._instances[params.tau > 0.0]
            return inst.transcription.costate_estimate(frac, inst.warm[1])

    def _may_retry(self, t0: float) -> bool:
        """Whether a further attempt may start, the first having started at ``t0`` (see ``retry_window``)."""
        return self.max_solve_time is None or time.perf_counter() - t0 <= self.retry_window

    def _bounds(self, tr: Transcription, displacement: float, duration: float, sx: np.ndarray, limits) -> dict:
        pb = tr.problem
        x0, xT = pb.boundary(displacement)
        lbx = np.full(tr.nw, -np.inf)
        ubx = np.full(tr.nw, np.inf)
        lbx[:pb.nx] = ubx[:pb.nx] = x0
        lbg, ubg = np.zeros(tr.ng), np.zeros(tr.ng)
        end = tr.nres + pb.nx
        lbg[tr.nres:end] = ubg[tr.nres:end] = xT
        if tr.limits:
            d = tr.degree
            vmax, amax, jmax = limits
            sa = sx[pb.states.index('a')]
            vmax = np.inf if vmax is None else vmax / sx[pb.states.index('v')]
            amax = np.inf if amax is None else amax / sa
            jmax = np.inf if jmax is None else jmax / (sa / duration)
            # less IPOPT's bound relaxation (1e-8 relative), so the limit itself holds
            bound = np.repeat([vmax, amax, jmax], tr.intervals * np.array([d + 2, d + 1, d])) * (1 - 2e-8)
            lbg[end:], ubg[end:] = -bound, bound
        return dict(lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)

    def _solve(self, displacement, duration, params, frac):
        servo = params.tau > 0.0
        t_build, built = time.perf_counter(), servo not in self._instances
        inst = self._instance(servo)
        build_time = time.perf_counter() - t_build if built else 0.0
        tr, solver = inst.transcription, inst.solver
        pb = tr.problem
        pvec = np.concatenate([pb.parameters(displacement, duration, params, self.weights), frac])
        sx, su = pb.scales(pvec[:len(PROBLEM_PARAMETERS)])
        sx, su = np.array(sx, dtype=float).ravel(), float(su)
        args = dict(p=pvec, **self._bounds(tr, displacement, duration, sx, self.limits))
        t0 = time.perf_counter()

        def cold():  # the initial guess; only computed when needed
            return dict(x0=tr.guess(displacement, frac))

        starts = ([lambda: self._warm_start(inst.warm, displacement)] if inst.warm is not None else []) + [cold]
        for k, start in enumerate(starts):
            if k and not self._may_retry(t0):
                break
            with inst.callback.solving(self._deadline):
                sol = solver(**args, **start())
            stats = solver.stats()
            if stats['success'] or stats['return_status'] == 'Maximum_WallTime_Exceeded':
                break
        solve_time = time.perf_counter() - t0
        if not stats['success']:
            raise PlanError(self._failure_message(stats, inst, displacement, duration, pvec, sx, cold(), t0))
        inst.warm = (math.copysign(1.0, displacement), dict(x0=sol['x'], lam_x0=sol['lam_x'], lam_g0=sol['lam_g']))
        info = {'solver': 'direct', 'status': stats['return_status'], 'iterations': int(stats['iter_count']),
                'solve_time_s': solve_time, 'build_time_s': build_time,
                'objective': float(sol['f']) * duration * su ** 2, 'intervals': tr.intervals,
                'robust': list(self.robust), 'sensitivities': list(pb.robust), 'servo_model': servo}
        return self._plan(tr, np.array(sol['x']).ravel(), sx, displacement, duration, frac, params, info)

    def _plan(self, tr, w, sx, displacement, duration, frac, params, info) -> CollocationPlan:
        """The CollocationPlan of the solution ``w`` (states scaled by ``sx``) lasting ``duration`` s."""
        pb = tr.problem
        nodes = tr.interval_nodes(w) * sx  # (N, d+1, nx), SI units
        pos, vel, acc = pb.reference({n: nodes[:, :, i] for i, n in enumerate(pb.states)}, params.tau)
        return CollocationPlan(self.method, float(displacement), float(duration), info,
                               mesh=duration * breakpoints(frac), coef=acc @ tr.basis,
                               start=np.stack([pos[:, 0], vel[:, 0]], axis=1))

    # -- the fastest plan ----------------------------------------------------------

    def fastest(self, displacement: float, params: CraneParams) -> CollocationPlan:
        """The shortest plan of ``displacement`` (m) within this solver's axis limits: free final time.

        One NLP with the duration as a variable (``Transcription(free_time=True)``:
        T = sigma T_0, minimizing sigma plus a small multiple of the cost of
        Eqs. 10/15). It starts from its own last solution; the first time (or
        if that fails) from the quintic guess at T_0 = 1.3 times the shortest
        quintic within the limits, and failing that from a fixed-duration
        solution (durations 1.5 times apart until one solves). T* is where a
        limit binds. With a ``max_solve_time`` the attempts together (the build
        of the NLP aside) stop at that budget: a PlanError names it.
        """
        from .profiles import quintic_duration
        from .limits import check_fastest_request, shortest_duration_bound
        displacement = check_fastest_request(displacement, self.limits)
        servo = params.tau > 0.0
        bound = shortest_duration_bound(displacement, self.limits)
        with self._lock:
            t_build = time.perf_counter()
            inst = self._free_instance(servo)
            build_time = time.perf_counter() - t_build
            tr, solver, pb = inst.transcription, inst.solver, inst.transcription.problem
            t0 = time.perf_counter()
            self._deadline = None if self.max_solve_time is None else t0 + self.max_solve_time
            try:
                return self._fastest(inst, displacement, params, servo, bound, build_time, t0)
            finally:
                self._deadline = None

    def _fastest(self, inst, displacement, params, servo, bound, build_time, t0) -> CollocationPlan:
        """``fastest``'s attempts, under ``self._deadline`` (see there)."""
        from .profiles import quintic_duration
        tr, solver, pb = inst.transcription, inst.solver, inst.transcription.problem
        fixed_solves = 0
        for attempt in range(3):
            self._check_deadline(displacement, attempt)
            if attempt == 0 and inst.warm is None:  # first: from the quintic's guess, no fixed NLP needed
                T0 = max(1.3 * quintic_duration(displacement, *self.limits), 1.5 * bound)
                start = {'x0': np.append(tr.guess(displacement, self.mesh(T0, params)), 1.0)}
                inst.T0 = T0
            elif inst.warm is None:  # else a fixed-duration solution: durations until one solves
                T0 = max(1.3 * quintic_duration(displacement, *self.limits), 1.5 * bound)
                for _ in range(30):
                    self._check_deadline(displacement, attempt)
                    fixed_solves += 1
                    try:
                        self._solve(displacement, T0, params, self.mesh(T0, params))
                        break
                    except PlanError:
                        T0 *= 1.5
                else:
                    raise PlanError(f'{self.method}: no plan of {displacement:g} m within the limits found')
                start = {'x0': np.append(np.array(self._instances[servo].warm[1]['x0']).ravel(), 1.0)}
                inst.T0 = T0
            else:
                T0 = inst.T0
                start = self._warm_start(inst.warm, displacement)
            frac = self.mesh(T0, params)
            pvec = np.concatenate([pb.parameters(displacement, T0, params, self.weights), frac])
            sx, _ = pb.scales(pvec[:len(PROBLEM_PARAMETERS)])
            sx = np.array(sx, dtype=float).ravel()
            args = self._bounds(tr, displacement, T0, sx, self.limits)
            args['lbx'][-1] = bound / T0 * (1.0 - 1e-9)  # sigma: no motion beats the bound
            with inst.callback.solving(self._deadline):
                sol = solver(p=pvec, **args, **start)
            stats = solver.stats()
            if stats['success']:
                break
            if stats['return_status'] == 'User_Requested_Stop':  # the deadline: the warm start stays good
                self._check_deadline(displacement, attempt + 1)
            if attempt == 2:
                raise self._fastest_failed(stats, displacement)
            inst.warm = None  # not from here: from a fixed-duration solution
        w = np.array(sol['x']).ravel()
        inst.warm = (math.copysign(1.0, displacement), dict(x0=sol['x'], lam_x0=sol['lam_x'], lam_g0=sol['lam_g']))
        info = {'solver': 'direct', 'status': stats['return_status'], 'iterations': int(stats['iter_count']),
                'solve_time_s': time.perf_counter() - t0, 'build_time_s': build_time,
                'intervals': tr.intervals, 'robust': list(self.robust), 'sensitivities': list(pb.robust),
                'servo_model': servo, 'fastest': {'scale_duration_s': T0, 'fixed_solves': fixed_solves,
                                                  'lower_bound_s': bound}}
        return self._plan(tr, w, sx, displacement, float(w[-1]) * T0, frac, params, info)

    def _check_deadline(self, displacement: float, attempts: int) -> None:
        """A PlanError naming ``max_solve_time`` once a fastest request's budget is spent."""
        if self._deadline is not None and time.perf_counter() > self._deadline:
            raise PlanError(f'{self.method}: no fastest plan of {displacement:g} m within max_solve_time '
                            f'{self.max_solve_time:g} s ({attempts} attempt{"s" if attempts != 1 else ""} '
                            'of the free-time NLP did not finish); raise max_solve_time')

    def _fastest_failed(self, stats, displacement) -> PlanError:
        return PlanError(f'{self.method}: the fastest plan of {displacement:g} m did not solve '
                         f'(IPOPT status {stats["return_status"]})')

    def _free_instance(self, servo: bool) -> _Instance:
        key = ('free', servo)
        inst = self._instances.get(key)
        if inst is None:
            with self._transcriptions_lock:
                tr = self._transcriptions.get(key)
                if tr is None:
                    tr = self._transcriptions[key] = Transcription(self.problem(servo), self.intervals,
                                                                   True, free_time=True)
            callback = _Yielding(tr.nw, tr.ng, tr.nlp['p'].shape[0])
            # a warm start sits at its optimum: a small barrier parameter keeps IPOPT there, and the
            # adaptive barrier update leaves it in fewer iterations than the monotone one (the same
            # request 15 -> 8 NVF, 9 -> 4 RVF; a new D of 0.5 m after 0.3 m 197 -> 88)
            options = dict(self._ipopt_options(), iteration_callback=callback,
                           **{'ipopt.mu_init': 1e-6, 'ipopt.mu_strategy': 'adaptive'})
            inst = self._instances[key] = _Instance(tr, tr.nlpsol(options), callback)
        return inst

    @staticmethod
    def _warm_start(warm: tuple, displacement: float) -> dict:
        """The last solution, mirrored if D changed sign.

        The crane is odd-symmetric (f(-x, -u) = -f(x, u), the cost is even),
        so the solution for -D is minus that for D, multipliers included; in
        scaled variables a request of the other sign is then as warm as one
        of the same sign.
        """
        sign, start = warm
        if sign == math.copysign(1.0, displacement):
            return start
        return {k: -v for k, v in start.items()}

    def _failure_message(self, stats, inst: _Instance, displacement, duration, pvec, sx, cold, t0) -> str:
        tr, solver = inst.transcription, inst.solver
        where = f'D={displacement:g} m, T={duration:g} s'
        status = stats['return_status']
        if status == 'Maximum_WallTime_Exceeded':
            cap = (f'max_solve_time {self.max_solve_time:g} s' if self.max_solve_time is not None
                   else f"the solver's time cap {self.max_wall_time:g} s")
            return (f'{self.method}: no plan for {where} within {cap} (IPOPT stopped after '
                    f'{stats["iter_count"]} iterations); lengthen the duration, shorten the move '
                    'or raise max_solve_time')
        if not self.has_limits:
            return f'{self.method} solver did not converge for {where} (IPOPT status {status})'
        # Name the limit: the ones that fail on their own, else all of them.
        names = ('max_velocity', 'max_acceleration', 'max_jerk')
        present = [n for n in names if getattr(self, n) is not None]
        failing = []
        if len(present) > 1:
            for name in present:
                if not self._may_retry(t0):
                    break
                alone = tuple(getattr(self, n) if n == name else None for n in names)
                with inst.callback.solving(self._deadline):  # counted and timed like every solve
                    solver(p=pvec, **self._bounds(tr, displacement, duration, sx, alone), **cold)
                if not solver.stats()['success']:
                    failing.append(name)
        culprits = failing or present
        named = ' and '.join(f'{n} {getattr(self, n):g}' for n in culprits)
        return (f'{self.method}: no plan for {where} within {named} (IPOPT status {status}); '
                f'the limit{"s are" if len(culprits) > 1 else " is"} infeasible or too tight to solve')
