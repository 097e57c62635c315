"""Where both masses go along a plan, predicted on the planning model (contract "Routes and protected
areas").

``predict_mass_path`` drives the planning model (``dynamics.crane_ode``:
Eqs. 18-19 with the servo of Eq. 6, the hoist's Lagrangian with one, the
spatial crane with a bridge) from rest with the plan's reference jerk per
axis, by the same RK4 steps ``continuation.predict`` carries a measured
state with, over the motion and a settle window after it, and places both
masses in ``crane_base`` (``dynamics.mass_positions``). What the planner
checks keep-out boxes against (``keep_out.KeepOut``); the simulator's
independent model is what the tests check this prediction against. Pure
Python, no ROS import.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from crane_msgs_py.params import CraneParams

from .continuation import CHUNK, _rk4_steps
from .dynamics import PARAMETERS, mass_positions
from .plan import AxesPlan, Plan
from .problem import AXIS_STATES, Form

#: RK4 step (s) of the prediction: a twentieth of the fastest swing period served (8.99 rad/s: 0.7 s)
#: and half the default servo tau's stability bound; the masses move < 0.1 mm between two steps.
PREDICTION_STEP = 5e-3
#: Seconds after the motion the masses are predicted over unless told otherwise (ExecuteMove's default settle).
DEFAULT_SETTLE = 2.0


@dataclass(frozen=True)
class MassPath:
    """Both masses' positions (m, ``crane_base``) at the times ``t`` (s from the plan's start): ``m1``, ``m2``
    of shape (len(t), 3); ``duration`` the motion's, the rest is its settle window."""

    t: np.ndarray
    m1: np.ndarray
    m2: np.ndarray
    duration: float


def plan_axes(plan: Plan) -> dict:
    """Every axis's plan by name (a cart plan alone: ``{'cart': plan}``)."""
    return dict(plan.axes) if isinstance(plan, AxesPlan) else {'cart': plan}


def predict_mass_path(plan: Plan, params: CraneParams, origin: dict | None = None,
                      settle: float = DEFAULT_SETTLE, step: float = PREDICTION_STEP,
                      start: dict | None = None) -> MassPath:
    """Both masses along ``plan`` and ``settle`` s after it, on the planning model ``params``.

    ``origin``: where each travel axis's reference starts (m, by joint name; the plan is relative), 0 if
    not given. The hoist's start is the plan's (``AxesPlan.starts``: the rope length), else ``params.L1``.
    ``start``: the model's states at the plan's start (SI, by name, as ``continuation.problem_start`` gives
    them for a plan from a moving, swinging state; with ``params`` its model); None = at rest.
    """
    origin = origin or {}
    axes = plan_axes(plan)
    hoist = 'hoist' in axes
    if hoist:
        params = params.replace(L1=float(plan.starts.get('hoist', params.L1)))
    form = Form.of(params, hoist, 'bridge' in axes)
    rk4, names = _rk4_steps(form)
    p = np.array([params.as_dict()[k] for k in PARAMETERS])
    t = _time_grid(plan, max(settle, 0.0), step)
    n, h = len(t) - 1, np.diff(t)
    # each step's jerk from within its own piece: a step never straddles a breakpoint, where the jerk jumps
    inside = 1e-9 * h
    jerk = [np.array([axes[name].evaluate(when).jerk for name in form.axes])
            for when in (t[:-1] + inside, t[:-1] + h / 2, t[1:] - inside)]
    u = np.vstack(jerk)
    x = np.array([(start or {}).get(name, 0.0) for name in names], dtype=float)
    states = [x[:, None]]
    for k in range(0, n, CHUNK):
        chunk = np.asarray(rk4(x, u[:, k:k + CHUNK], p, h[None, k:k + CHUNK]))
        states.append(chunk)
        x = chunk[:, -1]
    s = dict(zip(names, np.hstack(states)))
    zero = np.zeros(n + 1)
    x_cart = s[AXIS_STATES['cart'][0]] + origin.get('cart', 0.0)
    y_bridge = s[AXIS_STATES['bridge'][0]] + origin.get('bridge', 0.0) if form.bridge else zero + origin.get(
        'bridge', 0.0)
    L1 = params.L1 + (s[AXIS_STATES['hoist'][0]] if hoist else zero)
    angles = [s.get(k, zero) for k in ('theta1', 'theta2', 'phi1', 'phi2')]
    p1, p2 = mass_positions().map(n + 1)(x_cart, y_bridge, L1, params.L2, *angles)
    return MassPath(t, np.asarray(p1).T, np.asarray(p2).T, plan.duration)


def _time_grid(plan: Plan, settle: float, step: float) -> np.ndarray:
    """Times (s) from 0 to T + ``settle``: every breakpoint of the plan, no step longer than ``step``, and a
    whole number of ``CHUNK`` steps (the settle window takes up the rest)."""
    b = plan.breakpoints()
    pieces = [np.linspace(b[k], b[k + 1], max(1, math.ceil((b[k + 1] - b[k]) / step - 1e-9)) + 1)[:-1]
              for k in range(len(b) - 1)]
    motion = np.concatenate([*pieces, [b[-1]]])
    steps = len(motion) - 1 + max(1, math.ceil(settle / step - 1e-9))
    rest = math.ceil(steps / CHUNK) * CHUNK - (len(motion) - 1)
    return np.concatenate([motion, b[-1] + np.linspace(0.0, settle, rest + 1)[1:]])


def rest_positions(x: float, y: float, L1: float, L2: float) -> dict:
    """Both masses hanging at rest below the suspension point (x, y, 0): {mass: (3,)} (m)."""
    p1, p2 = mass_positions()(x, y, L1, L2, 0.0, 0.0, 0.0, 0.0)
    return {'m1': np.asarray(p1).ravel(), 'm2': np.asarray(p2).ravel()}
