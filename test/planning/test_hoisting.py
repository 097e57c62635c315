"""Hoisting while travelling: the planner's model, NVF/RVF with two axes, shapers while hoisting.

Residuals are measured on crane_sim's independent numpy model (Newton's law
projected across the cables), never on the planner's own CasADi model.
"""
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from crane_msgs_py.crane.params import CraneParams
from crane_planner.planning import PlanError
from crane_planner.planning.dispatch import PlanOptions, SolverCache, fastest, plan
from crane_planner.planning.dynamics import hoisting_swing, swing_accelerations
from crane_planner.planning.hoisting import HOIST_SHAPER_DESIGNS, quintic_hoisting_plan
from crane_planner.planning.plan import AxesPlan
from crane_planner.tools.evaluate import residual_load_mm, simulate_plan, simulate_plans
from crane_sim import dynamics as sim_dynamics

NOMINAL = CraneParams(tau=0.0, tau_hoist=0.0)  # Table 1, ideal servos
LIFT, LOWER = (0.47, 0.27), (0.27, 0.47)
#: one solver cache for the module: warm starts as the planner has them
SOLVERS = SolverCache()

angles = st.floats(-1.2, 1.2)
rates = st.floats(-3.0, 3.0)


@settings(max_examples=200, deadline=None)
@given(angles, angles, rates, rates, st.floats(-5, 5), st.floats(0.1, 1.5), st.floats(-1.0, 1.0),
       st.floats(-3.0, 3.0), st.floats(0.1, 1.5), st.floats(0.05, 2.0), st.floats(0.05, 2.0),
       st.floats(0.0, 0.05), st.floats(0.0, 0.05))
def test_the_lagrangian_model_agrees_with_the_simulators_newton_form(th1, th2, d1, d2, a, L1, dL1, ddL1, L2, m1,
                                                                      m2, c1, c2):
    """Two derivations of the hoisting crane: CasADi from the Lagrangian (planner), Newton's law projected
    across the cables by hand (crane_sim)."""
    planner = np.array([float(x) for x in hoisting_swing()(th1, th2, d1, d2, a, L1, dL1, ddL1, L2, m1, m2, 9.81,
                                                            c1, c2)])
    acc = sim_dynamics.hoisting_accelerations(np.array([th1, th1 + th2]), np.array([d1, d1 + d2]), a, L1, dL1,
                                               ddL1, L2, m1, m2, 9.81, c1, c2)
    sim = np.array([acc[0], acc[1] - acc[0]])
    assert np.allclose(planner, sim, rtol=1e-9, atol=1e-9 * (1 + np.abs(sim).max()))


@settings(max_examples=100, deadline=None)
@given(angles, angles, rates, rates, st.floats(-5, 5), st.floats(0.1, 1.5))
def test_with_the_length_held_the_lagrangian_model_is_eqs_18_19(th1, th2, d1, d2, a, L1):
    p = NOMINAL
    held = [float(x) for x in hoisting_swing()(th1, th2, d1, d2, a, L1, 0.0, 0.0, p.L2, p.m1, p.m2, p.g, 0.0, 0.0)]
    eqs = [float(x) for x in swing_accelerations(th1, th2, d1, d2, a, L1, p.L2, p.m1, p.m2, p.g)]
    assert np.allclose(held, eqs, rtol=1e-10, atol=1e-10)


@pytest.mark.parametrize('lengths', [LIFT, LOWER], ids=['lift', 'lower'])
@pytest.mark.parametrize('method', ['nvf', 'rvf'])
def test_variational_plans_move_both_axes_rest_to_rest_and_leave_no_swing(method, lengths):
    """0.3 m in 3 s while L1 goes 0.47 -> 0.27 m (and back): <= 0.1 mm of residual swing."""
    p = plan(method, 0.3, 3.0, NOMINAL, variational=SOLVERS, hoist=lengths)
    assert isinstance(p, AxesPlan) and p.joint_names == ('cart', 'hoist')
    end = p.evaluate_axis('hoist', [0.0, 3.0])
    assert end.position == pytest.approx(list(lengths), abs=1e-9)
    for axis in ('cart', 'hoist'):
        ends = p.axes[axis].evaluate([0.0, 3.0])
        assert np.abs(ends.velocity).max() < 1e-9 and np.abs(ends.acceleration).max() < 1e-7
    assert p.axes['cart'].evaluate(3.0).position[0] == pytest.approx(0.3, abs=1e-9)
    residual = residual_load_mm(simulate_plan(p, NOMINAL.replace(L1=lengths[0]), settle=10.0))[0]
    assert residual <= 0.1, residual


def test_over_the_payload_rvf_leaves_a_third_of_nvfs_worst_residual():
    """RVF made insensitive to L2 (the default with a hoist) against NVF over L2 +- 20 % (11 plants)."""
    plants = [NOMINAL.replace(L1=LIFT[0], L2=NOMINAL.L2 * f) for f in np.linspace(0.8, 1.2, 11)]
    nvf, rvf = (plan(m, 0.3, 3.0, NOMINAL, variational=SOLVERS, hoist=LIFT) for m in ('nvf', 'rvf'))
    worst = [residual_load_mm(ev).max() for ev in simulate_plans([nvf, rvf], plants, settle=8.0)]
    assert worst[1] <= worst[0] / 3.0, worst


@pytest.mark.parametrize('lengths', [LIFT, LOWER], ids=['lift', 'lower'])
@pytest.mark.parametrize('method', ['zv', 'zvd'])
def test_shapers_as_shipped_leave_a_fifth_of_the_unshaped_quintic(method, lengths):
    shaped = plan(method, 0.3, 3.0, NOMINAL, hoist=lengths)
    assert shaped.info['shaper_design'] == 'adaptive'  # what ships
    unshaped = quintic_hoisting_plan(0.3, lengths[1] - lengths[0], 3.0, NOMINAL)
    plant = NOMINAL.replace(L1=lengths[0])
    ours, quintic = (residual_load_mm(ev)[0] for ev in simulate_plans([shaped, unshaped], plant, settle=8.0))
    assert quintic > 3.0  # the hoisting move swings when unshaped: the comparison means something
    assert ours <= quintic / 5.0, (ours, quintic)


def test_a_shaper_designed_at_one_length_leaves_more_than_the_adaptive_one():
    """The README's comparison in one line: every fixed design leaves > 10x the adaptive one."""
    plans = [plan('zv', 0.3, 3.0, NOMINAL, PlanOptions(hoist_shaper=d), hoist=LIFT) for d in HOIST_SHAPER_DESIGNS]
    residuals = [residual_load_mm(ev)[0] for ev in simulate_plans(plans, NOMINAL.replace(L1=0.47), settle=8.0)]
    adaptive, fixed = residuals[0], residuals[1:]
    assert min(fixed) > 10 * adaptive, dict(zip(HOIST_SHAPER_DESIGNS, residuals))


def test_axis_limits_hold_per_axis_and_the_fastest_plan_meets_one():
    options = PlanOptions(max_velocity=0.3, max_acceleration=0.5, max_hoist_velocity=0.2,
                          max_hoist_acceleration=0.4, max_hoist_jerk=30.0)
    p = fastest('nvf', 0.3, NOMINAL, options, variational=SOLVERS, hoist=LIFT)
    cart, hoist = p.axes['cart'].peaks(), p.axes['hoist'].peaks()
    assert cart[0] <= 0.3 * (1 + 1e-6) and cart[1] <= 0.5 * (1 + 1e-6)
    assert hoist[0] <= 0.2 * (1 + 1e-6) and hoist[1] <= 0.4 * (1 + 1e-6) and hoist[2] <= 30.0 * (1 + 1e-6)
    binding = max([c / lim for c, lim in zip(cart[:2], (0.3, 0.5))] + [h / lim for h, lim in
                                                                         zip(hoist, (0.2, 0.4, 30.0))])
    assert binding > 1 - 1e-3  # the shortest: some limit binds
    # a fixed duration shorter than the hoist's own bound is refused naming the hoist's limit
    with pytest.raises(PlanError, match='max_hoist_velocity 0.2'):
        plan('nvf', 0.3, 0.9, NOMINAL, options, variational=SOLVERS, hoist=LIFT)


@pytest.mark.parametrize('hoist, words', [((0.47, -0.1), 'rope length must stay > 0'),
                                          ((0.0, 0.3), 'start length must be finite and > 0'),
                                          ((0.47,), 'start and goal rope lengths')])
def test_bad_hoists_are_refused_naming_why(hoist, words):
    with pytest.raises(PlanError, match=words):
        plan('zv', 0.3, 3.0, NOMINAL, hoist=hoist)


def test_the_indirect_route_refuses_a_hoist():
    with pytest.raises(PlanError, match='does not plan a hoist'):
        plan('nvf', 0.3, 3.0, NOMINAL, PlanOptions(solver='indirect'), hoist=LIFT)
