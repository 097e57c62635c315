"""Shapers while hoisting: the cart's shaped motion beside the hoist's own smooth profile.

With the upper cable's length L1(t) changing during the move, the swing's two
frequencies change, and the changing length also pumps the swing (the terms
in L1' of ``dynamics.hoisting_swing``): a shaper designed at one length leaves
swing. The hoist moves by its own rest-to-rest quintic over the whole
duration (``QuinticPlan``); the cart's base motion (the paper's quintic) is
shaped by a shaper designed at one length (``start``, ``middle`` or ``end``),
or by the length-adaptive one (``adaptive``, ``adaptive_shaper``): the same
impulses per mode, their delays and amplitudes fitted to the hoisting crane
linearized about rest, so that it ends at rest. ``HOIST_SHAPER_DESIGNS``
lists the choices; the README has the measured comparison behind the default.
With a bridge both travel axes take the one shaper on their shares of a
straight move (``shaped.along``).
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import casadi as ca
import numpy as np

from crane_msgs_py.crane.params import CraneParams

from .dynamics import hoisting_swing
from .limits import lead_axis
from .model import modal_properties
from .plan import AxesPlan, Plan, PlanError
from .profiles import quintic, quintic_base
from .shaped import ShapedPlan, along, shaped_plan
from .shapers import SHAPERS, Shaper, cascade

#: How the cart's shaper follows the rope length while hoisting: ``adaptive`` (fitted to the hoisting crane,
#: the default), or designed at the ``start`` length, the ``middle`` one or the ``end`` one.
HOIST_SHAPER_DESIGNS = ('adaptive', 'start', 'middle', 'end')


@dataclass(kw_only=True)
class QuinticPlan(Plan):
    """The rest-to-rest quintic D P(t/T) over the whole duration (the hoist's motion, or an unshaped cart)."""

    def _evaluate(self, t):
        return quintic(t, self.displacement, self.duration)


@functools.lru_cache(maxsize=1)
def _linearized_swing() -> ca.Function:
    """(A, B) of the swing linearized about rest, z = (theta1, theta2, theta1', theta2'), z' = A z + B a,
    as functions of the rope length and its rate and acceleration (from ``dynamics.hoisting_swing``)."""
    th1, th2, d1, d2, a = (ca.SX.sym(n) for n in ('th1', 'th2', 'd1', 'd2', 'a'))
    L, dL, ddL, L2, m1, m2, g, c1, c2 = (ca.SX.sym(n) for n in ('L', 'dL', 'ddL', 'L2', 'm1', 'm2', 'g', 'c1',
                                                                 'c2'))
    z = ca.vertcat(th1, th2, d1, d2)
    f = ca.vertcat(d1, d2, *hoisting_swing()(th1, th2, d1, d2, a, L, dL, ddL, L2, m1, m2, g, c1, c2))
    rest = ca.vertcat(z, a)
    A, B = (ca.substitute(ca.jacobian(f, v), rest, ca.DM.zeros(5)) for v in (z, a))
    return ca.Function('linearized_swing', [L, dL, ddL, L2, m1, m2, g, c1, c2], [A, B])


def end_response(params: CraneParams, hoist: Plan, duration: float, steps: int = 1500):
    """(s, G): the swing state at ``duration`` per unit of cart acceleration impulse at time s, G (steps+1, 4).

    For the swing linearized about rest while the rope length is
    L1 + hoist(t), z(T) = int_0^T G(s) a(s) ds with G(s) = Phi(T, s) B(s):
    the rows of the transition matrix come from one backward RK4
    integration of the adjoint, dPsi/ds = -Psi A(s), Psi(T) = I.
    """
    s = np.linspace(0.0, duration, 2 * steps + 1)  # nodes and midpoints
    h = hoist.evaluate(s)
    fixed = (params.L2, params.m1, params.m2, params.g, params.c1, params.c2)
    A, B = _linearized_swing().map(s.size)(params.L1 + h.position, h.velocity, h.acceleration,
                                           *(np.full(s.size, v) for v in fixed))
    A = np.array(A).reshape(4, s.size, 4).transpose(1, 0, 2)  # (n, 4, 4)
    B = np.array(B).T  # (n, 4)
    dt = 2.0 * duration / (s.size - 1)
    Psi = np.empty((steps + 1, 4, 4))
    Psi[-1] = np.eye(4)
    for i in range(steps, 0, -1):  # node 2i back to node 2i - 2, in reversed time r: dPsi/dr = Psi A(T - r)
        P = Psi[i]
        k1 = P @ A[2 * i]
        k2 = (P + 0.5 * dt * k1) @ A[2 * i - 1]
        k3 = (P + 0.5 * dt * k2) @ A[2 * i - 1]
        k4 = (P + dt * k3) @ A[2 * i - 2]
        Psi[i - 1] = P + dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    return s[::2], np.einsum('nij,nj->ni', Psi, B[::2])


def _simpson_weights(n: int, dt: float) -> np.ndarray:
    w = np.ones(n)
    w[1:-1:2], w[2:-1:2] = 4.0, 2.0
    return w * dt / 3.0


def adaptive_shaper(method: str, displacement: float, duration: float, params: CraneParams, hoist: Plan,
                    zeta=None) -> Shaper:
    """The ``method`` shaper adapted to the hoisting crane: no residual swing on its linearized model.

    Each mode's shaper keeps its form (its impulses at its own relative
    times, scaled by one delay; amplitudes summing to 1), but the delays and
    amplitudes are chosen so that the cascade applied to the quintic base
    (T minus the shaper long) leaves the swing linearized about rest, with
    the rope length moving as the hoist does (``end_response``), at rest at
    T: four equations. Among the shapers meeting them, the nearest to the
    design at the middle length (delays relative, amplitudes absolute), so
    a shaper with more impulses than ZV's keeps its robustness as well as
    it can. The impulses follow the changing frequencies through the model,
    not through a schedule of frequencies: a changing length also pumps the
    swing (the Coriolis terms in L1'), which delays alone do not cancel.
    ``zeta`` is the design damping ratio (None: the model's at the middle length).
    """
    L_mid = params.L1 + 0.5 * hoist.displacement
    omegas, zetas = modal_properties(params.replace(L1=L_mid))
    zetas = np.broadcast_to(np.asarray(zetas if zeta is None else zeta, dtype=float), (len(omegas),))
    modes = [SHAPERS[method](float(w), float(z)) for w, z in zip(omegas, zetas)]
    units = [m.times / m.duration for m in modes]
    sizes = [m.amplitudes.size for m in modes]
    s, G = end_response(params, hoist, duration)
    weights = _simpson_weights(s.size, s[1] - s[0])
    scale = max(abs(displacement), 1e-3) / (params.g * duration ** 2)  # the swing's size (rad)
    n = len(modes)

    def unpack(x) -> Shaper:
        amplitudes = np.split(x[n:], np.cumsum(sizes)[:-1])
        return cascade(*(Shaper(a, d * u) for a, d, u in zip(amplitudes, x[:n], units)))

    def end_state(x) -> np.ndarray:
        if np.any(x[:n] <= 0.0):
            return np.full(4, 1e3)
        shaper = unpack(x)
        base = duration - shaper.duration
        if base <= 0.0:
            return np.full(4, 1e3)
        acceleration = quintic(s[None, :] - shaper.times[:, None], displacement, base)[2]  # (K, n)
        return G.T @ (weights * (shaper.amplitudes @ acceleration)) / scale

    def conditions(x) -> np.ndarray:  # at rest at T, and each mode's amplitudes summing to 1
        sums = [np.sum(a) - 1.0 for a in np.split(x[n:], np.cumsum(sizes)[:-1])]
        return np.concatenate([end_state(x), sums])

    # Newton's method with the least-norm step (in delays relative to the design's, amplitudes as they
    # are): it ends on a solution near the design at the middle length
    nominal = np.concatenate([[m.duration for m in modes], *[m.amplitudes for m in modes]])
    scaled = np.concatenate([nominal[:n], np.ones(nominal.size - n)])
    y = nominal / scaled
    for _ in range(30):
        c = conditions(y * scaled)
        if np.max(np.abs(c)) < 1e-10:
            break
        J = np.empty((c.size, y.size))
        for j in range(y.size):
            dy = np.zeros(y.size)
            dy[j] = 1e-7
            J[:, j] = (conditions((y + dy) * scaled) - c) / 1e-7
        step = np.linalg.lstsq(J, c, rcond=None)[0]
        for _ in range(20):  # halved while it would make a delay negative or not bring the conditions closer
            trial = y - step
            if np.all(trial[:n] > 0.0) and np.linalg.norm(conditions(trial * scaled)) < np.linalg.norm(c):
                break
            step = 0.5 * step
        y = trial
    x = y * scaled
    if np.max(np.abs(conditions(x))) > 1e-8 or np.any(x[:n] <= 0.0):
        raise PlanError(f'{method}: no length-adaptive shaper found for this hoisting move; lengthen the '
                        'duration or hoist less')
    return unpack(x)


def adaptive_shaped_plan(method: str, displacement: float, duration: float, params: CraneParams, hoist: Plan,
                         zeta=None) -> ShapedPlan:
    """The cart's ``method`` plan with the length-adaptive shaper (``adaptive_shaper``) on the quintic base."""
    shaper = adaptive_shaper(method, displacement, duration, params, hoist, zeta)
    if not shaper.duration < duration:
        raise PlanError(f'{method} needs a duration longer than its shaper ({shaper.duration:.3f} s), '
                        f'got {duration} s')
    plan = ShapedPlan(method=method, displacement=float(displacement), duration=float(duration), info={},
                      shaper=shaper, base=quintic_base(displacement, duration - shaper.duration))
    plan.info.update({'shaper_design': 'adaptive', 'impulse_times': shaper.times.tolist(),
                      'impulse_amplitudes': shaper.amplitudes.tolist(), 'shaper_duration': shaper.duration,
                      'base': 'quintic', 'base_duration': plan.base.duration})
    return plan


def design_length(choice: str, L_start: float, L_goal: float) -> float:
    """The rope length (m) a fixed shaper is designed at: ``start``, ``middle`` or ``end``."""
    return {'start': L_start, 'middle': 0.5 * (L_start + L_goal), 'end': L_goal}[choice]


def shaped_hoisting_plan(method: str, displacement: float, hoist_displacement: float, duration: float,
                         params: CraneParams, zeta=None, shaper_design: str = 'adaptive',
                         bridge: float | None = None) -> AxesPlan:
    """The cart (and the ``bridge``'s displacement, m) shaped by ``method`` and the hoist's quintic, from
    L1 = ``params.L1`` by ``hoist_displacement``.

    ``shaper_design`` is one of ``HOIST_SHAPER_DESIGNS``; ``zeta`` the design
    damping ratio (None: the model's modal damping at the design length).
    With a bridge the move is straight (``shaped.along``): both travel axes
    take the one shaper, fitted or designed for the lead axis's move. The
    adaptive shaper fits the swing linearized about rest, where the x-z
    and y-z planes are uncoupled and alike, and its conditions are linear
    in the displacement: one fit serves both axes.
    """
    if shaper_design not in HOIST_SHAPER_DESIGNS:
        raise PlanError(f'hoist shaper design must be one of {", ".join(HOIST_SHAPER_DESIGNS)}, '
                        f'got {shaper_design!r}')
    check_hoist(params.L1, hoist_displacement)
    travel = travel_displacements(displacement, bridge)
    lead = travel[lead_axis(travel)]
    hoist = QuinticPlan(method='quintic', displacement=float(hoist_displacement), duration=float(duration))
    if shaper_design == 'adaptive':
        shaped = adaptive_shaped_plan(method, lead, duration, params, hoist, zeta)
    else:
        at = params.replace(L1=design_length(shaper_design, params.L1, params.L1 + hoist_displacement))
        omegas, zetas = modal_properties(at)
        shaped = shaped_plan(method, lead, duration, omegas, zetas if zeta is None else zeta)
        shaped.info['shaper_design'] = shaper_design
    return AxesPlan(method=method, displacement=float(displacement), duration=float(duration), info=shaped.info,
                    axes={**along(shaped, travel), 'hoist': hoist}, starts={'cart': 0.0, 'hoist': params.L1})


def travel_displacements(displacement: float, bridge: float | None = None) -> dict[str, float]:
    """The travel axes' displacements (m) by axis name: the cart's, and the bridge's if it moves."""
    return {'cart': float(displacement), **({} if bridge is None else {'bridge': float(bridge)})}


def quintic_axes_plan(displacements: dict, duration: float, starts: dict | None = None) -> AxesPlan:
    """Every axis of ``displacements`` (m, by axis name, the cart's first) on the unshaped quintic over the
    whole duration: what the shapers are measured against. ``starts``: as ``AxesPlan``'s."""
    axes = {name: QuinticPlan(method='quintic', displacement=float(D), duration=float(duration))
            for name, D in displacements.items()}
    return AxesPlan(method='quintic', displacement=axes['cart'].displacement, duration=float(duration), info={},
                    axes=axes, starts=dict(starts or {}))


def quintic_hoisting_plan(displacement: float, hoist_displacement: float, duration: float,
                          params: CraneParams, bridge: float | None = None) -> AxesPlan:
    """The cart (and the bridge) and the hoist on the unshaped quintic (``quintic_axes_plan``)."""
    return quintic_axes_plan({**travel_displacements(displacement, bridge), 'hoist': hoist_displacement}, duration,
                             {'cart': 0.0, 'hoist': params.L1})


def check_hoist(L_start: float, hoist_displacement: float) -> None:
    """PlanError unless the rope stays longer than 0 from ``L_start`` (m) by ``hoist_displacement`` (m)."""
    if not np.isfinite(hoist_displacement):
        raise PlanError(f'the hoist displacement must be finite, got {hoist_displacement}')
    if not L_start + hoist_displacement > 0.0:
        raise PlanError(f'the hoist would end at L1 = {L_start + hoist_displacement:g} m; the rope length must '
                        'stay > 0')
