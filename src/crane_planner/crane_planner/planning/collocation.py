"""Radau collocation of the NVF/RVF ``Problem``: the NLP transcription and the plan it yields.

``Transcription`` discretizes a ``problem.Problem`` once into a CasADi NLP
whose parameters carry each request (D, T, model, mesh), so nothing is rebuilt
per request; its solution is a ``CollocationPlan``, evaluated exactly from the
collocation polynomials. Axis limits are bounds on the plan's polynomials'
Bernstein coefficients (``bernstein_matrix``). The solves live in
``direct`` (fixed duration) and ``free_time`` (the shortest duration).
"""
from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from .compiled import in_background as compile_in_background
from .plan import Plan, PlanError
from .problem import PROBLEM_PARAMETERS, Problem, breakpoints


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


#: Keep-out boxes' sides beyond this (m) from the origin count as unbounded (an inf side of a box is this).
KEEP_OUT_FAR = 100.0
#: The longest length delta (m) the keep-out rows' smooth maximum (``Transcription._keep_out_point_rows``)
#: rounds over.
KEEP_OUT_SOFTNESS = 0.01
#: delta is also at most the clearance the rows ask for divided by this.
KEEP_OUT_SHARPNESS = 3.0
#: The length (m) the keep-out rows are divided by: O(1) for clearances of centimetres to decimetres.
KEEP_OUT_SCALE = 0.1


def keep_out_parameters(boxes: int) -> int:
    """How many NLP parameters follow the mesh fractions with ``boxes`` keep-out boxes: the travel axes' start
    positions (x, y), the clearance the rows ask for, the smooth maximum's length delta, then x0 x1 y0 y1 z0 z1
    of each box."""
    return 4 + 6 * boxes


def via_parameters(vias: int, nu: int, points: int) -> int:
    """How many NLP parameters the via points take (after the keep-out ones): per via, each axis's target
    position (scaled like the axis) and a selection weight per collocation point (one-hot: where it passes)."""
    return vias * (nu + points)


def keep_out_values(keep_out, origin: dict, extra: float = 0.0) -> np.ndarray:
    """The values of ``keep_out_parameters`` for a ``keep_out.KeepOut`` (its margin plus ``extra``) and the
    travel axes' start positions ``origin`` (m, by joint name)."""
    sides = [np.clip(v, -KEEP_OUT_FAR, KEEP_OUT_FAR) for box in keep_out.boxes
             for pair in zip(box.lower, box.upper) for v in pair]
    clearance = keep_out.margin + extra
    delta = max(min(KEEP_OUT_SOFTNESS, clearance / KEEP_OUT_SHARPNESS), 1e-6)  # (a clearance of 0: sharp)
    return np.array([origin.get('cart', 0.0), origin.get('bridge', 0.0), clearance, delta, *sides])


def smooth_max(values, delta):
    """delta log sum exp(values / delta): the largest of ``values`` (a column, CasADi or numbers), smoothed over
    the length ``delta``; between the maximum and the maximum plus delta log(len(values))."""
    top = ca.mmax(values)  # keeps exp in range (an unbounded side of a box is -100 m); cancels in the sum
    return top + delta * ca.log(ca.sum1(ca.exp((values - top) / delta)))


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

    def __init__(self, problem: Problem, intervals: int, limits: bool, free_time: bool = False, boxes: int = 0,
                 vias: int = 0):
        t0 = time.perf_counter()
        self.problem, self.intervals, self.limits, self.free_time = problem, intervals, limits, free_time
        nx, nu, N, d = problem.nx, problem.nu, intervals, self.degree
        if (boxes or vias) and free_time:
            raise PlanError('keep-out boxes and via points are planned at a fixed duration only')
        self.boxes, self.vias = boxes, vias
        self.tau_nodes, C, self.B, self.basis = radau_coefficients(d)
        npar = len(PROBLEM_PARAMETERS)
        nkeep = keep_out_parameters(boxes) if boxes else 0
        P = ca.SX.sym('P', npar + N + nkeep + via_parameters(vias, nu, N * d))
        Pp, frac = P[:npar], P[npar:npar + N]
        w = ca.SX.sym('w', nx + N * d * (nx + nu) + (1 if free_time else 0))
        # free final time: T = sigma T_0 with sigma the last variable and T_0 the parameter T, which
        # keeps scaling the states; every interval length is then sigma frac[k] of T_0
        sigma = w[-1] if free_time else 1
        frac = frac * sigma
        body = ca.reshape(w[nx:nx + N * d * (nx + nu)], nx + nu, N * d)
        Xc, Uc = body[:nx, :], body[nx:, :]
        Pm = ca.repmat(Pp, 1, N * d)
        Fc, Gc = problem.F.map(N * d)(Xc, Uc, Pm), problem.G.map(N * d)(Xc, Uc, Pm)
        # the collocation residuals xp - h F: their linear part here, the dynamics h F apart (``nlpsol``)
        res, dyn, J, xs = [], [], 0, [w[:nx]]
        C_float = C.tolist()  # (a numpy scalar times an SX goes through numpy's slow dispatch)
        for k in range(N):
            xs = [xs[-1]] + [Xc[:, k * d + j] for j in range(d)]
            for j in range(1, d + 1):
                res.append(sum(C_float[r][j] * xs[r] for r in range(d + 1)))
                dyn.append(frac[k] * Fc[:, k * d + j - 1])
                J += frac[k] * float(self.B[j]) * Gc[k * d + j - 1]
        g = [ca.vertcat(*res), xs[-1]]
        if limits:
            # Bound the plan's reference velocity, acceleration and jerk polynomials
            # (CollocationPlan) on whole intervals through their Bernstein
            # coefficients (a polynomial lies in their hull), not just at the
            # nodes: near-bang-bang solutions overshoot between nodes. Jerk is
            # dA/ds / frac in units of P/T^3 (A the acceleration in P/T^2).
            # One block of velocity, acceleration, jerk bounds per axis, in problem.axes' order.
            nodes = ca.horzcat(w[:nx], Xc)
            v, a = problem.reference_va.map(N * d + 1)(nodes, ca.repmat(Pp, 1, N * d + 1))
            to_bv, to_ba, to_bj = bernstein_matrix(d + 1), bernstein_matrix(d), bernstein_matrix(d - 1)
            for axis in range(nu):
                bv, ba, bj = [], [], []
                for k in range(N):
                    coef = ca.mtimes(self.basis.T, a[axis, k * d:k * d + d + 1].T)  # acceleration, powers of s
                    vel = ca.vertcat(v[axis, k * d], frac[k] * coef / np.arange(1, d + 2))
                    bv.append(ca.mtimes(to_bv, vel))
                    ba.append(ca.mtimes(to_ba, coef))
                    bj.append(ca.mtimes(to_bj, coef[1:] * np.arange(1, d + 1)) / frac[k])
                g += [ca.vertcat(*bv), ca.vertcat(*ba), ca.vertcat(*bj)]
        objective = sigma + self.free_time_cost_weight * J if free_time else J
        #: where the keep-out rows start among the constraints (after the limits'), and their number per point
        self.keep_out_start, self.keep_out_per_point = sum(x.shape[0] for x in g), 2 * boxes
        self.limit_rows = self.keep_out_start - nx * N * d - nx  # the axis limits' rows, after the ends
        keep_out = None
        if boxes:
            self._keep_out_point = self._keep_out_point_rows(boxes)
            Pk = ca.repmat(P[npar + N:npar + N + nkeep], 1, N * d)
            keep_out = ca.vec(self._keep_out_point.map(N * d)(Xc, Pm, Pk))  # point by point
            g.append(keep_out)
        if vias:  # each via point: sum_k sel_k y_ref(s_k) = target, per axis (scaled), sel one-hot on a point
            positions = problem.reference_position.map(N * d)(Xc, ca.repmat(Pp, 1, N * d))  # (nu, N d)
            block = ca.reshape(P[npar + N + nkeep:], nu + N * d, vias)
            for v in range(vias):
                g.append(ca.mtimes(positions, block[nu:, v]) - block[:nu, v])
        #: the constraints without the dynamics' part (linear in the collocation residuals' rows) nor the
        #: keep-out rows: both differentiated by point (``_derivatives_by_point``)
        self._g_rest = ca.vertcat(*(ca.SX(x.shape[0], 1) if x is keep_out else x for x in g))
        g = ca.vertcat(*g)
        self.nres = nx * N * d
        self.ng = g.shape[0]
        self.nlp = {'x': w, 'p': P, 'f': objective,
                    'g': g - ca.vertcat(*dyn, ca.SX(self.ng - self.nres, 1))}
        self._rest = None  # the derivatives of all but the dynamics (``_derivatives_by_point``)
        self.nu = nu
        self.nw = w.shape[0]
        self._derivatives = None
        #: how many times the derivatives were replaced (by their compiled form): instances made before
        #: are made again (``ipopt.Instance.refresh``)
        self.generation = 0
        self._lock = threading.Lock()
        self.build_time = time.perf_counter() - t0

    def _keep_out_point_rows(self, boxes: int) -> ca.Function:
        """The keep-out path constraints at one collocation point: a function of its scaled states X, the
        problem parameters P and ``keep_out_parameters`` Pk.

        A mass p is outside a box by the clearance c if the largest of its six
        signed face distances s_f (x0 - px, px - x1, y0 - py, ...) is at least c.
        The rows ask that of the maximum's smooth form, the log-sum-exp over the
        length delta: smax = delta log sum_f exp(s_f / delta), which lies between
        max s_f and max s_f + delta log 6, and is the maximum to within
        5 delta exp(-g / delta) where the other faces are at least g farther.
        Where faces tie, beside an edge or a corner of the box, smax exceeds the
        maximum, but the distance to the box, Euclidean there, exceeds it too:
        with delta at most c / ``KEEP_OUT_SHARPNESS`` and ``KEEP_OUT_SOFTNESS``,
        smax >= c keeps the mass at least 0.95 c from a box at least 3 delta
        thick each way, and never more than 1.3 mm nearer than c; from a box
        of no thickness (a plane, a post: both faces of an axis tie too) at
        least 0.92 c, 2.3 mm nearer at most (``smooth_max``).
        Unlike the maximum, or face weights that pick a face (a variable and a
        bilinear row per face), the rows are smooth and add no variable: IPOPT
        takes fewer iterations (docs/benchmarks.md). Rows per box: m1's and m2's
        (smax - c) / KEEP_OUT_SCALE >= 0; the NLP has them at every point in turn.
        """
        pb = self.problem
        Pk = ca.SX.sym('Pk', keep_out_parameters(boxes))
        origin, clearance, delta, sides = Pk[:2], Pk[2], Pk[3], ca.reshape(Pk[4:], 6, boxes)
        rows = []
        for b in range(boxes):
            lo, hi = sides[0::2, b], sides[1::2, b]
            for p in pb.masses(pb.X, pb.P, origin):
                faces = ca.vertcat(lo[0] - p[0], p[0] - hi[0], lo[1] - p[1], p[1] - hi[1], lo[2] - p[2], p[2] - hi[2])
                rows.append((smooth_max(faces, delta) - clearance) / KEEP_OUT_SCALE)
        return ca.Function('keep_out', [pb.X, pb.P, Pk], [ca.vertcat(*rows)])

    def via_values(self, targets, nodes: list[int]) -> np.ndarray:
        """The values of ``via_parameters``: ``targets`` (per via, each axis's scaled position) passed at the
        collocation points ``nodes`` (indices among the N d points, ``node_times`` less its first)."""
        values = []
        for target, node in zip(targets, nodes, strict=True):
            select = np.zeros(self.intervals * self.degree)
            select[node] = 1.0
            values += [np.asarray(target, dtype=float), select]
        return np.concatenate(values) if values else np.zeros(0)

    def keep_out_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(lbg, ubg) of the keep-out rows (``_keep_out_point_rows`` at every point): >= 0."""
        count = self.keep_out_per_point * self.intervals * self.degree
        return np.zeros(count), np.full(count, np.inf)

    def nlpsol(self, options: dict) -> ca.Function:
        """A new IPOPT instance of this NLP with ``options``.

        The first one generates the NLP's derivatives (most of a solver's
        build time; by collocation point, ``_derivatives_by_point``); later ones reuse them and cost a small
        fraction of that. Instances share only those functions, which each
        instance calls with its own work arrays, so instances solve side by
        side in different threads; one instance keeps per-call state and must
        serve one call at a time.
        """
        options = dict(options, no_nlp_grad=True, calc_lam_p=False)  # the multipliers of p are never used
        with self._lock:
            if self._derivatives is None:
                t0 = time.perf_counter()
                points = self._point_functions()
                self._derivatives = self._derivatives_by_point(points)
                self.build_time += time.perf_counter() - t0
                compile_in_background(points, self._use_compiled)
            derivatives = self._derivatives
        return ca.nlpsol('variational', 'ipopt', self.nlp, dict(options, **derivatives))

    def _use_compiled(self, points: dict) -> None:
        """The derivatives from the per-point functions compiled (``compiled.in_background``), from now on."""
        derivatives = self._derivatives_by_point(points)
        with self._lock:
            self._derivatives = derivatives
            self.generation += 1

    def _point_functions(self) -> dict:
        """The functions ``_derivatives_by_point`` evaluates at every collocation point: ``Problem.F``'s
        Jacobian c dF/d(X, U), the Hessian d2(mu^T F)/d(X, U)2, with the free time dF/d(X, U)^T mu too."""
        pb = self.problem
        XU, c, mu = ca.vertcat(pb.X, pb.U), ca.SX.sym('c'), ca.SX.sym('mu', pb.nx)
        f = pb.F(pb.X, pb.U, pb.P)
        points = {'jac': ca.Function('jac_F', [pb.X, pb.U, pb.P, c], [c * ca.jacobian(f, XU)]),
                  'hess': ca.Function('hess_F', [pb.X, pb.U, pb.P, mu], [ca.hessian(ca.dot(mu, f), XU)[0]])}
        if self.free_time:
            points['vjp'] = ca.Function('vjp_F', [pb.X, pb.U, pb.P, mu], [ca.jtimes(f, XU, mu, True)])
        if self.boxes:  # the keep-out rows: d/dX, and d2(lam^T rows)/dX2 (they do not depend on U)
            Pk, lam = ca.SX.sym('Pk', keep_out_parameters(self.boxes)), ca.SX.sym('lam', self.keep_out_per_point)
            rows = self._keep_out_point(pb.X, pb.P, Pk)
            points['keep_jac'] = ca.Function('jac_keep_out', [pb.X, pb.P, Pk], [ca.jacobian(rows, pb.X)])
            points['keep_hess'] = ca.Function('hess_keep_out', [pb.X, pb.P, Pk, lam],
                                              [ca.hessian(ca.dot(lam, rows), pb.X)[0]])
        return points

    def _derivatives_by_point(self, points: dict) -> dict:
        """The NLP's gradient, constraint Jacobian and Lagrangian Hessian (as ``nlpsol`` takes them), with the
        dynamics differentiated once per collocation point rather than over the whole NLP.

        The dynamics enter only the collocation residuals, each point's rows through h F(X_i, U_i) of that
        point's own variables (h its interval's length: frac_k, times sigma for the free time). So their
        Jacobian is block diagonal, of blocks -h dF/d(X, U), and so is their part of the Hessian of the
        Lagrangian, of blocks -h d2(mu_i^T F)/d(X, U)2 with mu_i the point's multipliers; with the free time
        sigma also has the column -frac_k F of the Jacobian and the cross terms -frac_k dF/d(X, U)^T mu_i of
        the Hessian. ``Problem.F`` is differentiated once, symbolically, and evaluated at every point
        (``map``). So are the keep-out rows, each point's a function of its own states (blocks
        d rows/dX of the Jacobian, d2(lam^T rows)/dX2 of the Hessian). The rest of the NLP (the residuals'
        linear part, the ends, the limits, the via rows, the cost) is differentiated as a whole; it is small.
        Both are the exact derivatives: IPOPT takes the same steps as with CasADi's own of the whole NLP,
        which cost many times more to build, the Hessian most (a third derivative of the crane's dynamics,
        for RVF). ``points``: the per-point functions (``_point_functions``), interpreted or compiled.
        """
        pb, nx, nu, N, d = self.problem, self.problem.nx, self.nu, self.intervals, self.degree
        n, npar, width = N * d, len(PROBLEM_PARAMETERS), nx + nu
        w, P, J = self.nlp['x'], self.nlp['p'], self.nlp['f']
        if self._rest is None:  # (the same for the interpreted and the compiled per-point functions)
            lam_f, lam_g = ca.SX.sym('lam_f'), ca.SX.sym('lam_g', self.ng)
            self._rest = (ca.Function('nlp_grad_f', [w, P], [J, ca.gradient(J, w)], ['x', 'p'], ['f', 'grad_f_x']),
                          ca.Function('jac_rest', [w, P], [ca.jacobian(self._g_rest, w)]),
                          ca.Function('hess_rest', [w, P, lam_f, lam_g],
                                      [ca.hessian(lam_f * J + ca.dot(lam_g, self._g_rest), w)[0]]),
                          ca.Function('g', [w, P], [self.nlp['g']]))
        grad_f, jac_rest, hess_rest, g_of = self._rest
        jac, hess = points['jac'], points['hess']
        wm, Pm, lfm, lgm = ca.MX.sym('x', self.nw), ca.MX.sym('p', P.shape[0]), ca.MX.sym('lam_f'), \
            ca.MX.sym('lam_g', self.ng)
        body = ca.reshape(wm[nx:nx + n * width], width, n)
        Xc, Uc, Pp = body[:nx, :], body[nx:, :], ca.repmat(Pm[:npar], 1, n)
        frac = ca.kron(Pm[npar:npar + N].T, ca.DM.ones(1, d))  # each point's interval fraction, (1, n)
        h = frac * wm[-1] if self.free_time else frac
        mu_c = ca.reshape(lgm[:self.nres], nx, n)  # each point's multipliers of its residual rows
        jblocks = ca.horzsplit(jac.map(n)(Xc, Uc, Pp, -h), width)
        hblocks = ca.horzsplit(hess.map(n)(Xc, Uc, Pp, mu_c * ca.repmat(-h, nx, 1)), width)
        after = self.nw - nx - n * width  # the free time's sigma
        keep_jac = ca.MX(self.ng, self.nw)
        if self.boxes:  # each point's keep-out rows depend on its states only: blocks as the dynamics'
            k0, rows, nkeep = self.keep_out_start, self.keep_out_per_point, keep_out_parameters(self.boxes)
            Pk = ca.repmat(Pm[npar + N:npar + N + nkeep], 1, n)
            lam_k = ca.reshape(lgm[k0:k0 + rows * n], rows, n)
            kj = ca.horzsplit(points['keep_jac'].map(n)(Xc, Pp, Pk), nx)
            kh = ca.horzsplit(points['keep_hess'].map(n)(Xc, Pp, Pk, lam_k), nx)
            blocks = ca.diagcat(*(ca.horzcat(b, ca.MX(rows, nu)) for b in kj))
            keep_jac = ca.vertcat(ca.MX(k0, self.nw),
                                  ca.horzcat(ca.MX(rows * n, nx), blocks, ca.MX(rows * n, after)),
                                  ca.MX(self.ng - k0 - rows * n, self.nw))
            hblocks = [hb + ca.diagcat(kb, ca.MX(nu, nu)) for hb, kb in zip(hblocks, kh)]
        jac_dyn = ca.vertcat(ca.horzcat(ca.MX(self.nres, nx), ca.diagcat(*jblocks), ca.MX(self.nres, after)),
                             ca.MX(self.ng - self.nres, self.nw))
        hess_dyn = ca.diagcat(ca.MX(nx, nx), *hblocks, ca.MX(after, after))
        if self.free_time:  # sigma, the last variable: its column of each, above the diagonal for the Hessian
            F_c = pb.F.map(n)(Xc, Uc, Pp) * ca.repmat(-frac, nx, 1)
            cross = points['vjp'].map(n)(Xc, Uc, Pp, mu_c * ca.repmat(-frac, nx, 1))
            jac_dyn += ca.vertcat(ca.horzcat(ca.MX(self.nres, self.nw - 1), ca.vec(F_c)),
                                  ca.MX(self.ng - self.nres, self.nw))
            hess_dyn += ca.vertcat(ca.MX(nx, self.nw),
                                   ca.horzcat(ca.MX(n * width, self.nw - 1), ca.vec(cross)),
                                   ca.MX(1, self.nw))
        return {'grad_f': grad_f,
                'jac_g': ca.Function('nlp_jac_g', [wm, Pm], [g_of(wm, Pm), jac_rest(wm, Pm) + jac_dyn + keep_jac],
                                     ['x', 'p'], ['g', 'jac_g_x']),
                'hess_lag': ca.Function('nlp_hess_l', [wm, Pm, lfm, lgm],
                                        [ca.triu(hess_rest(wm, Pm, lfm, lgm) + hess_dyn)],
                                        ['x', 'p', 'lam_f', 'lam_g'], ['triu_hess_gamma_x_x'])}

    # views of the variable vector
    def states(self, w: np.ndarray) -> np.ndarray:
        """Scaled states at s = 0 and at every collocation point, shape (nx, N*d + 1)."""
        nx, nu, N, d = self.problem.nx, self.problem.nu, self.intervals, self.degree
        body = w[nx:nx + N * d * (nx + nu)].reshape(N * d, nx + nu).T
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

    def mirror(self, axes) -> tuple[np.ndarray, np.ndarray]:
        """(signs of the NLP variables, signs of the constraints) of this NLP's solution mirrored in ``axes``.

        A travel axis's mirror (x -> -x for the cart, y -> -y for the bridge)
        maps the crane onto itself: with u(a, b) = (-sin a cos b, sin b, -cos a
        cos b) it negates the axis's states and input and the swing angles it
        drives (``Problem.mirrored``), and leaves the rest and the cost (even in
        each jerk and acceleration) alone. So the optimum of the mirrored
        request is the optimum with those variables negated, the multipliers of
        the constraints negated where the constraints are (residuals of the
        negated states, each axis's limits); the free time's sigma stays.
        """
        pb, N, d = self.problem, self.intervals, self.degree
        sx = np.array([-1.0 if pb.mirrored(name, axes) else 1.0 for name in pb.states])
        su = np.array([-1.0 if axis in axes else 1.0 for axis in pb.axes])
        w = np.concatenate([sx, np.tile(np.concatenate([sx, su]), N * d), [1.0] if self.free_time else []])
        g = [np.tile(sx, N * d), sx]
        if self.limits:  # per axis: the velocity, acceleration and jerk blocks (``__init__``)
            g += [np.full(N * (3 * d + 3), s) for s in su]
        return w, np.concatenate(g)

    def guess(self, displacement, frac: np.ndarray, x0: np.ndarray | None = None,
              xT: np.ndarray | None = None) -> np.ndarray:
        """The NLP variables of ``Problem.initial_guess`` (rest to rest, or from the scaled start ``x0``)."""
        X, U = self.problem.initial_guess(displacement, self.node_times(frac), x0, xT)
        return self.pack(X, U)

    @staticmethod
    def pack(X: np.ndarray, U: np.ndarray) -> np.ndarray:
        """The NLP variables of scaled states ``X`` and inputs ``U`` at the node times (``node_times``): the
        start's states, then each collocation point's states and inputs."""
        return np.concatenate([X[:, 0], np.vstack([X[:, 1:], U[:, 1:]]).T.ravel()])
