"""CasADi model of the double-pendulum crane used for planning (paper §2-3).

The one place in the planner where Eqs. 18-19 live. It is deliberately
independent of ``crane_sim``'s numpy implementation so that the two
cross-check each other (test/test_dynamics.py).

Two state-space forms of Eqs. 7-8, both with the *reference* as what the
planner chooses:

* ideal tracking (tau = 0): x = [y, v, a, theta1, theta2, dtheta1, dtheta2],
  u = cart jerk a' (the cart is the reference);
* servo (tau > 0, Eq. 6): x = [y, v, a, a_ref, theta1, ...], u = reference
  jerk a_ref', with tau a' + a = a_ref.

``augment`` adds the sensitivity states of Eqs. 13-14 / 25-26.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import casadi as ca
import numpy as np

from crane_msgs_py.crane.params import PARAMETER_NAMES

from .signals import SPATIAL_SWING_STATES, SWING_STATES, swing_rates

#: Order of the model parameter vector ``p`` of every model here (CraneParams' fields).
PARAMETERS = PARAMETER_NAMES
#: Each axis's states: position, velocity, acceleration and (with its servo) reference acceleration;
#: the hoist's position is its displacement from the start length L1.
CART_STATES = ('y', 'v', 'a', 'a_ref')
BRIDGE_STATES = ('yb', 'vb', 'ab', 'ab_ref')
HOIST_STATES = ('h', 'hv', 'ha', 'ha_ref')


def swing_accelerations(theta1, theta2, dtheta1, dtheta2, a, L1, L2, m1, m2, g, c1=0.0, c2=0.0):
    """(theta1'', theta2'') of Eqs. 18-19, plus viscous joint damping, for the cart acceleration ``a``.

    Eqs. 18-19 are linear in the angular accelerations:
        [(m1+m2) L1 + m2 L2 k2,  m2 L2 k2] [th1'']   [(m1+m2)(a cos th1 - g sin th1) + m2 L2 (th1'+th2')^2 s2]
        [L1 k2 + L2,             L2      ] [th2''] = [a cos(th1+th2) - g sin(th1+th2) - L1 th1'^2 s2         ]
    with k2 = cos th2, s2 = sin th2. The determinant is L1 L2 (m1 + m2 s2^2) > 0,
    so Cramer's rule is safe for every configuration. The first row is
    Lagrange's equation of theta1 with the lower cable's absolute angle held
    as a coordinate, over L1; the second that of the absolute angle, over
    m2 L2. Joint damping (torques -c1 th1' at the cart, -c2 th2' between the
    cables) adds their generalized forces: (-c1 th1' + c2 th2') / L1 to the
    first right-hand side and -c2 th2' / (m2 L2) to the second. Works on
    CasADi symbols and on floats.
    """
    k2, s2 = ca.cos(theta2), ca.sin(theta2)
    mt = m1 + m2
    m11, m12 = mt * L1 + m2 * L2 * k2, m2 * L2 * k2
    m21, m22 = L1 * k2 + L2, L2
    r1 = mt * (a * ca.cos(theta1) - g * ca.sin(theta1)) + m2 * L2 * (dtheta1 + dtheta2) ** 2 * s2
    r2 = a * ca.cos(theta1 + theta2) - g * ca.sin(theta1 + theta2) - L1 * dtheta1 ** 2 * s2
    r1 += (c2 * dtheta2 - c1 * dtheta1) / L1
    r2 -= c2 * dtheta2 / (m2 * L2)
    det = L1 * L2 * (m1 + m2 * s2 ** 2)
    return (m22 * r1 - m12 * r2) / det, (m11 * r2 - m21 * r1) / det


def _lagrange_terms(masses, q, dq, r, dr, ddr, gravity):
    """(M, bias) of Lagrange's equations M q'' + bias = Q of point masses at prescribed-motion positions.

    ``masses``: pairs (m_i, p_i(q, r)) with q the free coordinates and r(t)
    the prescribed ones (rates dr, accelerations ddr). With J_i = dp_i/dq,
    d/dt dT/dq' - dT/dq = sum m_i J_i^T p_i'' for T = sum m_i |p_i'|^2 / 2,
    and p_i'' = J_i q'' + rest_i (the chain rule's other terms, in q', r', r''),
    so M = sum m_i J_i^T J_i and bias = sum m_i J_i^T (rest_i + ``gravity``),
    the potential's gradient being m_i J_i^T times the gravity vector
    (g along the up axis). Differentiating T this way keeps the expressions a
    quarter the size of differentiating the Lagrangian twice.
    """
    coords, rates = ca.vertcat(q, r), ca.vertcat(dq, dr)
    M, bias = 0, 0
    for m, pos in masses:
        J = ca.jacobian(pos, q)
        velocity = ca.jtimes(pos, coords, rates)
        # the acceleration of the mass without its q'' part: J q'' is added by M q'' below
        rest = ca.jtimes(velocity, ca.vertcat(coords, dr), ca.vertcat(rates, ddr))
        M += m * J.T @ J
        bias += m * J.T @ (rest + gravity)
    return M, bias


@functools.lru_cache(maxsize=1)
def hoisting_swing() -> ca.Function:
    """(theta1'', theta2'') of the crane whose upper cable's length L1(t) is prescribed, from its Lagrangian.

    Not written out by hand: CasADi differentiates the kinematics of the
    same two masses as Eqs. 18-19 with the cart position y(t) and L1(t) as
    given functions of time. With p1 = (y - L1 sin th1, -L1 cos th1),
    p2 = p1 - L2 (sin(th1+th2), cos(th1+th2)), the Lagrangian
    L = sum m_i |p_i'|^2 / 2 - g sum m_i z_i and q = (th1, th2), Lagrange's
    equations d/dt dL/dq' - dL/dq = Q read, with J_i = dp_i/dq,

        sum_i m_i J_i^T (p_i'' + (0, g)) = Q,   p_i'' = J_i q'' + (the rest of p_i'', by the chain rule),

    i.e. M q'' = Q - sum_i m_i J_i^T (rest_i + (0, g)), M = sum_i m_i J_i^T J_i
    (the identity d/dt dT/dq' - dT/dq = sum m_i J_i^T p_i'' of T = sum m_i
    |p_i'|^2 / 2 keeps the expressions a quarter the size of differentiating
    L twice). Q = (-c1 th1', -c2 th2') are the joint damping torques. The
    chain rule brings the hoist's terms in L1' and L1'' (Coriolis and the
    like); with L1 constant this is Eqs. 18-19 (``swing_accelerations``,
    tested), and crane_sim's Newton-projected form agrees (tested). Inputs
    theta1, theta2, dtheta1, dtheta2, a (= y''), L1, dL1, ddL1, L2, m1, m2,
    g, c1, c2; outputs ddtheta1, ddtheta2.
    """
    q, dq = ca.SX.sym('q', 2), ca.SX.sym('dq', 2)
    r, dr, ddr = ca.SX.sym('r', 2), ca.SX.sym('dr', 2), ca.SX.sym('ddr', 2)
    L2, m1, m2, g, c1, c2 = (ca.SX.sym(n) for n in ('L2', 'm1', 'm2', 'g', 'c1', 'c2'))
    (th1, th2), (y, L1) = ca.vertsplit(q), ca.vertsplit(r)
    p1 = ca.vertcat(y - L1 * ca.sin(th1), -L1 * ca.cos(th1))
    p2 = p1 - L2 * ca.vertcat(ca.sin(th1 + th2), ca.cos(th1 + th2))
    M, bias = _lagrange_terms(((m1, p1), (m2, p2)), q, dq, r, dr, ddr, ca.vertcat(0, g))
    rest = bias - ca.vertcat(-c1 * dq[0], -c2 * dq[1])
    det = M[0, 0] * M[1, 1] - M[0, 1] * M[1, 0]
    dd1 = -(M[1, 1] * rest[0] - M[0, 1] * rest[1]) / det
    dd2 = -(M[0, 0] * rest[1] - M[1, 0] * rest[0]) / det
    # the cart's velocity cancels (a uniformly moving cart is a Galilean frame) but not symbolically;
    # common subexpressions shared (fewer operations for every derivative the NLP takes)
    dd1, dd2 = ca.vertsplit(ca.cse(ca.substitute(ca.vertcat(dd1, dd2), dr[0], 0.0)))
    return ca.Function('hoisting_swing', [th1, th2, dq[0], dq[1], ddr[0], L1, dr[1], ddr[1], L2, m1, m2, g, c1, c2],
                       [dd1, dd2], ['theta1', 'theta2', 'dtheta1', 'dtheta2', 'a', 'L1', 'dL1', 'ddL1', 'L2', 'm1',
                                    'm2', 'g', 'c1', 'c2'], ['ddtheta1', 'ddtheta2'])


def cable_direction(a, b, lib=ca):
    """u(a, b) = (-sin a cos b, sin b, -cos a cos b): a cable's unit vector (contract "The spatial crane").

    ``a`` the in-plane angle of Eqs. 18-19 (positive when the load lags a
    positive cart acceleration: x1 = x - L1 sin theta1), ``b`` the angle out of
    the x-z plane, positive towards +y. ``lib``: ``casadi`` for symbols (a
    column), ``numpy`` for arrays of angles (its rows).
    """
    return _column(lib, -lib.sin(a) * lib.cos(b), lib.sin(b), -lib.cos(a) * lib.cos(b))


def _column(lib, *rows):
    """``rows`` stacked: a CasADi column, or a NumPy array of one row each (numbers broadcast to the arrays)."""
    return ca.vertcat(*rows) if lib is ca else np.stack(np.broadcast_arrays(*rows))


def masses_at(x, y, L1, L2, theta1, theta2, phi1, phi2, lib=ca):
    """(p1, p2): both masses' positions (m) in ``crane_base`` (contract "The spatial crane").

    p1 = s + L1 u(theta1, phi1), p2 = p1 + L2 u(theta1 + theta2, phi1 + phi2)
    (``cable_direction``), s = (x, y, 0) the suspension point; the planar
    crane is phi1 = phi2 = 0 (Fig. 1: x1 = x - L1 sin theta1, z1 = -L1 cos
    theta1). ``lib``: ``casadi`` for symbols (the NLP's, the Lagrangian's),
    ``numpy`` for arrays (a path: each (3, n); every input a number or an array of the same n).
    """
    p1 = _column(lib, x, y, 0 * x) + L1 * cable_direction(theta1, phi1, lib)
    return p1, p1 + L2 * cable_direction(theta1 + theta2, phi1 + phi2, lib)


@functools.lru_cache(maxsize=1)
def mass_positions() -> ca.Function:
    """``masses_at`` as a CasADi function: inputs x, y, L1, L2, theta1, theta2, phi1, phi2; outputs p1, p2."""
    names = ('x', 'y', 'L1', 'L2', 'theta1', 'theta2', 'phi1', 'phi2')
    inputs = [ca.SX.sym(n) for n in names]
    return ca.Function('mass_positions', inputs, list(masses_at(*inputs)), list(names), ['p1', 'p2'])


def _inverse2(X):
    """The inverse of a 2x2 matrix by its adjugate (for the positive definite blocks of a mass matrix)."""
    det = X[0, 0] * X[1, 1] - X[0, 1] * X[1, 0]
    return ca.vertcat(ca.horzcat(X[1, 1], -X[0, 1]), ca.horzcat(-X[1, 0], X[0, 0])) / det


@functools.lru_cache(maxsize=1)
def spatial_swing() -> ca.Function:
    """(theta1'', theta2'', phi1'', phi2'') of the spatial crane, from its Lagrangian (contract "The spatial crane").

    The suspension point s(t) = (x, y, 0) (cart and bridge) and the upper
    cable's length L1(t) are prescribed; the four swing coordinates are
    q = (theta1, theta2, phi1, phi2), the lower cable's angles relative to the
    upper's: p1 = s + L1 u(theta1, phi1), p2 = p1 + L2 u(theta1 + theta2,
    phi1 + phi2) (``cable_direction``). Lagrange's equations of the two point
    masses (``_lagrange_terms``, as in ``hoisting_swing``) read
    M q'' = Q - sum m_i J_i^T (rest_i + g e_z), with the joint damping of the
    dissipation function D = c1 (theta1'^2 + phi1'^2)/2 + c2 (theta2'^2 +
    phi2'^2)/2, Q = -dD/dq' (the planar damping in each direction). M is
    solved in blocks, theta and phi: A = M_thth, B = M_thph, C = M_phph, the
    Schur complement S = C - B^T A^-1 B; A and S are positive definite (M is,
    for positive masses and cables off the horizontal), so both 2x2
    inversions are safe. With phi1 = phi2 = 0 and y'' = 0 the phi rows vanish
    (every term carries sin phi or y'') and the theta rows are
    ``hoisting_swing``'s (and with L1 constant Eqs. 18-19), tested; crane_sim's
    Newton-projected derivation agrees (tested). Inputs theta1, theta2, phi1,
    phi2, their rates, ax (= x''), ay (= y''), L1, dL1, ddL1, L2, m1, m2, g,
    c1, c2; outputs ddtheta1, ddtheta2, ddphi1, ddphi2.
    """
    q, dq = ca.SX.sym('q', 4), ca.SX.sym('dq', 4)
    r, dr, ddr = ca.SX.sym('r', 3), ca.SX.sym('dr', 3), ca.SX.sym('ddr', 3)
    L2, m1, m2, g, c1, c2 = (ca.SX.sym(n) for n in ('L2', 'm1', 'm2', 'g', 'c1', 'c2'))
    th1, th2, ph1, ph2 = ca.vertsplit(q)
    x, y, L1 = ca.vertsplit(r)
    p1, p2 = masses_at(x, y, L1, L2, th1, th2, ph1, ph2)
    M, bias = _lagrange_terms(((m1, p1), (m2, p2)), q, dq, r, dr, ddr, ca.vertcat(0, 0, g))
    rhs = ca.vertcat(-c1 * dq[0], -c2 * dq[1], -c1 * dq[2], -c2 * dq[3]) - bias
    A, B, C = M[:2, :2], M[:2, 2:], M[2:, 2:]
    Ainv = _inverse2(A)
    ddphi = _inverse2(C - B.T @ Ainv @ B) @ (rhs[2:] - B.T @ Ainv @ rhs[:2])
    ddtheta = Ainv @ (rhs[:2] - B @ ddphi)
    # the suspension point's velocity cancels (a uniformly moving frame is Galilean) but not symbolically
    dd = ca.cse(ca.substitute(ca.vertcat(ddtheta, ddphi), dr[:2], ca.DM.zeros(2)))
    names = ['theta1', 'theta2', 'phi1', 'phi2', 'dtheta1', 'dtheta2', 'dphi1', 'dphi2', 'ax', 'ay', 'L1', 'dL1',
             'ddL1', 'L2', 'm1', 'm2', 'g', 'c1', 'c2']
    return ca.Function('spatial_swing', [*ca.vertsplit(q), *ca.vertsplit(dq), ddr[0], ddr[1], L1, dr[2], ddr[2],
                                         L2, m1, m2, g, c1, c2],
                       ca.vertsplit(dd), names, ['ddtheta1', 'ddtheta2', 'ddphi1', 'ddphi2'])

@dataclass(frozen=True)
class CraneOde:
    """x' = f(x, u, p) as CasADi SX expressions.

    Attributes:
        states: names of the entries of ``x``; a sensitivity state of state
            ``s`` to parameter ``q`` is named ``'d<s>/d<q>'``.
        x, u, p: symbols (p ordered as ``PARAMETERS``).
        f: the right-hand side.
        servo: True for the tau > 0 form (Eq. 6 included).
        robust: parameters whose sensitivities are in the state.
        hoist, hoist_servo: the hoist is an axis (``crane_ode``), with its servo.
        bridge: the bridge is an axis: the spatial crane, swing ``SPATIAL_SWING_STATES``.
    """

    states: tuple
    x: ca.SX
    u: ca.SX
    p: ca.SX
    f: ca.SX
    servo: bool
    robust: tuple = ()
    hoist: bool = False
    hoist_servo: bool = False
    bridge: bool = False

    @property
    def swing_states(self) -> tuple:
        """The swing's states: the planar crane's, or with a bridge the spatial crane's."""
        return SPATIAL_SWING_STATES if self.bridge else SWING_STATES

    def index(self, name: str) -> int:
        return self.states.index(name)

    def function(self) -> ca.Function:
        return ca.Function('f', [self.x, self.u, self.p], [self.f], ['x', 'u', 'p'], ['xdot'])


def crane_ode(servo: bool, hoist: bool = False, hoist_servo: bool = False, bridge: bool = False) -> CraneOde:
    """The crane of Eqs. 18-19 driven by the cart acceleration, in the form of Eqs. 7-8.

    With ``servo`` the cart acceleration obeys Eq. 6, tau a' = a_ref - a, and
    the input is the reference jerk; otherwise the input is the cart jerk.

    With ``hoist`` the upper cable's length is a second actuated axis: L1 + h
    with h the hoist's displacement from the start length (the parameter
    ``L1``, so a sensitivity to L1 is one to an offset of the rope length),
    the swing from ``hoisting_swing`` (the Lagrangian with L1(t)), and a
    second input, the hoist's jerk, or with ``hoist_servo`` its reference
    jerk, the hoist's acceleration following Eq. 6 with tau_hoist.

    With ``bridge`` the suspension point also travels along y, driven like
    the cart (the same servo, tau): the spatial crane, its swing
    ``SPATIAL_SWING_STATES`` from ``spatial_swing`` (with or without the hoist).

    States: the cart's, then ``BRIDGE_STATES`` (with a bridge), then
    ``HOIST_STATES`` (with a hoist; ``a_ref``, ``ab_ref`` only with ``servo``,
    ``ha_ref`` only with ``hoist_servo``), then the swing. Inputs: one per axis
    in the same order (``crane_msgs_py.crane.axes.AXES``).
    """
    cart_names = CART_STATES if servo else CART_STATES[:3]
    bridge_names = (BRIDGE_STATES if servo else BRIDGE_STATES[:3]) if bridge else ()
    hoist_names = (HOIST_STATES if hoist_servo else HOIST_STATES[:3]) if hoist else ()
    swing = SPATIAL_SWING_STATES if bridge else SWING_STATES
    names = cart_names + bridge_names + hoist_names + swing
    x = ca.SX.sym('x', len(names))
    u = ca.SX.sym('u', 1 + bridge + hoist)
    p = ca.SX.sym('p', len(PARAMETERS))
    s = dict(zip(names, ca.vertsplit(x)))
    par = dict(zip(PARAMETERS, ca.vertsplit(p)))
    L1, L2, m1, m2, g, c1, c2 = (par[k] for k in ('L1', 'L2', 'm1', 'm2', 'g', 'c1', 'c2'))
    if bridge:
        rope = (L1 + s['h'], s['hv'], s['ha']) if hoist else (L1, 0.0, 0.0)
        dd = spatial_swing()(*(s[n] for n in SPATIAL_SWING_STATES), s['a'], s['ab'], *rope, L2, m1, m2, g, c1, c2)
    elif hoist:
        dd = hoisting_swing()(s['theta1'], s['theta2'], s['dtheta1'], s['dtheta2'], s['a'], L1 + s['h'],
                              s['hv'], s['ha'], L2, m1, m2, g, c1, c2)
    else:
        dd = swing_accelerations(s['theta1'], s['theta2'], s['dtheta1'], s['dtheta2'], s['a'],
                                 L1, L2, m1, m2, g, c1, c2)
    axes = [(CART_STATES, servo, par['tau'])]
    if bridge:
        axes.append((BRIDGE_STATES, servo, par['tau']))
    if hoist:
        axes.append((HOIST_STATES, hoist_servo, par['tau_hoist']))
    rows = []
    for k, ((y, v, a, a_ref), has_servo, tau) in enumerate(axes):
        # Eq. 6 with the servo: tau a' = a_ref - a, the input the reference's jerk; else the axis's jerk
        rows += [s[v], s[a], (s[a_ref] - s[a]) / tau, u[k]] if has_servo else [s[v], s[a], u[k]]
    rates = [s[n] for n in swing_rates(bridge)]
    f = ca.vertcat(*rows, *rates, *dd)
    return CraneOde(names, x, u, p, f, servo, hoist=hoist, hoist_servo=hoist_servo, bridge=bridge)


def _closure(seed: set, edges: dict) -> set:
    out, todo = set(seed), list(seed)
    while todo:
        for j in edges[todo.pop()]:
            if j not in out:
                out.add(j)
                todo.append(j)
    return out


def sensitivity_states(ode: CraneOde, parameter: str) -> tuple:
    """States whose sensitivity to ``parameter`` the robust problem must carry.

    These are the states that depend on the parameter (directly or through
    other states) and that the swing depends on: the cart position and
    velocity never feed back, and their sensitivities at T follow from that
    of the acceleration (y + tau v and v + tau a are fixed by the reference),
    so adding them would only duplicate boundary conditions. For L1, L2, m1,
    m2 this gives the four swing states of Eq. 26.

    For tau (servo form) only the cart acceleration is carried. Its
    sensitivity obeys S_a + tau S_a' = -a' and drives the swing
    sensitivities through the linearized pendulum; for each mode
    eigenvalue lambda, integrating against exp(-lambda t) with a(0) = a(T)
    = 0 and the nominal rest-to-rest condition int a exp(-lambda t) dt = 0
    gives (1 + tau lambda) int S_a exp(-lambda t) dt = -tau S_a(T) exp(-lambda T).
    So the swing sensitivities vanish at T exactly when S_a(T) does (about
    rest): their end conditions would repeat S_a(T) = 0 four times and make
    the problem degenerate. That argument needs constant modes: with a hoist
    the swing's sensitivities to tau are carried as well.
    """
    k = PARAMETERS.index(parameter)
    n = len(ode.states)
    jx = ca.jacobian(ode.f, ode.x)
    jp = ca.jacobian(ode.f, ode.p[k])
    uses = {i: [j for j in range(n) if not jx[i, j].is_zero()] for i in range(n)}
    used_by = {j: [i for i in range(n) if j in uses[i]] for j in range(n)}
    direct = {i for i in range(n) if not jp[i].is_zero()}
    dependent = _closure(direct, used_by)
    swing = {ode.index(name) for name in ode.swing_states}
    relevant = _closure(swing, uses)
    if parameter == 'tau' and not ode.hoist:
        relevant -= swing
    return tuple(ode.states[i] for i in range(n) if i in dependent and i in relevant)


#: Parameters that act on the swing only through its two modal frequencies and shapes.
PENDULUM_PARAMETERS = ('L1', 'L2', 'm1', 'm2')


def carried_parameters(robust, hoist: bool = False) -> tuple:
    """The parameters whose sensitivities make a plan insensitive to all of ``robust``.

    About rest, the crane's swing is two modes; a rest-to-rest motion leaves
    mode i at rest iff c_i = int_0^T a(t) exp(-lambda_i t) dt = 0, and the
    sensitivity of the end state to a parameter mu is
    sum_i phi_i b_i (d lambda_i / d mu) int_0^T t a(t) exp(-lambda_i t) dt
    (the terms with d phi_i/d mu and d b_i/d mu multiply c_i = 0). L1, L2 and
    m2/(m1+m2) (the only way the masses enter Eqs. 18-19) all move both
    frequencies, so the insensitivity conditions int t a exp(-lambda_i t) = 0
    are the same for each of them: the first of them in ``robust`` stands for
    all (to first order in the swing amplitude); carrying more would repeat
    the same four end conditions and make the NLP degenerate. tau is
    independent of them (see ``sensitivity_states``). With a ``hoist`` the
    modes change along the motion and that argument fails: every parameter
    of ``robust`` is carried.
    """
    robust = tuple(robust)
    if hoist:
        return robust
    pendulum = [q for q in robust if q in PENDULUM_PARAMETERS][:1]
    return tuple(q for q in robust if q in pendulum or q not in PENDULUM_PARAMETERS)


def augment(ode: CraneOde, robust) -> CraneOde:
    """The crane augmented with the sensitivity functions of Eqs. 13-14.

    For each parameter mu in ``robust`` the sensitivity S = dx/dmu of the
    states listed by ``sensitivity_states`` obeys S' = f_x S + f_mu (Eq. 14),
    with the sensitivities of the other states zero or not needed. Only the
    sensitivities of ``carried_parameters(robust)`` are added (the others
    follow from them).
    """
    robust = carried_parameters(robust, ode.hoist)
    if 'tau' in robust and not ode.servo:
        raise ValueError('sensitivity to tau needs the servo model (tau > 0)')
    blocks, names, sdot = [], list(ode.states), []
    for q in robust:
        sel = [ode.index(s) for s in sensitivity_states(ode, q)]
        S = ca.SX.sym('S_' + q, len(sel))
        full = ca.SX(len(ode.states), 1)
        for r, i in enumerate(sel):
            full[i] = S[r]
        dS = ca.jtimes(ode.f, ode.x, full) + ca.jacobian(ode.f, ode.p[PARAMETERS.index(q)])
        blocks.append(S)
        sdot.append(dS[sel])
        names += [f'd{ode.states[i]}/d{q}' for i in sel]
    x = ca.vertcat(ode.x, *blocks)
    f = ca.vertcat(ode.f, *sdot)
    return CraneOde(tuple(names), x, ode.u, ode.p, f, ode.servo, robust, ode.hoist, ode.hoist_servo, ode.bridge)
