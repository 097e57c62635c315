"""The direct solution route of NVF and RVF: Radau collocation of the ``Problem`` + IPOPT.

``Transcription`` discretizes a ``problem.Problem`` once into a CasADi NLP
whose parameters carry each request (D, T, model, mesh), so nothing is rebuilt
per request; ``DirectSolver`` solves it with warm starts and returns a
``CollocationPlan``, evaluated exactly from the collocation polynomials.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import casadi as ca
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

    def __init__(self, problem: Problem, intervals: int, limits: bool, options: dict):
        t0 = time.perf_counter()
        self.problem, self.intervals, self.limits = problem, intervals, limits
        nx, N, d = problem.nx, intervals, self.degree
        self.tau_nodes, C, self.B, self.basis = radau_coefficients(d)
        npar = len(PROBLEM_PARAMETERS)
        P = ca.SX.sym('P', npar + N)
        Pp, frac = P[:npar], P[npar:]
        w = ca.SX.sym('w', nx + N * d * (nx + 1))
        body = ca.reshape(w[nx:], nx + 1, N * d)
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
            # Bound the plan's reference velocity and acceleration polynomials
            # (CollocationPlan) on whole intervals through their Bernstein
            # coefficients (a polynomial lies in their hull), not just at the
            # nodes: near-bang-bang solutions overshoot between nodes.
            nodes = ca.horzcat(w[:nx], Xc)
            v, a = problem.reference_va.map(N * d + 1)(nodes, ca.repmat(Pp, 1, N * d + 1))
            to_bv, to_ba = bernstein_matrix(d + 1), bernstein_matrix(d)
            bv, ba = [], []
            for k in range(N):
                coef = ca.mtimes(self.basis.T, a[0, k * d:k * d + d + 1].T)  # acceleration, monomials in s
                vel = ca.vertcat(v[0, k * d], frac[k] * coef / np.arange(1, d + 2))
                bv.append(ca.mtimes(to_bv, vel))
                ba.append(ca.mtimes(to_ba, coef))
            g += [ca.vertcat(*bv), ca.vertcat(*ba)]
        self.nlp = {'x': w, 'p': P, 'f': J, 'g': ca.vertcat(*g)}
        self.solver = ca.nlpsol('variational', 'ipopt', self.nlp, options)
        self.ng = self.nlp['g'].shape[0]
        self.nres = nx * N * d
        self.nw = w.shape[0]
        self.warm = None
        self.build_time = time.perf_counter() - t0

    # views of the variable vector
    def states(self, w: np.ndarray) -> np.ndarray:
        """Scaled states at s = 0 and at every collocation point, shape (nx, N*d + 1)."""
        nx, N, d = self.problem.nx, self.intervals, self.degree
        body = w[nx:].reshape(N * d, nx + 1).T
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

    def costate_estimate(self, frac: np.ndarray):
        """(s, X, Lambda) of the last solution: scaled states and costates at every node.

        Stationarity of the NLP Lagrangian in the input at collocation point
        (k, j) reads h B_j G_u - h mu_kj^T F_u = 0, the discrete form of
        dH/du = G_u + lambda^T F_u = 0, so lambda(t_kj) ~ -mu_kj / B_j. The
        node s = 0 takes the costate of the first collocation point.
        """
        _, start = self.warm
        w = np.array(start['x0']).ravel()
        mu = np.array(start['lam_g0']).ravel()[:self.nres].reshape(-1, self.problem.nx).T
        lam = -mu / np.tile(self.B[1:], self.intervals)
        return self.node_times(frac), self.states(w), np.hstack([lam[:, :1], lam])

    def guess(self, displacement: float, frac: np.ndarray) -> np.ndarray:
        s = self.node_times(frac)
        X, U = self.problem.initial_guess(displacement, s)
        body = np.vstack([X[:, 1:], U[None, 1:]])
        return np.concatenate([X[:, 0], body.T.ravel()])


class DirectSolver(VariationalSolver):
    """NVF or RVF by Radau collocation + IPOPT; thread-safe.

    The NLP of each model form (ideal tracking, tau = 0; servo, tau > 0) is
    built on first use and kept; requests differ only in NLP parameters and
    bounds, and each solve is warm-started from the last solution of the
    same form. Reference velocity and acceleration are bounded as path
    constraints (axis limits).
    """

    route = 'direct'
    #: IPOPT iteration cap and wall-time cap (s) per attempt; a solve that needs more is
    #: reported as not converged (a service should answer, even with an error).
    max_iter = 200
    max_wall_time = 10.0
    #: IPOPT's tolerance on the NLP error (the variables are O(1), see ``problem``),
    #: and the level accepted after two iterations that stall above it on rounding noise
    #: (the servo's 1/tau makes the KKT system stiff for small tau).
    tol = 1e-10
    acceptable_tol = 1e-8

    def __init__(self, method: str, options, **overrides):
        super().__init__(method, options, **overrides)
        self._transcriptions = {}

    def transcription(self, servo: bool) -> Transcription:
        if servo not in self._transcriptions:
            opts = {'print_time': False, 'ipopt.print_level': 0, 'ipopt.sb': 'yes',
                    'ipopt.tol': self.tol, 'ipopt.max_iter': self.max_iter,
                    'ipopt.acceptable_tol': self.acceptable_tol, 'ipopt.acceptable_iter': 2,
                    'ipopt.max_wall_time': self.max_wall_time,
                    'ipopt.nlp_scaling_method': 'none',  # scaled by construction
                    'ipopt.warm_start_init_point': 'yes',
                    # MUMPS analyses the KKT matrix on every solve; on these banded,
                    # well-scaled systems QAMD ordering without scaling does it fastest
                    'ipopt.mumps_pivot_order': 6, 'ipopt.mumps_scaling': 0,
                    'ipopt.mumps_permuting_scaling': 0}
            if self.has_limits:
                opts.update({'ipopt.warm_start_bound_push': 1e-8, 'ipopt.warm_start_mult_bound_push': 1e-8})
            self._transcriptions[servo] = Transcription(self.problem(servo), self.intervals,
                                                        self.has_limits, opts)
        return self._transcriptions[servo]

    def costates(self, displacement: float, duration: float, params: CraneParams, frac: np.ndarray):
        """Solve on the mesh ``frac`` and return the costate estimate (``Transcription.costate_estimate``).

        The indirect route can start from it.
        """
        with self._lock:
            self._solve(displacement, duration, params, frac)
            return self.transcription(params.tau > 0.0).costate_estimate(frac)

    def _bounds(self, tr: Transcription, displacement: float, sx: np.ndarray, limits) -> dict:
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
            vmax, amax = limits
            vmax = np.inf if vmax is None else vmax / sx[pb.states.index('v')]
            amax = np.inf if amax is None else amax / sx[pb.states.index('a')]
            # less IPOPT's bound relaxation (1e-8 relative), so the limit itself holds
            bound = np.repeat([vmax, amax], tr.intervals * np.array([d + 2, d + 1])) * (1 - 2e-8)
            lbg[end:], ubg[end:] = -bound, bound
        return dict(lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)

    def _solve(self, displacement, duration, params, frac):
        servo = params.tau > 0.0
        built = servo not in self._transcriptions
        tr = self.transcription(servo)
        pb = tr.problem
        pvec = np.concatenate([pb.parameters(displacement, duration, params, self.weights), frac])
        sx, su = pb.scales(pvec[:len(PROBLEM_PARAMETERS)])
        sx, su = np.array(sx, dtype=float).ravel(), float(su)
        args = dict(p=pvec, **self._bounds(tr, displacement, sx, (self.max_velocity, self.max_acceleration)))
        t0 = time.perf_counter()
        cold = dict(x0=tr.guess(displacement, frac))
        starts = ([self._warm_start(tr, displacement)] if tr.warm is not None else []) + [cold]
        for start in starts:
            sol = tr.solver(**args, **start)
            stats = tr.solver.stats()
            if stats['success'] or stats['return_status'] == 'Maximum_WallTime_Exceeded':
                break
        solve_time = time.perf_counter() - t0
        status = stats['return_status']
        if not stats['success']:
            raise PlanError(self._failure_message(status, tr, displacement, duration, pvec, sx, cold))
        tr.warm = (math.copysign(1.0, displacement), dict(x0=sol['x'], lam_x0=sol['lam_x'], lam_g0=sol['lam_g']))
        N = tr.intervals
        nodes = tr.interval_nodes(np.array(sol['x']).ravel()) * sx  # (N, d+1, nx), SI units
        pos, vel, acc = pb.reference({n: nodes[:, :, i] for i, n in enumerate(pb.states)}, params.tau)
        mesh = duration * breakpoints(frac)
        info = {'solver': 'direct', 'status': status, 'iterations': int(stats['iter_count']),
                'solve_time_s': solve_time, 'build_time_s': tr.build_time if built else 0.0,
                'objective': float(sol['f']) * duration * su ** 2, 'intervals': N,
                'robust': list(self.robust), 'sensitivities': list(pb.robust), 'servo_model': servo}
        return CollocationPlan(self.method, float(displacement), float(duration), info,
                               mesh=mesh, coef=acc @ tr.basis, start=np.stack([pos[:, 0], vel[:, 0]], axis=1))

    @staticmethod
    def _warm_start(tr: Transcription, displacement: float) -> dict:
        """The last solution, mirrored if D changed sign.

        The crane is odd-symmetric (f(-x, -u) = -f(x, u), the cost is even),
        so the solution for -D is minus that for D, multipliers included; in
        scaled variables a request of the other sign is then as warm as one
        of the same sign.
        """
        sign, start = tr.warm
        if sign == math.copysign(1.0, displacement):
            return start
        return {k: -v for k, v in start.items()}

    def _failure_message(self, status, tr, displacement, duration, pvec, sx, cold) -> str:
        where = f'D={displacement:g} m, T={duration:g} s'
        if not self.has_limits:
            return f'{self.method} solver did not converge for {where} (IPOPT status {status})'
        # Name the limit: the ones that fail on their own, else the pair.
        limits = {'max_velocity': (self.max_velocity, None), 'max_acceleration': (None, self.max_acceleration)}
        present = [n for n in limits if getattr(self, n) is not None]
        failing = []
        if len(present) == 2:
            for name, values in limits.items():
                tr.solver(p=pvec, **self._bounds(tr, displacement, sx, values), **cold)
                if not tr.solver.stats()['success']:
                    failing.append(name)
        culprits = failing or present
        named = ' and '.join(f'{n} {getattr(self, n):g}' for n in culprits)
        return (f'{self.method}: no plan for {where} within {named} (IPOPT status {status}); '
                f'the limit{"s are" if len(culprits) > 1 else " is"} infeasible or too tight to solve')
