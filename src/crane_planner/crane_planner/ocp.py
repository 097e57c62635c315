"""The paper's variational planners NVF and RVF (Eqs. 10 and 15) as optimal control problems.

``Problem`` states the optimal control problem once, in scaled variables on
normalized time s = t / T, for both solution routes: the direct one here
(Radau collocation + IPOPT, ``Transcription``) and the paper's indirect one
(``crane_planner.indirect``). ``VariationalSolver`` is what the planning
facade calls.

Scaling: with P = max(|D|, P_MIN) the states are divided by their natural
sizes (position P, velocity P/T, acceleration P/T^2, swing angle P/(g T^2),
...), so every NLP variable is of order one for every T and D the planner
serves; sensitivities to a parameter q are further divided by q (by T for
tau).
"""
from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass, field

import casadi as ca
import numpy as np
from numpy.polynomial import polynomial as poly

from crane_msgs_py.params import CraneParams

from .dynamics import PARAMETERS, augment, crane_ode
from .plan import Plan, PlanError
from .profiles import QUINTIC

#: Smallest position scale (m): a request for D = 0 is still well scaled.
P_MIN = 1e-3

#: Entries of the NLP parameter vector of ``Problem`` (the mesh fractions follow in a transcription).
PROBLEM_PARAMETERS = ('T', 'P', *PARAMETERS, 'acceleration_weight', 'sensitivity_weight',
                      'reference_jerk_weight')


@dataclass(frozen=True)
class Weights:
    """Cost weights of the variational problem, g = jerk^2/2 + ...

    Attributes:
        acceleration: w_a (1/s^2) of w_a a^2/2, the cart acceleration term
            the paper suggests (§4).
        sensitivity: w_s of w_s |S|^2/2, the paper's §4.1 option of
            penalizing the sensitivities along the motion (RVF only); S in
            SI units of the state per SI unit of the parameter.
        reference_jerk: w_r of w_r (a_ref')^2/2 (servo model only). Some
            weight keeps the streamed reference acceleration continuous;
            without it the optimum steps a_ref at both ends. The cart jerk
            j must then start and end at zero and reaches its interior
            values through boundary layers of width tau sqrt(w_r/(1+w_r))
            (see ``VariationalSolver.mesh``) in which the reference jerk
            j + tau j' peaks at about sqrt((1+w_r)/w_r) times j: w_r = 1
            keeps that at 1.4 (w_r = 0.1 gives 3.3) and changes the interior
            only at O(tau^2), since int j tau j' dt = 0.
    """

    acceleration: float = 0.0
    sensitivity: float = 0.0
    reference_jerk: float = 1.0


def _state_scale(name: str, T, P, g, params: dict):
    """Natural size of a state (see the module docstring)."""
    if '/' in name:  # 'd<state>/d<q>'
        state, q = name[1:].split('/d')
        return _state_scale(state, T, P, g, params) / (T if q == 'tau' else params[q])
    return {'y': P, 'v': P / T, 'a': P / T ** 2, 'a_ref': P / T ** 2,
            'theta1': P / (g * T ** 2), 'theta2': P / (g * T ** 2),
            'dtheta1': P / (g * T ** 3), 'dtheta2': P / (g * T ** 3)}[name]


class Problem:
    """NVF (Eq. 10) or RVF (Eq. 15) for the crane, in scaled variables on s = t / T.

    min  int_0^T g dt,  g = u_j^2/2 + w_a a^2/2 + w_s |S|^2/2 + w_r u^2/2
    s.t. x' = f^r(x, u)  (Eqs. 6-8, 18-19, 14),  x(0) = 0,  x(T) = [D, 0, ...]

    with u_j the cart jerk (the input u itself when tau = 0, (a_ref - a)/tau
    with the servo, where u is the reference jerk).

    Attributes:
        ode: the (augmented) crane model.
        states: state names; ``nx`` of them, one input.
        P: symbolic parameter vector, entries ``PROBLEM_PARAMETERS``.
        F: dX/ds = F(X, U, P) in scaled variables.
        G: the cost integrand in scaled units; J = T (P/T^3)^2 int_0^1 G ds.
    """

    def __init__(self, robust: tuple, servo: bool):
        ode = crane_ode(servo)
        self.ode = augment(ode, robust) if robust else ode
        self.servo = servo
        self.robust = self.ode.robust
        self.states = self.ode.states
        self.nx = len(self.states)
        X = ca.SX.sym('X', self.nx)
        U = ca.SX.sym('U')
        P = ca.SX.sym('P', len(PROBLEM_PARAMETERS))
        par = dict(zip(PROBLEM_PARAMETERS, ca.vertsplit(P)))
        T, Ps, g = par['T'], par['P'], par['g']
        sx = ca.vertcat(*[_state_scale(s, T, Ps, g, par) for s in self.states])
        su = Ps / T ** 3
        x, u = sx * X, su * U
        p = ca.vertcat(*[par[q] for q in PARAMETERS])
        f = ca.substitute(ca.substitute(self.ode.f, self.ode.x, x), ca.vertcat(self.ode.u, self.ode.p),
                          ca.vertcat(u, p))
        s = dict(zip(self.states, ca.vertsplit(x)))
        jerk = (s['a_ref'] - s['a']) / par['tau'] if servo else u
        sens = ca.vertcat(*[s[n] for n in self.states if '/' in n])
        gcost = (jerk ** 2 + par['acceleration_weight'] * s['a'] ** 2
                 + par['sensitivity_weight'] * ca.sumsqr(sens)) / 2
        if servo:
            gcost += par['reference_jerk_weight'] * u ** 2 / 2
        self.X, self.U, self.P = X, U, P
        self.F = ca.Function('F', [X, U, P], [T * f / sx])
        self.G = ca.Function('G', [X, U, P], [gcost / su ** 2])
        self.scales = ca.Function('scales', [P], [sx, su])
        # reference velocity and acceleration (for the axis limits), scaled by P/T and P/T^2
        if servo:
            ref_v, ref_a = s['v'] + par['tau'] * s['a'], s['a_ref']
        else:
            ref_v, ref_a = s['v'], s['a']
        self.reference_va = ca.Function('reference_va', [X, P], [ref_v / (Ps / T), ref_a / (Ps / T ** 2)])

    def parameters(self, displacement: float, duration: float, params: CraneParams,
                   weights: Weights) -> np.ndarray:
        values = dict(params.as_dict(), T=duration, P=max(abs(displacement), P_MIN),
                      acceleration_weight=weights.acceleration, sensitivity_weight=weights.sensitivity,
                      reference_jerk_weight=weights.reference_jerk)
        return np.array([values[k] for k in PROBLEM_PARAMETERS], dtype=float)

    def reference(self, x: dict, tau: float) -> tuple:
        """Reference position, velocity, acceleration from states in SI units (``x`` by name).

        With the servo, tau a' + a = a_ref from rest gives y_ref = y + tau v and
        v_ref = v + tau a exactly; with tau = 0 the cart is the reference.
        """
        if self.servo:
            return x['y'] + tau * x['v'], x['v'] + tau * x['a'], x['a_ref']
        return x['y'], x['v'], x['a']

    def boundary(self, displacement: float) -> tuple[np.ndarray, np.ndarray]:
        """Scaled states at s = 0 and s = 1: rest at 0 and at D."""
        x0 = np.zeros(self.nx)
        xT = np.zeros(self.nx)
        xT[self.states.index('y')] = displacement / max(abs(displacement), P_MIN)
        return x0, xT

    def initial_guess(self, displacement: float, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Scaled states (nx, len(s)) and input of the rest-to-rest quintic with quasi-static swing.

        theta1 ~ a/g and dtheta1 ~ jerk/g, which in scaled units are A and U.
        """
        k = displacement / max(abs(displacement), P_MIN)
        q = [k * poly.polyval(s, QUINTIC[i]) for i in range(4)]
        guess = {'y': q[0], 'v': q[1], 'a': q[2], 'a_ref': q[2], 'theta1': q[2], 'dtheta1': q[3]}
        X = np.array([guess.get(n, 0.0 * s) for n in self.states])
        return X, q[3]


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
        nx, N, d = self.problem.nx, self.intervals, self.degree
        X = self.states(w)
        idx = np.arange(N)[:, None] * d + np.arange(d + 1)
        return X[:, idx].transpose(1, 2, 0)

    def node_times(self, frac: np.ndarray) -> np.ndarray:
        """Normalized times of the nodes returned by ``states``."""
        mesh = np.concatenate([[0.0], np.cumsum(frac)])
        s = (mesh[:-1, None] + np.outer(frac, self.tau_nodes[1:])).ravel()
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


def uniform_mesh(intervals: int) -> np.ndarray:
    return np.full(intervals, 1.0 / intervals)


def graded_mesh(intervals: int, layer: float, max_ratio: float = 2.0) -> np.ndarray:
    """Interval fractions that resolve boundary layers of relative width ``layer`` at both ends.

    m intervals at each end grow geometrically by r from ``layer`` to the
    uniform width of the interior; m is the smallest with r <= ``max_ratio``,
    but at most a fifth of the intervals, so a very thin layer costs a larger
    ratio, not the interior's resolution.
    """
    if layer * intervals >= 1.0:
        return uniform_mesh(intervals)

    def grading(m):
        # the interior width where the geometric ends r^i layer (i < m) meet it: r^m layer
        lo, hi = 1.0 + 1e-12, 1e6
        for _ in range(200):
            r = math.sqrt(lo * hi)
            ends = layer * (r ** m - 1.0) / (r - 1.0)
            inner = (1.0 - 2.0 * ends) / (intervals - 2 * m)
            lo, hi = (r, hi) if layer * r ** m < inner else (lo, r)
        return r, inner

    for m in range(1, max(intervals // 5, 1) + 1):
        r, inner = grading(m)
        if r <= max_ratio:
            break
    ends = list(layer * r ** np.arange(m))
    return np.array(ends + [inner] * (intervals - 2 * m) + ends[::-1])


def axis_limit_error(displacement: float, duration: float, max_velocity, max_acceleration):
    """A PlanError if no rest-to-rest motion of D in T can respect the limits, else None.

    Necessary conditions (exact bounds of the bang-bang motion; a smooth
    reference needs strictly more): peak velocity > |D|/T, peak acceleration
    > 4|D|/T^2 and, with both limits, T > |D|/v_max + v_max/a_max when the
    velocity limit is reached.
    """
    D, T = abs(displacement), duration
    D_ = D * (1 + 1e-12)  # 0.1 m/s * 3 s is 0.30000000000000004 m
    if max_velocity is not None and max_velocity * T <= D_:
        return PlanError(f'infeasible: max_velocity {max_velocity:g} m/s is too low to move {D:g} m in '
                         f'{T:g} s (needs more than {D / T:g} m/s)')
    if max_acceleration is not None and max_acceleration * T ** 2 <= 4 * D_:
        return PlanError(f'infeasible: max_acceleration {max_acceleration:g} m/s^2 is too low to move {D:g} m '
                         f'in {T:g} s (needs more than {4 * D / T ** 2:g} m/s^2)')
    if max_velocity is not None and max_acceleration is not None and max_velocity ** 2 < D * max_acceleration:
        t_min = D / max_velocity + max_velocity / max_acceleration
        if T <= t_min:
            return PlanError(f'infeasible: max_velocity {max_velocity:g} m/s and max_acceleration '
                             f'{max_acceleration:g} m/s^2 together need more than {t_min:g} s to move {D:g} m')
    return None


class VariationalSolver:
    """NVF or RVF plans for one (method, intervals, robust set, limits, solver kind); thread-safe.

    The NLP of each model form (ideal tracking, tau = 0; servo, tau > 0) is
    built on first use and kept; requests differ only in NLP parameters and
    bounds, and each solve is warm-started from the last solution of the
    same form. The class attributes are the tuning; the constructor's
    keywords override them per instance.
    """

    #: Collocation intervals when PlanOptions.intervals is None.
    default_intervals = 30
    weights = Weights()
    #: IPOPT iteration cap and wall-time cap (s) per attempt; a solve that needs more is
    #: reported as not converged (a service should answer, even with an error).
    max_iter = 200
    max_wall_time = 10.0
    #: IPOPT's tolerance on the NLP error (the variables are O(1), see the module docstring),
    #: and the level accepted after two iterations that stall above it on rounding noise
    #: (the servo's 1/tau makes the KKT system stiff for small tau).
    tol = 1e-10
    acceptable_tol = 1e-8
    #: End intervals of the servo mesh, as a multiple of the boundary-layer width (see ``mesh``).
    layer_resolution = 0.25
    #: Start of the indirect solver: 'linearized' (independent of IPOPT) or 'direct'.
    indirect_start = 'linearized'

    def __init__(self, method: str, options, **overrides):
        if method not in ('nvf', 'rvf'):
            raise PlanError(f'no variational method {method!r}; choose nvf or rvf')
        for name, value in overrides.items():
            if name.startswith('_') or not hasattr(type(self), name):
                raise TypeError(f'unknown VariationalSolver setting {name!r}')
            setattr(self, name, value)
        self.method = method
        self.intervals = options.intervals or self.default_intervals
        self.robust = tuple(options.robust) if method == 'rvf' else ()
        self.kind = options.solver
        self.max_velocity = options.max_velocity
        self.max_acceleration = options.max_acceleration
        self._problems = {}
        self._transcriptions = {}
        self._indirect = {}
        self._lock = threading.Lock()

    @staticmethod
    def key(method: str, options) -> tuple:
        """Everything that makes two solvers differ: the NLP structure and the limit values."""
        return (method, options.intervals or VariationalSolver.default_intervals,
                tuple(options.robust) if method == 'rvf' else (),
                options.max_velocity, options.max_acceleration, options.solver)

    @property
    def has_limits(self) -> bool:
        return self.max_velocity is not None or self.max_acceleration is not None

    def problem(self, servo: bool) -> Problem:
        if servo not in self._problems:
            self._problems[servo] = Problem(self.robust, servo)
        return self._problems[servo]

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

    def mesh(self, duration: float, params: CraneParams) -> np.ndarray:
        """Interval fractions of T.

        With the servo the optimum has boundary layers at both ends: the cart
        jerk j must start and end at zero (a = a_ref = 0 there), and the
        Euler-Lagrange equation of j^2 + w_r (j + tau j')^2, i.e.
        (1 + w_r) j = w_r tau^2 j'', gives them the width
        l = tau sqrt(w_r / (1 + w_r)). A uniform mesh that does not resolve l
        converges only to first order, so the end intervals are made
        ``layer_resolution`` l wide, growing geometrically into the uniform
        interior.
        """
        if params.tau == 0.0:
            return uniform_mesh(self.intervals)
        w = self.weights.reference_jerk
        layer = params.tau * math.sqrt(w / (1.0 + w)) * self.layer_resolution
        return graded_mesh(self.intervals, layer / duration)

    def solve(self, displacement: float, duration: float, params: CraneParams) -> Plan:
        """The plan from 0 to ``displacement`` (m) in ``duration`` (s) for the model ``params``.

        Raises PlanError naming the solver status if the solver does not
        converge, or the axis limit that makes the request infeasible.
        """
        if 'tau' in self.robust and params.tau == 0.0:
            raise PlanError('robust parameter tau needs a model with tau > 0 (the servo of Eq. 6); '
                            'with tau = 0 the model has no servo dynamics to be insensitive to')
        if self.kind == 'indirect' and self.has_limits:
            raise PlanError('the indirect solver does not handle axis limits '
                            '(max_velocity, max_acceleration); use the direct solver')
        err = axis_limit_error(displacement, duration, self.max_velocity, self.max_acceleration)
        if err is not None:
            raise err
        with self._lock:
            if self.kind == 'indirect':
                return self._solve_indirect(displacement, duration, params)
            return self._solve_direct(displacement, duration, params)

    def _solve_indirect(self, displacement, duration, params):
        from .indirect import IndirectSolver
        servo = params.tau > 0.0
        built = servo not in self._indirect
        if built:
            self._indirect[servo] = IndirectSolver(self.problem(servo))
        solver = self._indirect[servo]
        start = None
        if self.indirect_start == 'direct':
            self._solve_direct(displacement, duration, params)
            start = self.transcription(servo).costate_estimate(self.mesh(duration, params))
        plan = solver.solve(displacement, duration, params, self.weights, self.method,
                            self.mesh(duration, params), start)
        plan.info.update(build_time_s=solver.build_time if built else 0.0, robust=list(self.robust))
        return plan

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

    def _solve_direct(self, displacement, duration, params):
        servo = params.tau > 0.0
        built = servo not in self._transcriptions
        tr = self.transcription(servo)
        pb = tr.problem
        frac = self.mesh(duration, params)
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
        mesh = duration * np.concatenate([[0.0], np.cumsum(frac)])
        mesh[-1] = duration
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
