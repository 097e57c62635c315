"""Fastest plans under axis limits (Planner.fastest, shaped.fastest_shaped, --base limits), real CasADi/IPOPT.

Limits are checked here on a dense evaluation of each plan (2e5 samples),
independently of the planner's own checks; residual swing comes from
crane_sim's simulator.
"""
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from crane_msgs_py.crane.axes import AxisLimits
from crane_msgs_py.crane.params import CraneParams
from crane_planner.planning import METHODS, SHAPER_METHODS, PlanError, PlanOptions
from crane_planner.planning.model import modal_frequencies
from crane_planner.planning.profiles import limited_base, quintic_duration
from crane_planner.planning.shaped import fastest_shaped, shaped_plan
from crane_planner.planning.shapers import EI_TOLERANCE, design
from crane_planner.serving import Planner
from crane_planner.tools.evaluate import residual_load_mm, simulate_plan

PAPER = PlanOptions(max_velocity=0.25, max_acceleration=0.5)  # the paper's crane, D = 0.3 m
LIMITS = (0.25, 0.5, None)


def dense_peaks(plan, n=200_001):
    s = plan.evaluate(np.linspace(0.0, plan.duration, n))
    return np.abs(s.velocity).max(), np.abs(s.acceleration).max(), np.abs(s.jerk).max()


def ratios(plan, limits):
    return [p / lim for p, lim in zip(dense_peaks(plan), limits) if lim is not None]


@pytest.fixture(scope='module')
def planner():
    return Planner()


@pytest.mark.parametrize('method', METHODS)
def test_the_fastest_plan_is_within_the_limits_tight_and_leaves_no_swing(planner, method):
    plan = planner.fastest(method, 0.3, CraneParams(), PAPER)
    r = ratios(plan, LIMITS)
    assert max(r) <= 1.0 + 1e-6, r            # within every limit
    assert max(r) >= 0.995, r                 # and one of them active: T* is tight
    assert plan.evaluate(plan.duration).position[0] == pytest.approx(0.3, abs=1e-9)
    residual = residual_load_mm(simulate_plan(plan, CraneParams(), 10.0))[0]
    if method == 'ei':
        # EI is designed to leave EI_TOLERANCE (5 %) of the unshaped vibration at its design frequency:
        # here of its 0.67 s base alone (a ZV at 1000 rad/s is the quintic, 3 ms longer)
        unshaped = planner.plan('zv', 0.3, plan.base_duration + 0.0032, CraneParams(), PlanOptions(omega=(1e3, 1e3)))
        assert residual <= EI_TOLERANCE * 1.2 * residual_load_mm(simulate_plan(unshaped, CraneParams(), 10.0))[0]
    elif method == 'zv':
        # ZV at T* swings 0.06 rad: its linear design leaves 0.14 mm to the pendulum's softening at that
        # amplitude (README). The shaper itself is exact: the same move at 1/100 of D, where the crane is
        # linear, leaves (scaled back up) under 0.01 mm; the whole stays under 0.15 mm.
        small = shaped_plan('zv', 0.003, plan.duration, modal_frequencies(CraneParams()), 0.0)
        assert 100 * residual_load_mm(simulate_plan(small, CraneParams(), 10.0))[0] <= 0.01
        assert residual <= 0.15, residual
    else:
        assert residual <= 0.1, residual
    # 3 % faster the method cannot make it: refused, or (checked here) beyond a limit
    try:
        shorter = planner.plan(method, 0.3, 0.97 * plan.duration, CraneParams(), PlanOptions())
    except PlanError:
        return
    assert max(ratios(shorter, LIMITS)) > 1.0


@pytest.mark.parametrize('method', ['zv', 'zvd', 'mzv', 'zvdd'])
def test_the_limits_base_with_a_jerk_limit_leaves_no_swing(planner, method):
    """With a jerk limit the limits base's acceleration is continuous, so the 1 ms samples the plant is
    driven by do not blur its steps (without one ZV leaves 0.47 mm here, README): within every limit,
    no slower than the limits base plus the shaper, and under 0.1 mm on the nominal plant."""
    limits = (0.25, 0.5, 20.0)
    plan = planner.fastest(method, 0.3, CraneParams(), PlanOptions(max_velocity=0.25, max_acceleration=0.5,
                                                                    max_jerk=20.0, base='limits'))
    assert max(ratios(plan, limits)) <= 1.0 + 1e-9
    assert plan.base_duration == pytest.approx(limited_base(0.3, *limits).duration, rel=1e-12)
    assert residual_load_mm(simulate_plan(plan, CraneParams(), 10.0))[0] <= 0.1


@pytest.mark.parametrize('method', ['nvf', 'rvf'])
def test_a_jerk_limit_binds_nvf_and_rvf_as_a_path_constraint(planner, method):
    free = planner.plan(method, 0.3, 3.5, CraneParams(), PlanOptions())
    limit = 0.9 * dense_peaks(free)[2]  # 10 % below what the method takes without the limit
    bound = planner.plan(method, 0.3, 3.5, CraneParams(), PlanOptions(max_jerk=limit))
    assert dense_peaks(bound)[2] <= limit * (1 + 1e-6)
    assert residual_load_mm(simulate_plan(bound, CraneParams(), 10.0))[0] <= 0.1


def test_a_shaper_plan_beyond_a_jerk_limit_is_refused_naming_it(planner):
    with pytest.raises(PlanError, match='max_jerk 0.5'):
        planner.plan('zv', 0.3, 3.0, CraneParams(), PlanOptions(max_jerk=0.5))


POSITIVE = [m for m in SHAPER_METHODS if np.all(design(m, (3.6, 9.0), 0.0).amplitudes > 0)]


@settings(max_examples=25, deadline=None)
@given(st.sampled_from(POSITIVE), st.floats(0.01, 3.0), st.sampled_from([-1.0, 1.0]),
       st.floats(0.05, 2.0) | st.none(), st.floats(0.1, 5.0), st.floats(0.5, 50.0) | st.none())
def test_the_limits_base_is_never_slower_and_needs_no_check_with_positive_impulses(method, D, sign, v, a, j):
    """Property: on the jerk-limited time-optimal base the fastest shaped move is no slower than the
    shaper on the shortest quintic base within the same limits, and stays within them by construction."""
    omegas = modal_frequencies(CraneParams())
    limits = AxisLimits(v, a, j)
    plan = fastest_shaped(method, sign * D, omegas, 0.0, limits, base='limits')
    shaper = design(method, omegas, 0.0)
    assert plan.duration <= shaper.duration + quintic_duration(D, v, a, j) + 1e-9
    assert plan.base_duration == pytest.approx(limited_base(sign * D, v, a, j).duration, rel=1e-12)
    assert max(ratios(plan, limits)) <= 1.0 + 1e-9
    s = plan.evaluate(np.array([0.0, plan.duration]))
    assert s.position[-1] == pytest.approx(sign * D, abs=1e-12) and abs(s.velocity).max() < 1e-12


@pytest.mark.parametrize('method', ['nvf', 'rvf'])
def test_a_fastest_request_stops_at_max_solve_time_and_names_it(method):
    """The free-time attempts together stop at the budget (IPOPT is stopped between iterations),
    refused naming it; with a budget that allows it, the same request answers the same T*."""
    from crane_planner.planning.direct import DirectSolver
    tight = DirectSolver(method, PlanOptions(max_velocity=0.25, max_acceleration=0.5, max_solve_time=1e-3))
    with pytest.raises(PlanError, match=f'{method}: no fastest plan of 0.3 m within max_solve_time 0.001 s'):
        tight.fastest(0.3, CraneParams())
    roomy = DirectSolver(method, PlanOptions(max_velocity=0.25, max_acceleration=0.5, max_solve_time=5.0))
    plan = roomy.fastest(0.3, CraneParams())
    assert plan.duration == pytest.approx(Planner().fastest(method, 0.3, CraneParams(), PAPER).duration, rel=1e-6)
    assert max(ratios(plan, LIMITS)) >= 0.995


def test_the_fastest_needs_a_velocity_or_acceleration_limit(planner):
    for method in ('zv', 'nvf'):
        with pytest.raises(PlanError, match='needs max_velocity or max_acceleration'):
            planner.fastest(method, 0.3, CraneParams(), PlanOptions(max_jerk=2.0))
