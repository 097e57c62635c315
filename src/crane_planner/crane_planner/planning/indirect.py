"""The paper's own solution route (§2.1): Pontryagin's necessary conditions as a TPBVP.

With the Hamiltonian H = g + lambda^T f (Eq. 16) of a ``problem.Problem``
(the same scaled problem the direct solver discretizes), the necessary
conditions (Eq. 17) are x' = dH/dlambda, lambda' = -dH/dx and dH/du = 0; H is
quadratic in the single input u, so dH/du = 0 gives u in closed form. Rest at
both ends fixes all 2 n boundary conditions. The boundary value problem is
solved by ``scipy.integrate.solve_bvp`` (4th-order collocation with mesh
refinement) with CasADi-generated right-hand side and Jacobian.

The start is either the linearized problem (the dynamics linearized about
rest, a linear TPBVP solved the same way from zero; independent of the
direct solver) or, when a ``direct.DirectSolver`` is given as ``start``, the
direct solution with costates estimated from IPOPT's multipliers. It is the
baseline for correctness and speed, not the fast path.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import casadi as ca
import numpy as np
from scipy.integrate import simpson, solve_bvp

from .plan import Plan, PlanError
from .problem import Problem, breakpoints
from .variational import VariationalSolver


class Tpbvp:
    """The necessary conditions (Eq. 17) of a Problem as CasADi functions of z = [x; lambda].

    Attributes:
        rhs, jac: z' (per unit s = t/T) and its Jacobian dz'/dz, functions of (z, P).
        control: the minimizing input u(z, P) (dH/du = 0), scaled.
        cost: the cost integrand at that input.
    """

    def __init__(self, problem: Problem, linearized: bool = False):
        X, U, P = problem.X, problem.U, problem.P
        nx = problem.nx
        lam = ca.SX.sym('lam', nx)
        F = problem.F(X, U, P)
        if linearized:  # about rest: the LQ problem, whose TPBVP is linear
            rest = ca.DM.zeros(nx + 1)
            Fx, Fu = (ca.substitute(ca.jacobian(F, v), ca.vertcat(X, U), rest) for v in (X, U))
            F = Fx @ X + Fu @ U
        G = problem.G(X, U, P)
        H = G + ca.dot(lam, F)  # Eq. 16
        Hu = ca.gradient(H, U)
        Huu = ca.hessian(H, U)[0]
        if ca.depends_on(Huu, U):
            raise ValueError('the Hamiltonian must be quadratic in the input')
        u = -ca.substitute(Hu, U, 0) / Huu  # dH/du = 0, exact for a quadratic H
        z = ca.vertcat(X, lam)
        zdot = ca.substitute(ca.vertcat(F, -ca.gradient(H, X)), U, u)
        self.problem = problem
        self.nx = nx
        self.rhs = ca.Function('rhs', [z, P], [zdot])
        self.jac = ca.Function('rhs_jacobian', [z, P], [ca.jacobian(zdot, z)])
        self.control = ca.Function('control', [z, P], [u])
        self.cost = ca.Function('cost', [z, P], [ca.substitute(G, U, u)])


def _solve(tp: Tpbvp, pvec, x0, xT, s, z, tol, max_nodes):
    n = 2 * tp.nx
    pcol = pvec[:, None]

    def fun(_s, zz):
        return np.asarray(tp.rhs(zz, pcol))

    def fun_jac(_s, zz):
        m = zz.shape[1]
        return np.asarray(tp.jac(zz, pcol)).reshape(n, m, n).transpose(0, 2, 1)

    def bc(za, zb):
        return np.concatenate([za[:tp.nx] - x0, zb[:tp.nx] - xT])

    ea = np.zeros((n, n))
    ea[np.arange(tp.nx), np.arange(tp.nx)] = 1.0
    eb = np.zeros((n, n))
    eb[tp.nx + np.arange(tp.nx), np.arange(tp.nx)] = 1.0

    def bc_jac(_za, _zb):
        return ea, eb

    return solve_bvp(fun, bc, s, z, fun_jac=fun_jac, bc_jac=bc_jac, tol=tol, max_nodes=max_nodes)


@dataclass
class BvpPlan(Plan):
    """A plan evaluated from solve_bvp's C1 cubic interpolant of the TPBVP solution."""

    solution: object = field(default=None, repr=False)
    tpbvp: Tpbvp = field(default=None, repr=False)
    pvec: np.ndarray = field(default=None, repr=False)
    tau: float = 0.0

    def breakpoints(self) -> np.ndarray:
        return self.solution.x * self.duration  # the cubic interpolant's knots

    def _evaluate(self, t):
        pb = self.tpbvp.problem
        sx, su = (np.asarray(v, dtype=float) for v in pb.scales(self.pvec))
        z = self.solution.sol(t / self.duration)
        x = dict(zip(pb.states, z[:pb.nx] * sx))
        jerk = su.item() * np.asarray(self.tpbvp.control(z, self.pvec[:, None])).ravel()
        return (*pb.reference(x, self.tau), jerk)


class IndirectSolver(VariationalSolver):
    """NVF or RVF by the TPBVP of Pontryagin's conditions; thread-safe.

    The CasADi functions of each model form's conditions (and of their
    linearization, the default start) are built on first use and kept.
    Axis limits are not handled (state constraints would change the
    necessary conditions); a request with limits is refused.
    """

    route = 'indirect'
    handles_limits = False
    handles_time_budget = False  # scipy's solve_bvp has no time limit
    handles_hoist = False
    #: solve_bvp's relative residual tolerance; 1e-4 already agrees with a fine direct
    #: solution to 1e-8 m in position, 1e-5 leaves a margin.
    tol = 1e-5
    max_nodes = 200_000

    def __init__(self, method: str, options, start=None, **overrides):
        """``start``: None (the linearized start) or a ``direct.DirectSolver`` whose
        solution, with costates from its multipliers, starts each TPBVP."""
        super().__init__(method, options, **overrides)
        self.start = start
        self._tpbvps = {}

    def spawn(self, options=None) -> 'IndirectSolver':
        """Another indirect solver (nothing shared but a spawn of the start)."""
        return IndirectSolver(self.method, options or self.options,
                              start=self.start.spawn(options) if self.start is not None else None,
                              **self.overrides)

    def _solve(self, displacement, duration, params, frac) -> BvpPlan:
        """Raises PlanError naming solve_bvp's status message if it fails."""
        method = self.method
        servo = params.tau > 0.0
        built = servo not in self._tpbvps
        t0 = time.perf_counter()
        if built:  # the conditions and their linearization, the default start
            problem = self.problem(servo)
            self._tpbvps[servo] = (Tpbvp(problem), Tpbvp(problem, linearized=True))
        build_time = time.perf_counter() - t0 if built else 0.0
        tpbvp, linearized = self._tpbvps[servo]
        pb = tpbvp.problem
        pvec = pb.parameters(displacement, duration, params, self.weights)
        sx, _ = pb.scales(pvec)
        x0, xT = pb.boundary(displacement, np.array(sx, dtype=float).ravel())
        if self.start is None:
            t0 = time.perf_counter()
            s = breakpoints(frac)
            lin = _solve(linearized, pvec, x0, xT, s, np.zeros((2 * pb.nx, s.size)), self.tol, self.max_nodes)
            if not lin.success:
                raise PlanError(f'indirect {method}: the linearized TPBVP failed: {lin.message}')
            s, z = lin.x, lin.y
        else:  # solve time counts from here: the direct solve is the start's, not ours
            s, X, L = self.start.costates(displacement, duration, params, frac)
            z = np.vstack([X, L])
            t0 = time.perf_counter()
        sol = _solve(tpbvp, pvec, x0, xT, s, z, self.tol, self.max_nodes)
        elapsed = time.perf_counter() - t0
        if not sol.success:
            raise PlanError(f'indirect {method} solver did not converge for D={displacement:g} m, '
                            f'T={duration:g} s (solve_bvp status {sol.status}: {sol.message})')
        su = float(pb.scales(pvec)[1])
        # J = T (P/T^3)^2 int_0^1 G ds, by Simpson's rule on twice the final mesh
        sm = np.sort(np.concatenate([sol.x, (sol.x[1:] + sol.x[:-1]) / 2]))
        objective = float(simpson(np.asarray(tpbvp.cost(sol.sol(sm), pvec[:, None])).ravel(), x=sm))
        info = {'solver': 'indirect', 'status': sol.message, 'iterations': int(sol.niter),
                'solve_time_s': elapsed, 'objective': objective * duration * su ** 2,
                'intervals': int(sol.x.size - 1), 'sensitivities': list(pb.robust), 'servo_model': pb.servo,
                'start': 'linearized' if self.start is None else 'direct',
                'build_time_s': build_time, 'robust': list(self.robust)}
        return BvpPlan(method, float(displacement), float(duration), info, solution=sol, tpbvp=tpbvp,
                       pvec=pvec, tau=params.tau)
