"""NVF and RVF by the direct solver (crane_planner.planning.direct), judged by physics and the independent simulator.

The simulator (crane_sim) integrates its own implementation of Eqs. 18-19 and
the servo; residual load swing is the contract's metric (crane_sim.metrics).
"""
import threading
import time

import numpy as np
import pytest

from crane_msgs_py.crane.params import CraneParams
from crane_planner.planning import PlanOptions
from crane_planner.planning.direct import DirectSolver
from crane_planner.planning.plan import PlanError
from crane_planner.planning.problem import Weights
from crane_sim.metrics import swing_metrics
from crane_sim.simulator import simulate

MODEL = CraneParams()              # Table 1, tau = 0.01 s
IDEAL = CraneParams(tau=0.0)       # the nominal plant with ideal tracking
D = 0.3


@pytest.fixture(scope='module')
def solver():
    """One solver per method, shared so each NLP is built once for the whole file."""
    cache = {}

    def get(method, **options):
        key = (method, tuple(sorted(options.items())))
        if key not in cache:
            cache[key] = DirectSolver(method, PlanOptions(**options))
        return cache[key]
    return get


def residual_mm(plan, plants, settle=4.0):
    """Residual load excursion (mm) of each plant driven by the plan's 1 ms acceleration samples."""
    s = plan.sample(1e-3)
    result = simulate(s.t, s.acceleration, plants, dt=1e-3, t_end=plan.duration + settle,
                      interpolation='linear')
    return np.array([m['residual']['load_mm'] for m in swing_metrics(result, plants, plan.duration, settle)])


def peaks(plan):
    s = plan.sample(1e-4)
    return np.array([np.abs(x).max() for x in (s.velocity, s.acceleration, s.jerk)])


@pytest.mark.parametrize('method', ['nvf', 'rvf'])
@pytest.mark.parametrize('params', [IDEAL, MODEL], ids=['tau0', 'tau0.01'])
def test_rest_to_rest(solver, method, params):
    plan = solver(method).solve(D, 3.0, params)
    ends = plan.evaluate([0.0, 3.0])
    np.testing.assert_allclose(ends.position, [0.0, D], atol=1e-12)
    np.testing.assert_allclose(ends.velocity, 0.0, atol=1e-12)
    np.testing.assert_allclose(ends.acceleration, 0.0, atol=1e-12)
    # the reference acceleration is continuous: no step at the ends even with the servo
    near = plan.evaluate([1e-5, 3.0 - 1e-5])
    assert np.all(np.abs(near.acceleration) < 1e-5 * peaks(plan)[2] * 1.01)
    assert plan.info['status'] in ('Solve_Succeeded', 'Solved_To_Acceptable_Level')
    for key in ('iterations', 'solve_time_s', 'build_time_s', 'objective', 'intervals', 'robust', 'solver'):
        assert key in plan.info


@pytest.mark.parametrize('method', ['nvf', 'rvf'])
def test_samples_are_one_continuous_trajectory(solver, method):
    """Velocity is the derivative of position and acceleration that of velocity, across the
    mesh intervals too (no jumps where the polynomials meet)."""
    plan = solver(method).solve(D, 3.0, MODEL)
    t = np.linspace(0.0, 3.0, 300001)
    s = plan.evaluate(t)
    for f, df in ((s.position, s.velocity), (s.velocity, s.acceleration)):
        numeric = np.gradient(f, t)
        assert np.abs(numeric - df)[1:-1].max() < 1e-6 * np.abs(df).max()
    numeric = np.gradient(s.acceleration, t)
    assert np.median(np.abs(numeric - s.jerk)) < 1e-6 * np.abs(s.jerk).max()


def test_displacement_sign_mirrors_the_plan(solver):
    """The crane is odd-symmetric, so the plan for -D is minus the plan for D."""
    s = solver('rvf')
    t = np.linspace(0, 2.5, 501)
    up = s.solve(0.4, 2.5, MODEL).evaluate(t)
    down = s.solve(-0.4, 2.5, MODEL).evaluate(t)  # warm-started from the mirrored solution
    for name in ('position', 'velocity', 'acceleration', 'jerk'):
        np.testing.assert_allclose(getattr(down, name), -getattr(up, name), atol=1e-9 * np.abs(getattr(up, name)).max())


@pytest.mark.parametrize('method', ['nvf', 'rvf'])
def test_ideal_tracking_plan_is_time_symmetric(solver, method):
    """With tau = 0 the plant is time-reversible (theta -> -theta, a -> -a under t -> T - t) and the
    cost and end conditions are symmetric, so v(T - t) = v(t)."""
    plan = solver(method).solve(D, 3.0, IDEAL)
    t = np.linspace(0, 3.0, 601)
    v, vr = plan.evaluate(t).velocity, plan.evaluate(3.0 - t).velocity
    np.testing.assert_allclose(vr, v, atol=1e-5 * np.abs(v).max())


@pytest.mark.parametrize('method', ['nvf', 'rvf'])
@pytest.mark.parametrize('duration', [3.0, 2.5])
def test_doubling_intervals_changes_peaks_below_0p1_percent(solver, method, duration):
    default = solver(method).solve(D, duration, MODEL)
    double = solver(method, intervals=2 * default.info['intervals']).solve(D, duration, MODEL)
    np.testing.assert_allclose(peaks(default), peaks(double), rtol=1e-3)


@pytest.mark.parametrize('method', ['nvf', 'rvf'])
@pytest.mark.parametrize('duration', [3.0, 2.5])
def test_nominal_plant_has_no_residual_swing(solver, method, duration):
    plan = solver(method).solve(D, duration, IDEAL)
    assert residual_mm(plan, [IDEAL])[0] < 0.05


@pytest.mark.parametrize('duration', [2.5, 3.0])
def test_rvf_is_robust_to_L1(solver, duration):
    """Paper §5.2 (L1 shortened to 0.42 m) and §4.1 (L1 within +-30 %)."""
    nvf = solver('nvf').solve(D, duration, MODEL)
    rvf = solver('rvf').solve(D, duration, MODEL)
    scale = np.round(np.arange(0.70, 1.301, 0.05), 2)
    plants = [MODEL.replace(L1=0.42)] + [MODEL.replace(L1=MODEL.L1 * k) for k in scale]
    r_nvf, r_rvf = residual_mm(nvf, plants), residual_mm(rvf, plants)
    assert r_rvf[0] <= 0.5 * r_nvf[0]
    off = np.abs(scale - 1.0) >= 0.05 - 1e-9
    assert np.all(r_rvf[1:][off] < r_nvf[1:][off])
    assert r_nvf[1:][off].min() > 0.5  # NVF does swing there: the comparison means something


def test_rvf_insensitive_to_L1_is_insensitive_to_L2_and_masses(solver):
    """About rest, L1, L2 and m2/(m1+m2) all act through the two modal frequencies
    (dynamics.carried_parameters): robustness to one is robustness to the others."""
    nvf = solver('nvf').solve(D, 3.0, MODEL)
    rvf = solver('rvf').solve(D, 3.0, MODEL)  # robust to L1
    plants = [MODEL.replace(L2=MODEL.L2 * k) for k in (0.8, 1.2)] + [MODEL.replace(m2=MODEL.m2 * k) for k in (0.8, 1.2)]
    assert np.all(residual_mm(rvf, plants) < 0.3 * residual_mm(nvf, plants))


def test_rvf_robust_to_tau(solver):
    model = CraneParams(tau=0.05)
    nvf = solver('nvf').solve(D, 2.5, model)
    rvf = solver('rvf', robust=('tau',)).solve(D, 2.5, model)
    plants = [model.replace(tau=t) for t in (0.02, 0.03, 0.07, 0.08)]
    assert np.all(residual_mm(rvf, plants) < 0.6 * residual_mm(nvf, plants))


def test_robust_tau_needs_a_servo_model(solver):
    with pytest.raises(PlanError, match='tau > 0'):
        solver('rvf', robust=('tau',)).solve(D, 3.0, IDEAL)


def test_servo_aware_plan(solver):
    """T = 1.5 s on a plant with tau = 0.05 s: planning with the servo removes the lag's swing."""
    plant = CraneParams(tau=0.05)
    aware = solver('nvf').solve(D, 1.5, plant)
    unaware = solver('nvf').solve(D, 1.5, IDEAL)
    r_aware, r_unaware = residual_mm(aware, [plant])[0], residual_mm(unaware, [plant])[0]
    assert r_aware < 0.5 * r_unaware
    assert r_aware < 0.1


def test_sensitivity_weight_trades_peaks_for_robustness(solver):
    """Paper §4.1: penalizing the sensitivities lowers the overall sensitivity at the cost of
    higher peak acceleration and jerk."""
    plain = solver('rvf').solve(D, 3.0, MODEL)
    weighted = DirectSolver('rvf', PlanOptions(), weights=Weights(sensitivity=1e4)).solve(D, 3.0, MODEL)
    plants = [MODEL.replace(L1=MODEL.L1 * k) for k in (0.7, 0.8, 0.9, 1.1, 1.2, 1.3)]
    assert residual_mm(weighted, plants).mean() < 0.9 * residual_mm(plain, plants).mean()
    assert np.all(peaks(weighted)[1:] > peaks(plain)[1:])


def test_warm_start_and_reuse(solver):
    s = solver('nvf')
    first = s.solve(0.25, 2.8, MODEL)
    again = s.solve(0.25, 2.8, MODEL)
    assert again.info['build_time_s'] == 0.0
    assert again.info['iterations'] <= 1
    t = np.linspace(0, 2.8, 300)
    np.testing.assert_allclose(again.evaluate(t).position, first.evaluate(t).position, atol=1e-10)


def test_concurrent_solves_are_serialized_and_correct(solver):
    s = solver('nvf')
    requests = [(0.1 * k, 2.0 + 0.25 * k) for k in range(1, 5)]
    expected = {r: s.solve(*r, MODEL).evaluate(np.linspace(0, r[1], 50)).position for r in requests}
    results, errors = {}, []

    def work(r):
        try:
            results[r] = s.solve(*r, MODEL).evaluate(np.linspace(0, r[1], 50)).position
        except Exception as e:  # noqa: BLE001 - reported below
            errors.append(e)
    threads = [threading.Thread(target=work, args=(r,)) for r in requests * 2]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    assert not errors
    for r in requests:
        np.testing.assert_allclose(results[r], expected[r], atol=1e-8)


def test_not_converged_is_an_error_naming_the_status():
    s = DirectSolver('nvf', PlanOptions(), max_iter=1)
    with pytest.raises(PlanError, match='Maximum_Iterations_Exceeded'):
        s.solve(D, 2.5, MODEL)


def test_without_a_budget_the_solve_is_capped_by_its_own_cpu_time_not_the_hosts_load():
    """No max_solve_time: IPOPT stops at max_cpu_time of the solver's own work, and says so; a busy
    host (a wall-time cap) would otherwise turn a slow proof of infeasibility into a different error."""
    s = DirectSolver('nvf', PlanOptions())
    s.max_cpu_time = 0.2
    cpu = time.process_time()
    with pytest.raises(PlanError, match=r"nvf: no plan for D=10 m, T=0.5 s within the solver's cap of 0.2 s "
                                        r'of CPU time \(IPOPT stopped after \d+ iterations\)'):
        s.solve(10.0, 0.5, MODEL)
    assert time.process_time() - cpu >= 0.2


@pytest.mark.parametrize('limit,value', [('max_velocity', 0.16), ('max_acceleration', 0.18)])
def test_axis_limit_holds_everywhere(limit, value):
    s = DirectSolver('nvf', PlanOptions(**{limit: value}))
    plan = s.solve(D, 3.0, MODEL)
    free = DirectSolver('nvf', PlanOptions()).solve(D, 3.0, MODEL)
    i = 0 if limit == 'max_velocity' else 1
    assert peaks(free)[i] > value  # the limit binds
    assert peaks(plan)[i] <= value
    assert peaks(plan)[i] >= value * 0.999
    assert residual_mm(plan, [MODEL])[0] < 0.05


@pytest.mark.parametrize('limits,named', [
    (dict(max_velocity=0.09), 'max_velocity'),                          # needs more than D/T
    (dict(max_acceleration=0.12), 'max_acceleration'),                  # needs more than 4 D/T^2
    (dict(max_velocity=0.12, max_acceleration=0.2), 'max_velocity 0.12 m/s and max_acceleration'),
    (dict(max_acceleration=0.135), 'max_acceleration 0.135'),           # bang-bang bound passes, IPOPT refuses
])
def test_infeasible_limits_are_errors_naming_the_limit(limits, named):
    with pytest.raises(PlanError, match=named):
        DirectSolver('nvf', PlanOptions(**limits)).solve(D, 3.0, IDEAL)
