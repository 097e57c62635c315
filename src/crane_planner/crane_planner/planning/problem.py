"""The paper's variational planners NVF and RVF (Eqs. 10 and 15): the optimal control problem.

``Problem`` states the optimal control problem once, in scaled variables on
normalized time s = t / T, for both solution routes: the direct one
(``crane_planner.planning.direct``: Radau collocation + IPOPT) and the paper's
indirect one (``crane_planner.planning.indirect``: Pontryagin's TPBVP). The
mesh both start from lives here too, so the routes share it (the axis
limits' necessary conditions are in ``limits``); neither route imports the other.

Scaling: with P = max(|D|, P_MIN) the states are divided by their natural
sizes (position P, velocity P/T, acceleration P/T^2, swing angle P/(g T^2),
...), so every NLP variable is of order one for every T and D the planner
serves; sensitivities to a parameter q are further divided by q (by T for
tau).
"""
from __future__ import annotations

import functools
import math
from collections.abc import Mapping
from dataclasses import dataclass

import casadi as ca
import numpy as np
from numpy.polynomial import polynomial as poly
from scipy.optimize import brentq

from crane_msgs_py.crane.axes import AXIS_NAMES
from crane_msgs_py.crane.params import CraneParams

from .dynamics import BRIDGE_STATES, CART_STATES, HOIST_STATES, PARAMETERS, augment, crane_ode, mass_positions
from .profiles import QUINTIC

#: Smallest position scale (m): a request for D = 0 is still well scaled.
P_MIN = 1e-3

#: Entries of the NLP parameter vector of ``Problem`` (the mesh fractions follow in a transcription).
PROBLEM_PARAMETERS = ('T', 'P', *PARAMETERS, 'acceleration_weight', 'sensitivity_weight',
                      'reference_jerk_weight', 'P_hoist', 'hoist_weight', 'P_bridge', 'bridge_weight')


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
    #: w_h: the hoist's jerk (and reference jerk) counts w_h times the cart's in the cost,
    #: w_h jerk_h^2/2: 1 weighs a metre of hoisting like a metre of travel.
    hoist: float = 1.0
    #: w_b: the same for the bridge's jerk (and reference jerk): 1 weighs it like the cart's.
    bridge: float = 1.0


def _state_scale(name: str, T, P, g, params: dict):
    """Natural size of a state (see the module docstring)."""
    if '/' in name:  # 'd<state>/d<q>'
        state, q = name[1:].split('/d')
        return _state_scale(state, T, P, g, params) / (T if q == 'tau' else params[q])
    H, B = params.get('P_hoist', P), params.get('P_bridge', P)
    # the swing in the x-z plane (theta) is driven by the cart, out of it (phi) by the bridge
    return {'y': P, 'v': P / T, 'a': P / T ** 2, 'a_ref': P / T ** 2,
            'yb': B, 'vb': B / T, 'ab': B / T ** 2, 'ab_ref': B / T ** 2,
            'h': H, 'hv': H / T, 'ha': H / T ** 2, 'ha_ref': H / T ** 2,
            'theta1': P / (g * T ** 2), 'theta2': P / (g * T ** 2),
            'dtheta1': P / (g * T ** 3), 'dtheta2': P / (g * T ** 3),
            'phi1': B / (g * T ** 2), 'phi2': B / (g * T ** 2),
            'dphi1': B / (g * T ** 3), 'dphi2': B / (g * T ** 3)}[name]


def axis_displacements(displacement) -> dict[str, float]:
    """{axis name: D} of a request's ``displacement``, in ``crane_msgs_py.crane.axes.AXES`` order.

    ``displacement`` is a number (the cart alone), a pair (the cart's and the
    hoist's, the form before the bridge), or a mapping by axis name (any of
    the axes; the cart's is 0 if not given).
    """
    if isinstance(displacement, Mapping):
        unknown = [name for name in displacement if name not in AXIS_NAMES]
        if unknown:
            raise ValueError(f'no axis {unknown[0]!r}; the axes are {", ".join(AXIS_NAMES)}')
        given = dict(displacement, cart=displacement.get('cart', 0.0))
        return {name: float(given[name]) for name in AXIS_NAMES if name in given}
    d = np.atleast_1d(np.asarray(displacement, dtype=float))
    return {'cart': float(d[0]), **({'hoist': float(d[1])} if d.size > 1 else {})}


def displacements(displacement) -> tuple[float, float | None]:
    """(cart D, hoist D or None) of a request's ``displacement`` (``axis_displacements``)."""
    d = axis_displacements(displacement)
    return d['cart'], d.get('hoist')


@dataclass(frozen=True)
class Form:
    """Which model a problem is built on: the cart's (and bridge's) servo (tau > 0), a hoist axis, the hoist's
    servo, a bridge axis (the spatial crane)."""

    servo: bool
    hoist: bool = False
    hoist_servo: bool = False
    bridge: bool = False

    @classmethod
    def of(cls, params: CraneParams, hoist: bool, bridge: bool = False) -> 'Form':
        return cls(params.tau > 0.0, hoist, hoist and params.tau_hoist > 0.0, bridge)

    @classmethod
    def of_request(cls, params: CraneParams, displacement) -> 'Form':
        """The form of a request's ``displacement`` (``axis_displacements``): its axes beside the cart."""
        axes = axis_displacements(displacement)
        return cls.of(params, 'hoist' in axes, 'bridge' in axes)

    @property
    def axes(self) -> tuple:
        """The axes planned, in ``crane_msgs_py.crane.axes.AXES`` order."""
        return ('cart',) + (('bridge',) if self.bridge else ()) + (('hoist',) if self.hoist else ())

    @classmethod
    def coerce(cls, form) -> 'Form':
        """``form`` itself, or for a bool ``servo`` the form of the crane without a hoist."""
        return form if isinstance(form, cls) else cls(bool(form))


#: Each axis's states (``dynamics``), by axis name.
AXIS_STATES = {'cart': CART_STATES, 'bridge': BRIDGE_STATES, 'hoist': HOIST_STATES}
#: Each axis's position scale among ``PROBLEM_PARAMETERS``.
AXIS_SCALES = {'cart': 'P', 'bridge': 'P_bridge', 'hoist': 'P_hoist'}


class Problem:
    """NVF (Eq. 10) or RVF (Eq. 15) for the crane, in scaled variables on s = t / T.

    min  int_0^T g dt,  g = u_j^2/2 + w_a a^2/2 + w_s |S|^2/2 + w_r u^2/2
    s.t. x' = f^r(x, u)  (Eqs. 6-8, 18-19, 14),  x(0) = 0,  x(T) = [D, 0, ...]

    with u_j the cart jerk (the input u itself when tau = 0, (a_ref - a)/tau
    with the servo, where u is the reference jerk). With a hoist (``form``)
    its jerk and reference jerk enter the same way, weighted by w_h
    (``Weights.hoist``), and it also goes from rest to rest: x(T) has its
    displacement D_h. With a bridge likewise (w_b, ``Weights.bridge``, its
    acceleration under w_a like the cart's), on the spatial crane.

    Attributes:
        ode: the (augmented) crane model.
        states: state names; ``nx`` of them, ``nu`` inputs (one per axis).
        axes: the axes planned (``Form.axes``): ``('cart',)``, ``('cart', 'hoist')``, ``('cart', 'bridge')``,
            ``('cart', 'bridge', 'hoist')``.
        P: symbolic parameter vector, entries ``PROBLEM_PARAMETERS``.
        F: dX/ds = F(X, U, P) in scaled variables.
        G: the cost integrand in scaled units; J = T (P/T^3)^2 int_0^1 G ds.
    """

    def __init__(self, robust: tuple, form: Form):
        ode = crane_ode(form.servo, form.hoist, form.hoist_servo, form.bridge)
        self.ode = augment(ode, robust) if robust else ode
        self.form, self.servo = form, form.servo
        self.axes = form.axes
        self.robust = self.ode.robust
        self.states = self.ode.states
        self.nx, self.nu = len(self.states), len(self.axes)
        X = ca.SX.sym('X', self.nx)
        U = ca.SX.sym('U', self.nu)
        P = ca.SX.sym('P', len(PROBLEM_PARAMETERS))
        par = dict(zip(PROBLEM_PARAMETERS, ca.vertsplit(P)))
        T, Ps, g = par['T'], par['P'], par['g']
        sx = ca.vertcat(*[_state_scale(s, T, Ps, g, par) for s in self.states])
        su = ca.vertcat(*[par[AXIS_SCALES[axis]] for axis in self.axes]) / T ** 3
        x, u = sx * X, su * U
        p = ca.vertcat(*[par[q] for q in PARAMETERS])
        f = ca.substitute(ca.substitute(self.ode.f, self.ode.x, x), ca.vertcat(self.ode.u, self.ode.p),
                          ca.vertcat(u, p))
        s = dict(zip(self.states, ca.vertsplit(x)))
        jerk = (s['a_ref'] - s['a']) / par['tau'] if form.servo else u[0]
        sens = ca.vertcat(*[s[n] for n in self.states if '/' in n])
        gcost = (jerk ** 2 + par['acceleration_weight'] * s['a'] ** 2
                 + par['sensitivity_weight'] * ca.sumsqr(sens)) / 2
        if form.servo:
            gcost += par['reference_jerk_weight'] * u[0] ** 2 / 2
        if form.bridge:
            k = self.axes.index('bridge')
            bridge_jerk = (s['ab_ref'] - s['ab']) / par['tau'] if form.servo else u[k]
            gcost += par['bridge_weight'] * (bridge_jerk ** 2 + par['acceleration_weight'] * s['ab'] ** 2) / 2
            if form.servo:
                gcost += par['bridge_weight'] * par['reference_jerk_weight'] * u[k] ** 2 / 2
        if form.hoist:
            k = self.axes.index('hoist')
            hoist_jerk = (s['ha_ref'] - s['ha']) / par['tau_hoist'] if form.hoist_servo else u[k]
            gcost += par['hoist_weight'] * hoist_jerk ** 2 / 2
            if form.hoist_servo:
                gcost += par['hoist_weight'] * par['reference_jerk_weight'] * u[k] ** 2 / 2
        self.X, self.U, self.P = X, U, P
        self.F = ca.Function('F', [X, U, P], [T * f / sx])
        self.G = ca.Function('G', [X, U, P], [gcost / su[0] ** 2])
        self.scales = ca.Function('scales', [P], [sx, su])
        # reference velocity and acceleration of each axis (for the axis limits), scaled by P/T and P/T^2
        ref_p, ref_v, ref_a = [], [], []
        for axis in self.axes:
            scale = par[AXIS_SCALES[axis]]
            y, v, a = self.reference(s, par['tau'], axis, par['tau_hoist'])
            ref_p.append(y / scale)
            ref_v.append(v / (scale / T))
            ref_a.append(a / (scale / T ** 2))
        self.reference_va = ca.Function('reference_va', [X, P], [ca.vertcat(*ref_v), ca.vertcat(*ref_a)])
        # each axis's reference position (relative to its start; scaled by its position scale): via points
        self.reference_position = ca.Function('reference_position', [X, P], [ca.vertcat(*ref_p)])
        # both masses in crane_base (m) from the scaled states, the travel axes' start positions given
        origin = ca.SX.sym('origin', 2)
        zero = ca.SX(0)
        p1, p2 = mass_positions()(s['y'] + origin[0], (s['yb'] if form.bridge else zero) + origin[1],
                                  par['L1'] + (s['h'] if form.hoist else zero), par['L2'], s['theta1'], s['theta2'],
                                  s.get('phi1', zero), s.get('phi2', zero))
        self.masses = ca.Function('masses', [X, P, origin], [p1, p2], ['X', 'P', 'origin'], ['p1', 'p2'])

    #: The swing angles each travel axis drives (their rates and sensitivities follow their names).
    DRIVEN_SWING = {'cart': ('theta1', 'theta2'), 'bridge': ('phi1', 'phi2')}

    def mirrored(self, state: str, axes) -> bool:
        """Whether the state ``state`` changes sign when the travel axes ``axes`` are mirrored
        (``Transcription.mirror``): an axis's own states and the swing angles it drives (theta the cart's, phi
        the bridge's), with their rates and sensitivities; the hoist's never (it has no mirror)."""
        base = state[1:].split('/d')[0] if '/' in state else state  # 'd<s>/d<q>': that of s
        for axis in axes:
            angles = self.DRIVEN_SWING[axis]
            if base in AXIS_STATES[axis] or base in angles or base in tuple('d' + a for a in angles):
                return True
        return False

    def parameters(self, displacement, duration: float, params: CraneParams, weights: Weights,
                   start: dict | None = None) -> np.ndarray:
        """The NLP parameter vector (``PROBLEM_PARAMETERS``) of a request.

        The position scales P, P_bridge and P_hoist are the displacements, and
        with a ``start`` (SI state values by name, see ``boundary``) also what
        the start's velocity, acceleration and swing would carry the axis in T
        (the cart's the swing in the x-z plane, the bridge's the swing out of
        it), so a stop (D ~ 0) or a settle (D = 0, the swing alone) is well
        scaled too.
        """
        D = self.displacements_of(displacement)
        scale = {axis: max(abs(D.get(axis, 0.0)), P_MIN) for axis in AXIS_SCALES}
        if start:
            T, g = duration, params.g
            x = {k: abs(v) for k, v in start.items()}
            swing = {'cart': ('theta', 'dtheta'), 'bridge': ('phi', 'dphi'), 'hoist': ()}
            for axis, (y, v, a, a_ref) in AXIS_STATES.items():
                angles = [g * T ** (2 + k) * x.get(f'{n}{i}', 0.0) for k, n in enumerate(swing[axis]) for i in (1, 2)]
                scale[axis] = max(scale[axis], x.get(y, 0.0), x.get(v, 0.0) * T, x.get(a, 0.0) * T ** 2,
                                  x.get(a_ref, 0.0) * T ** 2, *angles)
        values = dict(params.as_dict(), T=duration, P=scale['cart'],
                      acceleration_weight=weights.acceleration, sensitivity_weight=weights.sensitivity,
                      reference_jerk_weight=weights.reference_jerk, P_hoist=scale['hoist'],
                      hoist_weight=weights.hoist, P_bridge=scale['bridge'], bridge_weight=weights.bridge)
        return np.array([values[k] for k in PROBLEM_PARAMETERS], dtype=float)

    def displacements_of(self, displacement) -> dict[str, float]:
        """{axis: D} of every axis of this problem (``axis_displacements``; an axis not given: 0)."""
        given = axis_displacements(displacement)
        return {axis: given.get(axis, 0.0) for axis in self.axes}

    def reference(self, x: dict, tau: float, axis: str = 'cart', tau_hoist: float = 0.0) -> tuple:
        """Reference position, velocity, acceleration of ``axis`` from states in SI units (``x`` by name).

        With the servo, tau a' + a = a_ref from rest gives y_ref = y + tau v and
        v_ref = v + tau a exactly; with tau = 0 the axis is the reference. The
        hoist's position is its displacement from the start length.
        """
        y, v, a, a_ref = AXIS_STATES[axis]
        servo, tc = (self.form.hoist_servo, tau_hoist) if axis == 'hoist' else (self.form.servo, tau)
        if servo:
            return x[y] + tc * x[v], x[v] + tc * x[a], x[a_ref]
        return x[y], x[v], x[a]

    def boundary(self, displacement, sx: np.ndarray, start: dict | None = None,
                 free_end: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """Scaled states at s = 0 and s = 1 (``sx``: the state scales of ``scales``).

        At s = 0 rest, or ``start``: SI values of states by name (the others
        0; sensitivities are always 0 there, the start being known), positions
        relative to where the plan's reference starts (``continuation``). At
        s = 1 rest at D (and the hoist at D_h); with ``free_end`` the axes'
        positions are free (NaN): a stop.
        """
        x0 = np.zeros(self.nx)
        for name, value in (start or {}).items():
            if name in self.states and '/' not in name:
                x0[self.states.index(name)] = value / sx[self.states.index(name)]
        xT = np.zeros(self.nx)
        for axis, value in self.displacements_of(displacement).items():
            i = self.states.index(AXIS_STATES[axis][0])
            xT[i] = np.nan if free_end else value / sx[i]
        return x0, xT

    def initial_guess(self, displacement, s: np.ndarray, x0: np.ndarray | None = None,
                      xT: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Scaled states (nx, len(s)) and inputs (nu, len(s)) of a quintic with quasi-static swing.

        From rest to rest the quintic of D; from a scaled start ``x0`` to the
        end ``xT`` (``boundary``) the quintic that starts with x0's position,
        velocity and acceleration and ends at rest at xT's position (a free one:
        where the start's velocity carries it in half the time), the start's
        swing fading out linearly. In scaled units a state's s-derivative is
        the next state, and theta1 ~ a/g, dtheta1 ~ jerk/g are A and U.
        """
        guess, U = {}, []
        for axis, d in self.displacements_of(displacement).items():
            y, v, a, a_ref = AXIS_STATES[axis]
            k = d / max(abs(d), P_MIN)
            if x0 is None:
                q = [k * poly.polyval(s, QUINTIC[i]) for i in range(4)]
            else:
                p0, v0, a0 = (x0[self.states.index(n)] for n in (y, v, a))
                end = xT[self.states.index(y)]
                p1 = p0 + v0 / 2 if np.isnan(end) else end
                c = _hermite5(p0, v0, a0, p1)
                q = [poly.polyval(s, poly.polyder(c, i)) for i in range(4)]
            guess.update({y: q[0], v: q[1], a: q[2], a_ref: q[2]})
            U.append(q[3])
        guess.update(theta1=guess['a'], dtheta1=U[0])
        if self.form.bridge:  # phi is positive towards +y: the load lags a bridge acceleration at phi1 ~ -ab/g
            guess.update(phi1=-guess['ab'], dphi1=-U[self.axes.index('bridge')])
        if x0 is not None:
            for n in self.ode.swing_states:
                guess[n] = guess.get(n, 0.0 * s) + x0[self.states.index(n)] * (1.0 - s)
        X = np.array([guess.get(n, 0.0 * s) for n in self.states])
        return X, np.array(U)


def _hermite5(p0: float, v0: float, a0: float, p1: float) -> np.ndarray:
    """Coefficients (powers of s) of the quintic on [0, 1] from (p0, v0, a0) to rest at p1."""
    rhs = [p1 - p0 - v0 - a0 / 2, -v0 - a0, -a0]  # p, p', p'' at s = 1 less what the first three terms give
    c345 = np.linalg.solve([[1.0, 1.0, 1.0], [3.0, 4.0, 5.0], [6.0, 12.0, 20.0]], rhs)
    return np.concatenate([[p0, v0, a0 / 2], c345])


def uniform_mesh(intervals: int) -> np.ndarray:
    return np.full(intervals, 1.0 / intervals)


@functools.lru_cache(maxsize=256)
def graded_mesh(intervals: int, layer: float, max_ratio: float = 2.0) -> np.ndarray:
    """Interval fractions that resolve boundary layers of relative width ``layer`` at both ends.

    m intervals at each end grow geometrically by r from ``layer`` to the
    uniform width of the interior; m is the smallest with r <= ``max_ratio``,
    but at most a fifth of the intervals, so a very thin layer costs a larger
    ratio, not the interior's resolution. Cached (a repeated duration costs
    nothing); the array is read-only.
    """
    if layer * intervals >= 1.0:
        return uniform_mesh(intervals)

    def grading(m):
        # the ratio r at which the geometric ends r^i layer (i < m) meet the uniform
        # interior width, r^m layer: the root of a function increasing in r
        def excess(r):
            ends = layer * m if r == 1.0 else layer * (r ** m - 1.0) / (r - 1.0)
            return layer * r ** m - (1.0 - 2.0 * ends) / (intervals - 2 * m)

        r = brentq(excess, 1.0, 1e6, xtol=1e-14, rtol=4 * np.finfo(float).eps)
        ends = layer * m if r == 1.0 else layer * (r ** m - 1.0) / (r - 1.0)
        return r, (1.0 - 2.0 * ends) / (intervals - 2 * m)

    for m in range(1, max(intervals // 5, 1) + 1):
        r, inner = grading(m)
        if r <= max_ratio:
            break
    ends = list(layer * r ** np.arange(m))
    frac = np.array(ends + [inner] * (intervals - 2 * m) + ends[::-1])
    frac.flags.writeable = False
    return frac


def servo_layer(tau: float, weights: Weights) -> float:
    """Width (s) of the boundary layers of the servo model's optimum.

    The cart jerk j must start and end at zero (a = a_ref = 0 there), and
    the Euler-Lagrange equation of j^2 + w_r (j + tau j')^2, i.e.
    (1 + w_r) j = w_r tau^2 j'', gives them the width
    l = tau sqrt(w_r / (1 + w_r)).
    """
    w = weights.reference_jerk
    return tau * math.sqrt(w / (1.0 + w))


def breakpoints(frac: np.ndarray) -> np.ndarray:
    """Normalized mesh points [0, ..., 1] of interval fractions (the last exactly 1)."""
    s = np.concatenate([[0.0], np.cumsum(frac)])
    s[-1] = 1.0
    return s
