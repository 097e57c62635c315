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

from dataclasses import dataclass

import casadi as ca

from crane_msgs_py.params import PARAMETER_NAMES

#: Order of the model parameter vector ``p`` of every model here (CraneParams' fields).
PARAMETERS = PARAMETER_NAMES
SWING_STATES = ('theta1', 'theta2', 'dtheta1', 'dtheta2')
IDEAL_STATES = ('y', 'v', 'a') + SWING_STATES
SERVO_STATES = ('y', 'v', 'a', 'a_ref') + SWING_STATES


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
    """

    states: tuple
    x: ca.SX
    u: ca.SX
    p: ca.SX
    f: ca.SX
    servo: bool
    robust: tuple = ()

    def index(self, name: str) -> int:
        return self.states.index(name)

    def function(self) -> ca.Function:
        return ca.Function('f', [self.x, self.u, self.p], [self.f], ['x', 'u', 'p'], ['xdot'])


def crane_ode(servo: bool) -> CraneOde:
    """The crane of Eqs. 18-19 driven by the cart acceleration, in the form of Eqs. 7-8.

    With ``servo`` the cart acceleration obeys Eq. 6, tau a' = a_ref - a, and
    the input is the reference jerk; otherwise the input is the cart jerk.
    """
    names = SERVO_STATES if servo else IDEAL_STATES
    x = ca.SX.sym('x', len(names))
    u = ca.SX.sym('u')
    p = ca.SX.sym('p', len(PARAMETERS))
    s = dict(zip(names, ca.vertsplit(x)))
    L1, L2, m1, m2, g, tau, c1, c2 = ca.vertsplit(p)
    dd1, dd2 = swing_accelerations(s['theta1'], s['theta2'], s['dtheta1'], s['dtheta2'], s['a'],
                                   L1, L2, m1, m2, g, c1, c2)
    if servo:
        cart = [s['v'], s['a'], (s['a_ref'] - s['a']) / tau, u]
    else:
        cart = [s['v'], s['a'], u]
    f = ca.vertcat(*cart, s['dtheta1'], s['dtheta2'], dd1, dd2)
    return CraneOde(names, x, u, p, f, servo)


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
    the problem degenerate.
    """
    k = PARAMETERS.index(parameter)
    n = len(ode.states)
    jx = ca.jacobian(ode.f, ode.x)
    jp = ca.jacobian(ode.f, ode.p[k])
    uses = {i: [j for j in range(n) if not jx[i, j].is_zero()] for i in range(n)}
    used_by = {j: [i for i in range(n) if j in uses[i]] for j in range(n)}
    direct = {i for i in range(n) if not jp[i].is_zero()}
    dependent = _closure(direct, used_by)
    swing = {ode.index(name) for name in SWING_STATES}
    relevant = _closure(swing, uses)
    if parameter == 'tau':
        relevant -= swing
    return tuple(ode.states[i] for i in range(n) if i in dependent and i in relevant)


#: Parameters that act on the swing only through its two modal frequencies and shapes.
PENDULUM_PARAMETERS = ('L1', 'L2', 'm1', 'm2')


def carried_parameters(robust) -> tuple:
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
    independent of them (see ``sensitivity_states``).
    """
    robust = tuple(robust)
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
    robust = carried_parameters(robust)
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
    return CraneOde(tuple(names), x, ode.u, ode.p, f, ode.servo, robust)
