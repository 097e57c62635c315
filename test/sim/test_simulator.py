"""crane_sim.simulator against closed forms: servo (Eq. 6), linearized modes, equilibria, interpolation."""
import math

import numpy as np
import pytest
import scipy.linalg
from references import lagrangian_energy, lagrangian_linearization

from crane_msgs_py.crane.params import CraneParams, ParameterError
from crane_planner.planning.model import modal_frequencies
from crane_planner.planning.profiles import quintic
from crane_sim.simulator import CraneSimulator, CraneState, SimulationError, simulate

P = CraneParams()


def zero_crossing_frequency(t, x):
    """Angular frequency from a least-squares line through the zero-crossing times (linear interpolation)."""
    i = np.nonzero(np.signbit(x[:-1]) != np.signbit(x[1:]))[0]
    tc = t[i] - x[i] * (t[i + 1] - t[i]) / (x[i + 1] - x[i])
    half_period = np.polyfit(np.arange(tc.size), tc, 1)[0]
    return math.pi / half_period


def test_small_angle_modes_match_the_linearization():
    """Free response started on each linear mode shape swings at that mode's frequency (0.1 %)."""
    M, K = lagrangian_linearization(P)  # written independently of the code under test
    lam, shapes = scipy.linalg.eigh(K, M)
    omega = np.sqrt(lam)
    assert omega == pytest.approx(modal_frequencies(P), rel=1e-9)  # two independent linearizations agree

    amplitude = 1e-3  # rad: nonlinear frequency shift ~ amplitude^2, far below 0.1 %
    starts = np.zeros((2, 7))
    for i in range(2):
        starts[i, 3:5] = amplitude * shapes[:, i] / np.abs(shapes[:, i]).max()
    r = simulate([0.0, 12.0], [0.0, 0.0], [P, P], dt=1e-3, record_every=2, initial_state=starts)
    for i in range(2):
        for x in (r.theta1[i], r.theta2[i]):
            assert zero_crossing_frequency(r.t, x) == pytest.approx(omega[i], rel=1e-3)
    # a pure mode keeps its shape: theta2 / theta1 stays the eigenvector ratio
    ratio = shapes[1, 0] / shapes[0, 0]
    big = np.abs(r.theta1[0]) > 0.5 * np.abs(r.theta1[0]).max()
    assert r.theta2[0][big] / r.theta1[0][big] == pytest.approx(ratio, rel=1e-3)


def servo_step_response(t, A, tau):
    """Cart a, v, y after a step of a_ref to A at t = 0 from rest (Eq. 6 in closed form)."""
    if tau == 0.0:
        return A * np.ones_like(t), A * t, A * t**2 / 2
    e = -np.expm1(-t / tau)
    return A * e, A * (t - tau * e), A * (t**2 / 2 - tau * t + tau**2 * e)


def servo_ramp_response(t, c, tau):
    """Cart a, v, y for a_ref = c t from t = 0 (rest before)."""
    if tau == 0.0:
        return c * t, c * t**2 / 2, c * t**3 / 6
    e = -np.expm1(-t / tau)
    return (c * (t - tau * e), c * (t**2 / 2 - tau * t + tau**2 * e),
            c * (t**3 / 6 - tau * t**2 / 2 + tau**2 * t - tau**3 * e))


TAUS = [0.01, 1e-4, 0.0, 0.5]


def test_servo_step_matches_closed_form_for_any_tau():
    """tau = 0.01, tau = 1e-4 < dt (no blow-up), tau = 0 (a = a_ref exactly), slow tau = 0.5."""
    A = 2.0
    plants = [P.replace(tau=tau) for tau in TAUS]
    r = simulate([-0.5, 0.0], [0.0, A], plants, dt=1e-3, t_end=2.0, interpolation='zoh')
    after = r.t > 1e-9
    t = r.t[after]
    for i, tau in enumerate(TAUS):
        a, v, y = servo_step_response(t, A, tau)
        assert np.all(r.a[i, ~after] == 0.0) and np.all(r.y[i, ~after] == 0.0)
        assert r.a[i, after] == pytest.approx(a, abs=1e-12)
        assert r.v[i, after] == pytest.approx(v, abs=1e-12)
        assert r.y[i, after] == pytest.approx(y, abs=1e-12)
    assert np.all(r.a[2, after] == A)   # tau = 0: the reference itself


def test_servo_ramp_matches_closed_form_with_linear_interpolation():
    c = 1.5
    plants = [P.replace(tau=tau) for tau in TAUS]
    r = simulate([-0.5, 0.0, 3.0], [0.0, 0.0, 3.0 * c], plants, dt=1e-3, t_end=2.0, interpolation='linear')
    t = np.maximum(r.t, 0.0)
    for i, tau in enumerate(TAUS):
        a, v, y = servo_ramp_response(t, c, tau)
        assert r.a[i] == pytest.approx(a, abs=1e-12)
        assert r.v[i] == pytest.approx(v, abs=1e-12)
        assert r.y[i] == pytest.approx(y, abs=1e-12)


def test_zoh_and_linear_interpolation_of_a_ramp():
    """Acceleration samples c t_k every 0.1 s: 'linear' integrates c t^3/6 exactly,
    'zoh' the staircase, y(t_k) = c H^3 (k-1) k (2k-1) / 12."""
    c, H = 2.0, 0.1
    t_ref = H * np.arange(11)
    plant = P.replace(tau=0.0)
    lin = simulate(t_ref, c * t_ref, plant, interpolation='linear')
    zoh = simulate(t_ref, c * t_ref, plant, interpolation='zoh')
    assert lin.y[0] == pytest.approx(c * lin.t**3 / 6, abs=1e-13)
    on_knot = np.isclose(zoh.t / H, np.rint(zoh.t / H), atol=1e-9)
    k = np.rint(zoh.t[on_knot] / H)
    assert k.size == 11
    assert zoh.y[0, on_knot] == pytest.approx(c * H**3 * (k - 1) * k * (2 * k - 1) / 12, abs=1e-13)
    assert zoh.v[0, on_knot] == pytest.approx(c * H**2 * k * (k - 1) / 2, abs=1e-13)


def test_position_source_recovers_the_acceleration_of_a_quintic():
    """Positions every 10 ms of a rest-to-rest quintic: the reconstructed acceleration is the
    quintic's, one sample late (a causal controller), and the cart stops exactly at D."""
    D, T, H = 0.3, 3.0, 0.01
    jerk_jump = 60.0 * D / T**3          # the quintic's jerk steps at both ends
    t_ref = H * np.arange(round(T / H) + 1)
    p_ref = quintic(t_ref, D, T)[0]
    plant = P.replace(tau=0.0)
    for interpolation in ('linear', 'zoh'):
        r = simulate(t_ref, 0.1 + p_ref, plant, t_end=T + 1.0, source='position', interpolation=interpolation)
        assert r.y[0, 0] == 0.1
        assert r.y[0, -1] == pytest.approx(0.1 + D, abs=1e-12)
        assert r.v[0, -1] == pytest.approx(0.0, abs=1e-12)
        delay = H if interpolation == 'linear' else 1.5 * H   # zoh holds each sample a further half interval
        error = np.abs(r.a[0] - quintic(r.t - delay, D, T)[2])
        if interpolation == 'linear':
            # inside: second difference H^2/12 p plus linear interpolation H^2/8 p;
            # across the jerk step at the ends it is off by ~ jerk_jump H / 6
            interior = (r.t > 3 * H) & (r.t < T - 2 * H)
            assert error[interior].max() < 1.01 * (1 / 12 + 1 / 8) * H**2 * 360.0 * D / T**4
            assert error.max() < jerk_jump * H / 4
            assert r.y[0] == pytest.approx(0.1 + quintic(r.t - H, D, T)[0], abs=1e-5)
        else:
            assert error.max() < jerk_jump * H / 2 + 1e-4


def test_constant_acceleration_static_deflection_is_an_equilibrium():
    """Held cart acceleration a0: tan(theta1) = a0 / g, theta2 = 0 stays put."""
    a0 = 2.5
    th_eq = math.atan(a0 / P.g)
    starts = [[0.0, 0.0, a0, th_eq, 0.0, 0.0, 0.0],
              [0.0, 0.0, a0, 0.0, 0.0, 0.0, 0.0]]
    r = simulate([0.0, 3.0], [a0, a0], [P, P], initial_state=starts)
    assert np.abs(r.theta1[0] - th_eq).max() < 1e-12
    assert np.abs(r.theta2[0]).max() < 1e-12
    assert r.y[0, -1] == pytest.approx(a0 * 9.0 / 2, rel=1e-12)
    # started hanging straight instead, it swings about the deflected equilibrium (lagging)
    assert r.theta1[1].max() > th_eq and r.theta1[1].min() == 0.0


def test_batch_equals_members_run_one_by_one():
    t_ref = np.linspace(0.0, 2.0, 201)
    acc = quintic(t_ref, 0.3, 2.0)[2]
    plants = [P, P.replace(L1=0.35, tau=0.0), P.replace(m2=0.5, L2=0.6, tau=0.05)]
    refs = np.stack([acc, 1.3 * acc, -acc])
    batch = simulate(t_ref, refs, plants, t_end=2.5, record_every=7)
    for i, p in enumerate(plants):
        one = simulate(t_ref, refs[i], p, t_end=2.5, record_every=7)
        assert np.array_equal(one.t, batch.t)
        for name in ('y', 'v', 'a', 'theta1', 'theta2', 'dtheta1', 'dtheta2'):
            assert getattr(batch, name)[i] == pytest.approx(getattr(one, name)[0], rel=1e-12, abs=1e-15)
    assert batch.t[-1] == pytest.approx(2.5) and batch.load_excursion.shape == batch.y.shape
    # one plant, several references: the plant is repeated
    rep = simulate(t_ref, refs, P, t_end=1.0)
    assert rep.theta1.shape[0] == 3 and rep.theta1[2] == pytest.approx(-rep.theta1[0], abs=1e-15)


def test_streaming_simulator_follows_the_batch_path():
    t_ref = np.linspace(0.0, 1.0, 101)
    acc = quintic(t_ref, 0.2, 1.0)[2]
    r = simulate(t_ref, acc, P, t_end=1.5, interpolation='linear')
    sim = CraneSimulator(P, dt=1e-3)
    a_grid = np.interp(r.t, t_ref, acc)
    for k in range(r.t.size - 1):
        sim.step(a_grid[k], a_grid[k + 1])
    s = sim.state
    assert sim.t == pytest.approx(r.t[-1])
    for name in ('y', 'v', 'a', 'theta1', 'theta2', 'dtheta1', 'dtheta2'):
        assert getattr(s, name) == pytest.approx(getattr(r, name)[0, -1], rel=1e-12, abs=1e-15)
    assert sim.load_excursion == pytest.approx(r.load_excursion[0, -1], rel=1e-12)
    positions, velocities = sim.joint_state()
    assert positions == [s.y, s.theta1, s.theta2] and velocities == [s.v, s.dtheta1, s.dtheta2]


def test_streaming_set_params_keeps_state_and_reset():
    sim = CraneSimulator(P.replace(tau=0.0))
    for _ in range(100):
        sim.step(1.0)
    before = sim.state
    sim.set_params(P.replace(L1=0.3, tau=0.02))
    assert sim.state == before and sim.params['L1'] == 0.3
    sim.step(0.0)   # new tau: a decays from 1 towards 0 with tau = 0.02
    assert sim.state.a == pytest.approx(math.exp(-1e-3 / 0.02), rel=1e-12)
    sim.reset(CraneState(y=0.5))
    assert sim.state == CraneState(y=0.5) and sim.t == 0.0
    with pytest.raises(ParameterError, match='tau'):
        sim.set_params(P.replace(tau=0.0).as_dict() | {'tau': -1.0})
    with pytest.raises(SimulationError, match='finite'):
        sim.step(float('nan'))


def test_rest_steps_after_the_reference_keep_the_free_swing():
    """After the last reference sample the input holds: ``rest_dt`` steps the free swing 5x coarser.

    A 0.3 m quintic in 1 s (it leaves a large swing) observed for 6 s more: the grid is 1 ms up
    to the end of the reference, then 5 ms; the swing agrees with the all-1 ms run at the common
    times to 1e-5 of each signal's peak (RK4's global error grows as h^4: ~3e-6 here, 1e-4 mm of
    load), and the free swing's energy (the cart at rest at its goal) stays constant.
    """
    t = np.linspace(0.0, 1.0, 1001)
    acc = quintic(t, 0.3, 1.0)[2]
    fine = simulate(t, acc, P, dt=1e-3, t_end=7.0, rest_dt=None)
    coarse = simulate(t, acc, P, dt=1e-3, t_end=7.0, rest_dt=5e-3)
    steps = np.diff(coarse.t)
    assert np.allclose(steps[:1000], 1e-3) and np.allclose(steps[1000:], 5e-3) and coarse.t[-1] >= 7.0 - 1e-9
    common = np.searchsorted(fine.t, coarse.t - 1e-9)
    assert np.allclose(fine.t[common], coarse.t, atol=1e-9)
    assert np.abs(fine.theta1[0, -1]) > 0.01  # it still swings
    for name in ('theta1', 'theta2', 'dtheta1', 'dtheta2'):
        exact = getattr(fine, name)[0]
        assert np.abs(exact[common] - getattr(coarse, name)[0]).max() < 1e-5 * np.abs(exact).max(), name
    free = coarse.t > 1.2  # the servo settled
    assert np.ptp(coarse.y[0, free]) < 1e-12 and coarse.y[0, -1] == pytest.approx(0.3, abs=1e-5)  # at rest
    e = lagrangian_energy(coarse.theta1[0, free], coarse.theta2[0, free], coarse.dtheta1[0, free],
                          coarse.dtheta2[0, free], P)
    assert np.abs(e - e[0]).max() / e[0] < 1e-7


@pytest.mark.parametrize('kwargs, match', [
    (dict(interpolation='cubic'), 'interpolation'),
    (dict(source='velocity'), 'source'),
    (dict(t_end=-1.0), 't_end'),
    (dict(record_every=0), 'record_every'),
    (dict(initial_state=[0.0] * 6), 'initial_state'),
])
def test_bad_arguments_are_named(kwargs, match):
    with pytest.raises(SimulationError, match=match):
        simulate([0.0, 1.0], [0.0, 0.0], P, **kwargs)


def test_bad_references_and_plants_are_named():
    with pytest.raises(SimulationError, match='increasing'):
        simulate([0.0, 0.0], [0.0, 0.0], P)
    with pytest.raises(SimulationError, match='shape'):
        simulate([0.0, 1.0], [0.0, 0.0, 0.0], P)
    with pytest.raises(SimulationError, match='finite'):
        simulate([0.0, 1.0], [0.0, np.inf], P)
    with pytest.raises(SimulationError, match='rows'):
        simulate([0.0, 1.0], np.zeros((3, 2)), [P, P])
    with pytest.raises(ParameterError, match='L1'):
        simulate([0.0, 1.0], [0.0, 0.0], {'L2': 0.4, 'm1': 1, 'm2': 1, 'g': 9.81, 'tau': 0})
    with pytest.raises(ParameterError, match='dt'):
        simulate([0.0, 1.0], [0.0, 0.0], P, dt=0.0)
    with pytest.raises(ParameterError, match='rest_dt'):
        simulate([0.0, 1.0], [0.0, 0.0], P, rest_dt=-1e-3)


def test_measured_angles_add_seeded_noise_of_the_given_deviation():
    from crane_sim.measurement import AngleNoise, measured_angles
    t = np.arange(0.0, 4.0, 1e-3)
    r = simulate(t, np.where(t < 0.5, 1.0, 0.0), CraneParams(), dt=1e-3, record_every=5)
    a1, a2 = measured_angles(r, 2e-3, seed=5)
    b1, _ = measured_angles(r, 2e-3, seed=5)
    assert np.array_equal(a1, b1)  # reproducible
    for noisy, true in ((a1, r.theta1), (a2, r.theta2)):
        e = (noisy - true).ravel()
        assert abs(e.mean()) < 3 * 2e-3 / np.sqrt(e.size) and np.std(e) == pytest.approx(2e-3, rel=0.1)
    assert measured_angles(r, 0.0)[0] is r.theta1  # no noise: the angles themselves
    with pytest.raises(ValueError, match='noise'):
        AngleNoise(-1e-3)
