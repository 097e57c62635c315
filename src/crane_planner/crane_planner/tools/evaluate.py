"""Judge a plan on a plant: drive the independent simulator and report the contract's figures.

The plan's own peaks (velocity, acceleration, jerk) are of the reference; the
swing figures come from ``crane_sim`` integrating Eqs. 18-19 plus the servo,
driven by the plan's acceleration as an axis controller would see it
(linear interpolation between 1 ms samples), and with a hoist (an
``AxesPlan``) by the hoist's too: each plant's L1 is then the start length.
With a bridge the plant is the spatial crane (contract "The spatial crane"):
the figures add the out-of-plane angles ``phi1``, ``phi2`` and the residual
load swing is the norm of the load's horizontal offset (``spatial_metrics``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from crane_msgs_py.crane.params import CraneParams
from crane_msgs_py.messages.names import ACTUATED_JOINTS, CART_JOINT, HOIST_JOINT
from crane_planner.planning import Plan, Samples
from crane_planner.planning.plan import AxesPlan, time_grid
from crane_sim.metrics import peak, rms, swing_metrics, window
from crane_sim.simulator import SimResult, simulate
from crane_sim.spatial import mass_paths

#: Simulation step and reference sample period used to evaluate plans (s).
EVAL_STEP = 1e-3
#: Simulation step of batch evaluations (compare, sweep, choose) once every plan has ended (s):
#: the swing is then free, and RK4 at 5 ms changes the residual figures by < 0.05 % (peaks
#: sampled 5x coarser) for a third of the steps of a 5 s settle window (``simulate``'s rest_dt).
EVAL_REST_STEP = 5e-3
#: Seconds observed after the motion by default (contract: ``--settle``).
DEFAULT_SETTLE = 10.0


@dataclass
class Evaluation:
    """A plan, its 1 ms samples and the simulated response of one or more plants."""

    plan: Plan
    samples: Samples
    sim: SimResult
    metrics: list  # one contract dict per plant


def simulate_plans(plans, plants, settle: float = DEFAULT_SETTLE, rest_step: float = EVAL_REST_STEP
                   ) -> list[Evaluation]:
    """Simulate every plan on every plant over [0, T + settle], in one batch.

    The simulator is vectorized and its cost per step is mostly fixed, so all
    (plan, plant) pairs share one run, over [0, max T + settle]: a shorter
    plan rests at its goal after its end, and each plan's figures are taken
    over its own [0, T] and [T, T + settle].

    Args:
        plans: the plans (durations may differ).
        plants: one CraneParams or a sequence of them.
        settle: seconds observed after the motion.
        rest_step: simulation step (s) once every plan has ended (``EVAL_STEP`` for 1 ms throughout).

    Returns:
        One Evaluation per plan, its ``sim`` and ``metrics`` over all plants.
    """
    plans = list(plans)
    plants = [plants] if isinstance(plants, CraneParams) else list(plants)
    longest = max(p.duration for p in plans)
    t = time_grid(longest, EVAL_STEP)
    n = len(plants)
    # every axis any plan moves; a plan without it holds it (the hoist: each plant's L1 is where it starts)
    axes = [CART_JOINT, *(name for name in ACTUATED_JOINTS[1:]
                          if any(isinstance(p, AxesPlan) and name in p.axes for p in plans))]
    references = {name: np.repeat(np.stack([_axis_acceleration(p, name, t) for p in plans]), n, axis=0)
                  for name in axes}
    sim = simulate(t, references, plants * len(plans), dt=EVAL_STEP, t_end=longest + settle,
                   interpolation='linear', rest_dt=rest_step)
    evaluations = []
    for k, plan in enumerate(plans):
        part = sim.members(slice(k * n, (k + 1) * n))
        evaluations.append(Evaluation(plan, plan.sample(EVAL_STEP), part,
                                      spatial_metrics(part, plan.duration, settle)))
    return evaluations


#: The out-of-plane swing angles a simulation with a bridge has beside theta1, theta2.
OUT_OF_PLANE = ('phi1', 'phi2')


def spatial_metrics(result: SimResult, duration: float, settle: float) -> list[dict]:
    """``crane_sim.metrics.swing_metrics`` of ``result`` and, with a bridge, the same figures of ``phi1``,
    ``phi2`` beside them and the residual ``load_mm`` the peak norm of the load's horizontal offset over
    [T, T + settle] (``SimResult.load_excursion``; swing_metrics' is the x-z plane's)."""
    figures = swing_metrics(result, None, duration, settle)
    if 'phi1' not in result.states:
        return figures
    t = result.t
    motion, after = window(t, 0.0, duration), window(t, duration, duration + settle)
    load_mm = 1e3 * peak(result.load_excursion[:, after])
    for i, m in enumerate(figures):
        for name in OUT_OF_PLANE:
            x = result.states[name][i]
            m['peak'][name] = peak(x[motion])
            m['rms'][name] = rms(x[motion], t[motion])
            m['residual'][name] = peak(x[after])
        m['residual']['load_mm'] = float(load_mm[i])
    return figures


def _axis_acceleration(plan: Plan, name: str, t) -> np.ndarray:
    """The reference acceleration of the axis ``name`` in ``plan`` at ``t``; 0 where the plan does not move it."""
    one = plan.axes.get(name) if isinstance(plan, AxesPlan) else plan if name == CART_JOINT else None
    return 0.0 * t if one is None else one.evaluate(t).acceleration


def simulate_plan(plan: Plan, plants, settle: float = DEFAULT_SETTLE) -> Evaluation:
    """Simulate ``plants`` (one CraneParams or a sequence) driven by ``plan`` over [0, T + settle], at 1 ms."""
    return simulate_plans([plan], plants, settle, rest_step=EVAL_STEP)[0]


def plan_report(ev: Evaluation, plan_time_s: float, index: int = 0) -> dict:
    """The contract's JSON object for ``crane-plan plan`` (plant ``index`` of the batch)."""
    s, m = ev.samples, ev.metrics[index]
    return {
        'method': ev.plan.method,
        'displacement': ev.plan.displacement,
        'duration': ev.plan.duration,
        'peak': {'velocity': peak(s.velocity), 'acceleration': peak(s.acceleration),
                 'jerk': peak(s.jerk), **m['peak']},
        'rms': {'velocity': rms(s.velocity), 'acceleration': rms(s.acceleration), **m['rms']},
        'residual': dict(m['residual']),
        'plan_time_s': plan_time_s,
        **axes_report(ev.plan),
        # the smallest predicted distance of a mass to a keep-out box (m), when boxes were given
        **({'min_clearance': ev.plan.info['min_clearance']} if 'min_clearance' in ev.plan.info else {}),
    }


def axes_report(plan: Plan) -> dict:
    """Per axis beside the cart (``AxesPlan``; empty for a cart alone), by its name: ``{start, goal (m), peak
    velocity, acceleration, jerk of its reference}`` (the bridge's relative like the cart's, the hoist's the
    rope length), the hoist's with the ``shaper_design`` a shaper followed the rope length by."""
    if not isinstance(plan, AxesPlan):
        return {}
    report = {}
    for name, one in plan.axes.items():
        if name == CART_JOINT:
            continue
        v, a, j = one.peaks()
        start = plan.starts.get(name, 0.0)
        report[name] = {'start': start, 'goal': start + one.displacement,
                        'peak': {'velocity': v, 'acceleration': a, 'jerk': j}}
        if name == HOIST_JOINT:
            report[name]['shaper_design'] = plan.info.get('shaper_design')
    return report


def vary_parameter(model: CraneParams, param: str, span: float, points: int):
    """Plants with ``param`` at model value x (1 + linspace(-span, span, points))."""
    values = getattr(model, param) * (1.0 + np.linspace(-span, span, points))
    return values, [model.replace(**{param: float(v)}) for v in values]


def simulated_masses(result: SimResult, index: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(m1, m2): both masses' positions (3, n) in ``crane_base`` at ``result.t`` for plant ``index``, from the
    simulator's states (the suspension point relative to where the plan starts; with a hoist its rope
    length, else the plant's L1) placed by crane_sim's own cable directions."""
    states, zero = result.states, 0.0 * result.t
    row = {name: states[name][index] if name in states else zero for name in ('yb', 'phi1', 'phi2')}
    L1 = states['L1'][index] if 'L1' in states else zero + result.plants.L1[index]
    return mass_paths(states['y'][index], row['yb'], L1, result.plants.L2[index], states['theta1'][index],
                      states['theta2'][index], row['phi1'], row['phi2'])


def residual_load_mm(ev: Evaluation) -> np.ndarray:
    """Residual load excursion (mm) of every plant in the batch."""
    return np.array([m['residual']['load_mm'] for m in ev.metrics])
