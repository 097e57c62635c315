"""Where both masses go along a plan, predicted on the planning model (contract "Routes and protected
areas").

``predict_mass_path`` drives the planning model (``dynamics.crane_ode``:
Eqs. 18-19 with the servo of Eq. 6, the hoist's Lagrangian with one, the
spatial crane with a bridge) from rest with the plan's reference jerk per
axis, by the same RK4 steps ``continuation.predict`` carries a measured
state with, over the motion and a settle window after it, and places both
masses in ``crane_base`` (``dynamics.masses_at``). What the planner
checks keep-out boxes against (``keep_out.KeepOut``); the simulator's
independent model is what the tests check this prediction against. Pure
Python, no ROS import.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from crane_msgs_py.crane.params import CraneParams

from .continuation import CHUNK, _rk4_steps
from .dynamics import PARAMETERS, masses_at
from .plan import AxesPlan, Plan
from .problem import AXIS_STATES, Form

#: RK4 step (s) of the prediction: a twentieth of the fastest swing period served (8.99 rad/s: 0.7 s)
#: and half the default servo tau's stability bound; the masses move < 0.1 mm between two steps.
PREDICTION_STEP = 5e-3
#: Seconds after the motion the masses are predicted over unless told otherwise (ExecuteMove's default settle).
DEFAULT_SETTLE = 2.0
#: The states that place an axis (each relative to its start); every other state, a sensitivity aside, is 0 at rest.
POSITIONS = tuple(states[0] for states in AXIS_STATES.values())
#: The swing angles that place the masses below the suspension point (``dynamics.masses_at``).
ANGLES = ('theta1', 'theta2', 'phi1', 'phi2')
#: The states that place both masses.
PLACING = POSITIONS + ANGLES
#: A solved model whose every non-position state ends within this (SI) is at rest: it stays where it ends.
REST_TOLERANCE = 1e-6


@dataclass(frozen=True)
class MassPath:
    """Both masses' positions (m, ``crane_base``) at the times ``t`` (s from the plan's start): ``m1``, ``m2``
    of shape (len(t), 3); ``duration`` the motion's, the rest is its settle window."""

    t: np.ndarray
    m1: np.ndarray
    m2: np.ndarray
    duration: float

    def largest_step(self) -> float:
        """The largest distance (m) either mass moves from one time to the next."""
        return max(float(np.linalg.norm(np.diff(m, axis=0), axis=1).max(initial=0.0)) for m in (self.m1, self.m2))


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
    return _placed(t, dict(zip(names, np.hstack(states))), params, origin, plan.duration)


def solved_mass_path(plan: Plan, params: CraneParams, origin: dict | None = None,
                     settle: float = DEFAULT_SETTLE) -> MassPath | None:
    """Both masses where ``plan``'s solver put the planning model ``params`` (``Plan.model_path``: an NVF/RVF
    solution's collocation points, some 10 ms apart), and at rest at the goal ``settle`` s later; None if the
    plan carries no model path, or its model does not end at rest (then ``predict_mass_path``).

    No integration: the solution's states are the model's own prediction (the collocation equations hold
    at these points). Between two points a mass may come closer to a box than at either, by at most about
    ``MassPath.largest_step``.
    """
    solved = plan.model_path
    if solved is None:
        return None
    end = {name: values[-1] for name, values in solved.states.items()}
    if any(abs(v) > REST_TOLERANCE for name, v in end.items() if name not in POSITIONS and '/' not in name):
        return None
    if 'hoist' in plan_axes(plan):
        params = params.replace(L1=float(plan.starts.get('hoist', params.L1)))
    t = np.append(solved.t, solved.t[-1] + max(settle, 0.0))
    states = {name: np.append(values, values[-1]) for name, values in solved.states.items() if name in PLACING}
    return _placed(t, states, params, origin or {}, plan.duration)


def _placed(t: np.ndarray, s: dict, params: CraneParams, origin: dict, duration: float) -> MassPath:
    """The MassPath of the model's states ``s`` (SI, by name) at the times ``t``: the travel axes' positions
    relative to ``origin``, the hoist's to ``params.L1``; an axis without states stands still."""
    zero = np.zeros(len(t))
    x_cart = s[AXIS_STATES['cart'][0]] + origin.get('cart', 0.0)
    y_bridge = s.get(AXIS_STATES['bridge'][0], zero) + origin.get('bridge', 0.0)
    L1 = params.L1 + s.get(AXIS_STATES['hoist'][0], zero)
    p1, p2 = masses_at(x_cart, y_bridge, L1, params.L2, *(s.get(k, zero) for k in ANGLES), lib=np)
    return MassPath(t, p1.T, p2.T, duration)


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
    """Both masses hanging at rest below the suspension point (x, y, 0): {mass: (3,)} (m); the cables
    straight down (``dynamics.masses_at`` with every angle 0)."""
    return {'m1': np.array([x, y, -L1]), 'm2': np.array([x, y, -L1 - L2])}
