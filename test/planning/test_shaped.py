"""Shaped plans: the quintic base, rest-to-rest kinematics, paper §4 numbers, zero swing on the linear crane."""
import json
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from crane_msgs_py.crane.params import CraneParams
from crane_planner.planning import PlanOptions
from crane_planner.planning.model import linearized_matrices, modal_frequencies
from crane_planner.planning.plan import PlanError
from crane_planner.planning.profiles import quintic
from crane_planner.planning.shaped import shaped_plan
from crane_planner.serving import Planner

PAPER_OMEGAS = (3.640, 9.017)  # Table 1, rad/s
POSITIVE = ('zv', 'zvd', 'ei', 'mzv', 'zvdd')
METHODS = POSITIVE + ('nzv',)


def plan_for(method, D=0.3, T=3.0, omegas=PAPER_OMEGAS, zeta=0.0):
    # ZVDD is three half periods per mode long (3.63 s): give it room
    return shaped_plan(method, D, T + (1.5 if method == 'zvdd' else 0.0), omegas, zeta)


def test_quintic_is_the_rest_to_rest_quintic():
    # the unique degree-5 polynomial with p, v, a = (0, 0, 0) at 0 and (D, 0, 0) at T
    D, T = -0.7, 1.3
    basis = np.polynomial.Polynomial.basis
    rows = [[basis(k).deriv(n)(tt) for k in range(6)] for tt in (0.0, T) for n in range(3)]
    c = np.linalg.solve(rows, [0, 0, 0, D, 0, 0])
    P = np.polynomial.Polynomial(c)
    t = np.linspace(0.0, T, 101)[:-1]  # jerk is taken right-continuous, so T itself is at rest
    for got, ref in zip(quintic(t, D, T), (P(t), P.deriv()(t), P.deriv(2)(t), P.deriv(3)(t))):
        np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-12 * abs(D) / T**3)


def test_quintic_at_rest_outside():
    p, v, a, j = quintic(np.array([-1.0, 0.0, 2.0, 5.0]), 0.3, 2.0)
    np.testing.assert_array_equal(p, [0.0, 0.0, 0.3, 0.3])
    np.testing.assert_array_equal(v, 0.0)
    np.testing.assert_array_equal(a, 0.0)
    np.testing.assert_array_equal(j, [0.0, 60 * 0.3 / 8, 0.0, 0.0])


def test_paper_base_durations():
    """Paper §4: for T = 3 s the quintic lasts 1.789 s under ZV and 2.192 s under NZV."""
    assert shaped_plan('zv', 0.3, 3.0, PAPER_OMEGAS, 0.0).info['base_duration'] == pytest.approx(1.789, abs=1e-3)
    assert shaped_plan('nzv', 0.3, 3.0, PAPER_OMEGAS, 0.0).info['base_duration'] == pytest.approx(2.192, abs=1e-3)


@pytest.mark.parametrize('zeta', [0.0, 0.1])
@pytest.mark.parametrize('method', METHODS)
def test_plan_is_the_sum_of_shifted_quintics(method, zeta):
    # the definition, summed term by term (the plan re-expands it piece by piece)
    plan = plan_for(method, D=0.45, zeta=zeta)
    t = np.linspace(-0.5, plan.duration + 0.5, 2001)
    kinks = np.concatenate((plan.shaper.times, plan.shaper.times + plan.base_duration))
    t = t[np.min(np.abs(t[:, None] - kinks), axis=1) > 1e-9]  # jerk jumps there
    terms = [quintic(t - ti, 0.45, plan.base_duration) for ti in plan.shaper.times]
    got = plan.evaluate(t)
    for n, name in enumerate(('position', 'velocity', 'acceleration', 'jerk')):
        ref = sum(A * q[n] for A, q in zip(plan.shaper.amplitudes, terms))
        np.testing.assert_allclose(getattr(got, name), ref, rtol=0, atol=1e-13 * np.max(np.abs(ref)), err_msg=name)


@pytest.mark.parametrize('method', METHODS)
def test_info_describes_the_impulses(method):
    plan = plan_for(method)
    info = json.loads(json.dumps(plan.info))
    assert info['shaper_duration'] + info['base_duration'] == pytest.approx(plan.duration, abs=1e-15)
    assert info['impulse_times'][0] == 0.0 and info['impulse_times'][-1] == info['shaper_duration']
    assert sum(info['impulse_amplitudes']) == pytest.approx(1.0, abs=1e-14)
    # two modes, one shaper each: (number of impulses per mode)^2 impulses
    assert len(info['impulse_times']) == {'zv': 4, 'zvdd': 16}.get(method, 9)


@pytest.mark.parametrize('zeta', [0.0, 0.05, 0.2])
@pytest.mark.parametrize('method', METHODS)
@pytest.mark.parametrize('D', [0.3, -1.2])
def test_rest_to_rest(method, zeta, D):
    plan = plan_for(method, D=D, zeta=zeta)
    T = plan.duration
    s = plan.evaluate([0.0, T])
    np.testing.assert_allclose(s.position, [0.0, D], rtol=1e-13, atol=0.0)
    np.testing.assert_allclose(s.velocity, 0.0, atol=1e-15)
    np.testing.assert_allclose(s.acceleration, 0.0, atol=1e-14)
    # the last shifted quintic is still moving until T: D is not reached early
    before = plan.evaluate(T - 1e-2).position[0]
    assert abs(before - D) > 1e-9 * abs(D)
    assert plan.evaluate(T + 1.0).position[0] == D


@pytest.mark.parametrize('method', POSITIVE)
def test_positive_shapers_are_monotone(method):
    for D in (0.3, -0.3):
        s = plan_for(method, D=D, zeta=0.1).sample(1e-3)
        assert np.all(np.sign(D) * s.velocity >= -1e-15)
        assert np.all(np.sign(D) * np.diff(s.position) >= -1e-15)


@pytest.mark.parametrize('method', METHODS)
def test_derivatives_match_finite_differences(method):
    plan = plan_for(method, zeta=0.05)
    h = 1e-5
    t = np.linspace(0.0, plan.duration, 997)[1:-1]
    # jerk jumps where a shifted quintic starts or ends: keep away from those instants
    kinks = np.concatenate((plan.shaper.times, plan.shaper.times + plan.base_duration))
    t = t[np.min(np.abs(t[:, None] - kinks), axis=1) > 2 * h]
    lo, mid, hi = plan.evaluate(t - h), plan.evaluate(t), plan.evaluate(t + h)
    scale = {n: np.max(np.abs(getattr(mid, n))) for n in ('velocity', 'acceleration', 'jerk')}
    for f, df in (('position', 'velocity'), ('velocity', 'acceleration'), ('acceleration', 'jerk')):
        fd = (getattr(hi, f) - getattr(lo, f)) / (2 * h)
        np.testing.assert_allclose(fd, getattr(mid, df), atol=1e-6 * scale[df], err_msg=df)


@pytest.mark.parametrize('method', METHODS)
def test_duration_not_longer_than_the_shaper_is_refused(method):
    length = plan_for(method).shaper.duration
    for T in (length, 0.9 * length):
        with pytest.raises(PlanError, match=rf'{method} .*\({length:.3f} s\).*got {T}'):
            shaped_plan(method, 0.3, T, PAPER_OMEGAS, 0.0)
    with pytest.raises(PlanError, match=method):
        Planner().plan(method, 0.3, 0.9 * length, options=PlanOptions(omega=PAPER_OMEGAS))


@pytest.mark.parametrize('method', ['zv', 'zvd', 'ei', 'mzv'])
def test_axis_limits_of_positive_shapers_against_the_quintic_bounds(method):
    """A shaper with positive amplitudes summing to 1 averages shifted copies of the
    quintic (length Tq): its peaks lie between the mean (D/T, 4 D/T^2 for a rest-to-rest
    move) and the quintic's (15/8 D/Tq, 10/sqrt(3) D/Tq^2)."""
    D, T = 0.3, 4.0
    shaper = plan_for(method).shaper
    Tq = T - shaper.duration
    v_quintic, a_quintic = 15.0 / 8.0 * D / Tq, 10.0 / math.sqrt(3.0) * D / Tq ** 2
    options = PlanOptions(omega=PAPER_OMEGAS, max_velocity=v_quintic, max_acceleration=a_quintic)
    Planner().plan(method, D, T, options=options)  # within both
    for limits, named in ((dict(max_velocity=D / T), 'max_velocity'),
                          (dict(max_acceleration=4 * D / T ** 2), 'max_acceleration')):
        with pytest.raises(PlanError, match=rf'{method} plan exceeds {named}'):
            Planner().plan(method, D, T, options=PlanOptions(omega=PAPER_OMEGAS, **limits))


def test_facade_uses_model_frequencies():
    params = CraneParams()
    plan = Planner().plan('zvd', 0.3, 3.0, params)
    np.testing.assert_allclose(plan.info['omegas'], modal_frequencies(params), rtol=1e-15)
    # ZVD lasts one period per mode
    assert plan.shaper.duration == pytest.approx(sum(2 * math.pi / w for w in modal_frequencies(params)), rel=1e-14)


def linear_crane_residual(acceleration, duration, kinks, params):
    """Peak free swing (theta1, theta2) of the linearized crane after a motion ends.

    Integrates M q'' + K q = b a(t) (Eqs. 18-19 linearized, ideal servo)
    piecewise between the ``kinks`` where the jerk jumps, then splits the
    state at ``duration`` into normal modes: the peak over the free motion is
    the sum of the modal amplitudes times the mode shapes.
    """
    M, K, b = linearized_matrices(params)
    MK, Mb = np.linalg.solve(M, K), np.linalg.solve(M, b)

    def rhs(t, x):
        return np.concatenate((x[2:], Mb * acceleration(t) - MK @ x[:2]))

    edges = np.unique(np.clip(np.concatenate(([0.0, duration], kinks)), 0.0, duration))
    x = np.zeros(4)
    for t0, t1 in zip(edges[:-1], edges[1:]):
        x = solve_ivp(rhs, (t0, t1), x, method='DOP853', rtol=1e-12, atol=1e-14).y[:, -1]
    lam, phi = np.linalg.eig(MK)
    eta, deta = np.linalg.solve(phi, x[:2]), np.linalg.solve(phi, x[2:])
    return np.abs(phi) @ np.hypot(eta, deta / np.sqrt(lam.real))


def swings(plan, params):
    """Residual swing of ``plan`` and of its base quintic alone (unshaped), on the linear crane."""
    starts = plan.shaper.times
    shaped = linear_crane_residual(lambda t: plan.evaluate(t).acceleration[0], plan.duration,
                                   np.concatenate((starts, starts + plan.base_duration)), params)
    unshaped = linear_crane_residual(lambda t: quintic(t, plan.displacement, plan.base_duration)[2],
                                     plan.base_duration, [], params)
    return shaped, unshaped


@pytest.mark.parametrize('method', ('zv', 'nzv', 'zvd', 'mzv', 'zvdd'))
def test_zero_residual_swing_on_the_linear_crane(method):
    params = CraneParams(tau=0.0)
    plan = plan_for(method, omegas=modal_frequencies(params))
    shaped, unshaped = swings(plan, params)
    assert np.all(shaped < 1e-6)
    assert np.all(unshaped > 1e-3)  # what the shaper removed: the base motion alone swings


def test_ei_residual_swing_on_the_linear_crane_bounded_by_V():
    params = CraneParams(tau=0.0)
    plan = plan_for('ei', omegas=modal_frequencies(params))
    shaped, unshaped = swings(plan, params)
    assert np.all(shaped <= 0.05 * unshaped)
    assert np.all(shaped > 1e-4 * unshaped)  # EI trades exact cancellation for insensitivity
