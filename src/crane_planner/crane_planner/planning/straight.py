"""A straight move of the spatial crane planned on its own vertical plane: the coupled model's optimum at the
planar crane's cost.

The spatial crane (contract "The spatial crane") is symmetric about the vertical: its Lagrangian does not
change when the whole crane is turned about z, and neither do the variational cost (the jerks, accelerations
and sensitivities of both travel axes weighed alike, ``problem.Weights.bridge`` = 1) nor the parameters RVF
is made robust to. So a rest-to-rest move of the suspension point along a straight line at angle alpha is
one of the planar crane's (Eqs. 18-19) in the vertical plane through that line: the load swings in that
plane only, by the planar angles psi1, psi2, and the optimum of the coupled problem is the planar optimum
of the line's length, its reference shared by the cart (cos alpha) and the bridge (sin alpha). The planar
NLP has half the states and solves in a fraction of the time (``bench/spatial.py`` times both).

A motion from a state (a stop, a retarget) keeps the symmetry when the state lies in one vertical plane:
every travel state of the cart and the bridge (the servo's lag, velocity, acceleration and its reference's)
and the goal along one line, and both cables swinging in the vertical plane through it (``planar_start``;
a motion of one axis alone is the common case: the runway guard's stop of a bridge travel). The motion
then stays in that plane, and the planar optimum from the planar state is the coupled one.

Where the symmetry breaks, the coupled problem is solved as it is (``applies``): joint damping (its
dissipation function, ``dynamics.spatial_swing``, is written in theta and phi, not in the cable's angular
velocity, so it is isotropic only for small swing), axis limits (a box in (x, y), not a disc), a start
out of one vertical plane, keep-out boxes and via points. The hoist is along z and keeps the symmetry.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from crane_msgs_py.crane.params import CraneParams
from crane_msgs_py.messages.names import BRIDGE_JOINT, CART_JOINT, HOIST_JOINT

from .collocation import CollocationPlan
from .dynamics import BRIDGE_STATES, CART_STATES, HOIST_STATES
from .mass_path import plan_axes
from .plan import AxesPlan, ModelPath, Plan


@dataclass(frozen=True)
class Line:
    """The straight path of a move of the travel axes: its ``length`` (m, >= 0) and direction (``cos``,
    ``sin``: the cart's and the bridge's share of it; (1, 0) for a move of length 0)."""

    length: float
    cos: float
    sin: float

    @classmethod
    def of(cls, cart: float, bridge: float) -> 'Line':
        length = math.hypot(cart, bridge)
        if length == 0.0:
            return cls(0.0, 1.0, 0.0)
        return cls(length, cart / length, bridge / length)


def applies(params: CraneParams, has_limits: bool, bridge_weight: float) -> bool:
    """Whether a rest-to-rest move of the travel axes may be planned on its plane (module docstring): no
    joint damping, no axis limits, the bridge weighed like the cart."""
    return params.c1 == 0.0 and params.c2 == 0.0 and not has_limits and bridge_weight == 1.0


def planar_displacement(moves: dict) -> tuple[Line, dict]:
    """(the line, the planar request: the line's length as the cart's, the hoist's as it is) of a move's
    displacements by axis name (``problem.axis_displacements``: the cart's, the bridge's, maybe the hoist's)."""
    line = Line.of(moves[CART_JOINT], moves[BRIDGE_JOINT])
    return line, {CART_JOINT: line.length, **({HOIST_JOINT: moves[HOIST_JOINT]} if HOIST_JOINT in moves else {})}


#: How far (rad, and m, m/s... for the travel states) a start may be off one vertical plane and still be planned on
#: it: rounding (a model integrated along a straight motion keeps its plane to ~1e-15).
IN_PLANE_TOLERANCE = 1e-9


def planar_start(moves: dict, start: dict) -> tuple[Line, dict, dict] | None:
    """(the line, the planar request, the planar start) of a motion from ``start`` (the spatial problem's
    start states, SI, by ``dynamics`` name: ``continuation.problem_start``) with displacements ``moves`` by
    axis name (a free end's: its scale), if the start lies in one vertical plane (module docstring); else None.

    The line is along the travel states' largest pair (cart, bridge), or the upper cable's lean; the planar
    travel states are their shares along it (the request's length >= 0), the planar swing the cables' angles
    in its plane (``spatial_angles`` inverted, then checked by mapping them back)."""
    pairs = [np.array([start.get(c, 0.0), start.get(b, 0.0)], dtype=float)
             for c, b in zip(CART_STATES, BRIDGE_STATES, strict=True)]
    pairs.append(np.array([moves.get(CART_JOINT, 0.0), moves.get(BRIDGE_JOINT, 0.0)], dtype=float))
    theta1, theta2 = start.get('theta1', 0.0), start.get('theta2', 0.0)
    phi1, phi2 = start.get('phi1', 0.0), start.get('phi2', 0.0)
    lean = np.array([-math.sin(theta1) * math.cos(phi1), math.sin(phi1)])  # (the upper cable's, horizontal)
    along = max(pairs, key=lambda p: float(np.hypot(*p)))
    if not np.hypot(*along) > IN_PLANE_TOLERANCE:
        along = lean if np.hypot(*lean) > IN_PLANE_TOLERANCE else np.array([1.0, 0.0])
    u = along / np.hypot(*along)
    if pairs[-1] @ u < 0.0:  # (the request's length is >= 0)
        u = -u
    if any(abs(p[0] * u[1] - p[1] * u[0]) > IN_PLANE_TOLERANCE for p in pairs):
        return None
    line = Line(float(pairs[-1] @ u), float(u[0]), float(u[1]))
    psi = _planar_angles(theta1, theta2, phi1, phi2, start.get('dtheta1', 0.0), start.get('dtheta2', 0.0),
                         start.get('dphi1', 0.0), start.get('dphi2', 0.0), line)
    if psi is None:
        return None
    planar = {c: float(p @ u) for c, p in zip(CART_STATES, pairs[:-1], strict=True) if c in start}
    planar.update({name: start[name] for name in HOIST_STATES if name in start})
    planar.update(dict(zip(('theta1', 'theta2', 'dtheta1', 'dtheta2'), psi, strict=True)))
    request = {CART_JOINT: line.length, **({HOIST_JOINT: moves[HOIST_JOINT]} if HOIST_JOINT in moves else {})}
    return line, request, planar


def _planar_angles(theta1, theta2, phi1, phi2, dtheta1, dtheta2, dphi1, dphi2, line: Line):
    """(psi1, psi2, dpsi1, dpsi2): the planar swing in the plane of ``line`` whose ``spatial_angles`` are the
    given ones (to ``IN_PLANE_TOLERANCE``), else None. Each cable's absolute in-plane angle from its direction
    u(a, b) (``spatial_angles``), its rate by least squares from both angles' rates."""
    absolute = []
    for a, b, da, db in ((theta1, phi1, dtheta1, dphi1), (theta1 + theta2, phi1 + phi2, dtheta1 + dtheta2,
                                                           dphi1 + dphi2)):
        lean = -(-math.sin(a) * math.cos(b) * line.cos + math.sin(b) * line.sin)  # sin(Psi)
        Psi = math.atan2(lean, math.cos(a) * math.cos(b))
        ka, kb = line.cos / math.cos(b) ** 2, -line.sin * math.cos(Psi) / math.cos(b)  # d(a, b)/dPsi
        absolute.append((Psi, (ka * da + kb * db) / (ka * ka + kb * kb)))
    (Psi1, dPsi1), (Psi2, dPsi2) = absolute
    psi = (Psi1, Psi2 - Psi1, dPsi1, dPsi2 - dPsi1)
    back = spatial_angles(*psi, line)
    given = dict(theta1=theta1, theta2=theta2, phi1=phi1, phi2=phi2, dtheta1=dtheta1, dtheta2=dtheta2,
                 dphi1=dphi1, dphi2=dphi2)
    if any(abs(float(back[name]) - value) > IN_PLANE_TOLERANCE for name, value in given.items()):
        return None
    return psi


def on_line(planar: Plan, line: Line) -> AxesPlan:
    """The spatial plan of ``planar`` (a ``CollocationPlan`` of the cart, or an ``AxesPlan`` of the cart and
    the hoist, solved for the line's length) along ``line``: the cart's and the bridge's references its
    travel reference times ``line.cos`` and ``line.sin``, the hoist's its own; the model path turned into
    the spatial crane's states (``spatial_angles``; the planar sensitivities are not carried over)."""
    axes = plan_axes(planar)
    travel = axes[CART_JOINT]
    info = dict(planar.info, solved_in_plane=True)
    plans = {CART_JOINT: _scaled(travel, line.cos, info), BRIDGE_JOINT: _scaled(travel, line.sin, info)}
    if HOIST_JOINT in axes:
        plans[HOIST_JOINT] = axes[HOIST_JOINT]
    starts = {name: (planar.starts.get(HOIST_JOINT) if name == HOIST_JOINT else 0.0) for name in plans}
    path = planar.model_path
    return AxesPlan(method=planar.method, displacement=plans[CART_JOINT].displacement, duration=planar.duration,
                    info=info, axes=plans, starts=starts,
                    model_path=None if path is None else ModelPath(path.t, spatial_states(path.states, line)))


def _scaled(plan: CollocationPlan, k: float, info: dict) -> CollocationPlan:
    """``plan`` times ``k`` (its reference is linear in its coefficients and start values)."""
    return CollocationPlan(plan.method, plan.displacement * k, plan.duration, info, mesh=plan.mesh,
                           coef=plan.coef * k, start=plan.start * k)


def spatial_states(planar: dict, line: Line) -> dict:
    """The spatial crane's states (SI, by ``dynamics`` name) of the planar crane's ``planar`` swinging in
    the vertical plane of ``line``: the cart's and the bridge's the travel axis's shares, the hoist's its
    own, the swing ``spatial_angles``."""
    states = {}
    for cart, bridge in zip(CART_STATES, BRIDGE_STATES, strict=True):
        if cart in planar:  # (a_ref only with the servo)
            states[cart], states[bridge] = planar[cart] * line.cos, planar[cart] * line.sin
    states.update({name: planar[name] for name in HOIST_STATES if name in planar})
    states.update(spatial_angles(planar['theta1'], planar['theta2'], planar['dtheta1'], planar['dtheta2'], line))
    return states


def spatial_angles(psi1, psi2, dpsi1, dpsi2, line: Line) -> dict:
    """theta1, theta2, phi1, phi2 and their rates (contract "The spatial crane": ``dynamics.cable_direction``)
    of the planar swing psi1, psi2 (the lower cable's relative to the upper's) and its rates in the vertical
    plane of ``line``.

    A cable at the absolute in-plane angle Psi points along u = (-sin Psi cos alpha, -sin Psi sin alpha,
    -cos Psi); u(a, b) = (-sin a cos b, sin b, -cos a cos b) gives b = asin(-sin alpha sin Psi) and
    a = atan2(cos alpha sin Psi, cos Psi), so da/dPsi = cos alpha / cos^2 b and db/dPsi = -sin alpha
    cos Psi / cos b. The lower cable's theta2, phi2 are relative to the upper's, as psi2 is.
    """
    out = {}
    a_prev = b_prev = da_prev = db_prev = 0.0
    for k, (Psi, dPsi) in enumerate(((psi1, dpsi1), (np.add(psi1, psi2), np.add(dpsi1, dpsi2))), start=1):
        b = np.arcsin(-line.sin * np.sin(Psi))
        a = np.arctan2(line.cos * np.sin(Psi), np.cos(Psi))
        da = line.cos / np.cos(b) ** 2 * dPsi
        db = -line.sin * np.cos(Psi) / np.cos(b) * dPsi
        out.update({f'theta{k}': a - a_prev, f'phi{k}': b - b_prev, f'dtheta{k}': da - da_prev,
                    f'dphi{k}': db - db_prev})
        a_prev, b_prev, da_prev, db_prev = a, b, da, db
    return out
