"""crane_sim.disturbances: the gusts' Ornstein-Uhlenbeck process against its closed-form statistics (standard
deviation, autocorrelation e^(-lag/T)), its seeding, and the settings' checks."""
import math

import numpy as np
import pytest

from crane_msgs_py.crane.params import CraneParams, ParameterError
from crane_sim.disturbances import Disturbances, Gust, SampledDisturbance
from crane_sim.simulator import simulate


def autocorrelation(x, lag: int) -> float:
    x = x - x.mean()
    return float(np.dot(x[:-lag], x[lag:]) / np.dot(x, x))


@pytest.mark.parametrize('h', [0.05, 1.0])
def test_a_long_seeded_gust_has_the_standard_deviation_and_the_lag_T_autocorrelation_e_to_the_minus_1(h):
    """Over 10^4 correlation times (about 5000 independent samples: 1 % on the deviation, 0.015 on the
    correlation) at a fine step and at a step as long as T: the discretisation is exact at any step."""
    sd, T = 0.4, 2.0
    gust = Gust(sd, T, planes=2, seed=11)
    steps = round(1e4 * T / h)
    w = gust.path(steps, h)
    assert w.shape == (2, steps + 1)
    lag = round(T / h)
    for plane in w:
        assert plane.std() == pytest.approx(sd, rel=0.04)
        assert abs(plane.mean()) < 0.05 * sd
        assert autocorrelation(plane, lag) == pytest.approx(math.exp(-1.0), abs=0.04)
        assert autocorrelation(plane, 3 * lag) == pytest.approx(math.exp(-3.0), abs=0.04)
    assert abs(np.corrcoef(w)[0, 1]) < 0.04  # the planes independent


def test_a_gust_is_reproducible_from_its_seed_and_its_path_is_its_steps_one_by_one():
    one, two, other = Gust(0.3, 1.0, 2, seed=7), Gust(0.3, 1.0, 2, seed=7), Gust(0.3, 1.0, 2, seed=8)
    path = one.path(500, 1e-3)
    steps = np.array([two.value] + [two.step(1e-3) for _ in range(500)]).T
    assert np.array_equal(path, steps)
    assert one.value == two.value  # moved on alike
    assert not np.array_equal(path, other.path(500, 1e-3))
    assert path[:, 0] == pytest.approx(path[:, 1], abs=0.05)  # correlated over 1 s, not white


def test_a_gust_off_draws_nothing_starts_stationary_when_turned_on_and_scales_with_its_deviation():
    quiet, fresh = Gust(0.0, 1.0, seed=3), Gust(0.5, 1.0, seed=3)
    assert quiet.step(1e-3) == (0.0,) and quiet.value == (0.0,) and not quiet.path(10, 1e-3).any()
    quiet.configure(0.5, 1.0)  # as if it had started now: nothing was drawn while off
    assert quiet.value == fresh.value and quiet.step(1e-3) == fresh.step(1e-3)
    before = quiet.value[0]
    quiet.configure(1.0, 1.0)
    assert quiet.value[0] == pytest.approx(2.0 * before, rel=1e-15)
    # the first value of a stationary start: a draw of N(0, sd^2), over many seeds
    starts = np.array([Gust(0.5, 1.0, seed=s).value[0] for s in range(4000)])
    assert starts.std() == pytest.approx(0.5, rel=0.05)
    with pytest.raises(ParameterError, match='gust_time'):
        quiet.configure(0.5, 0.0)
    with pytest.raises(ParameterError, match='gust'):
        Gust(-0.1)
    with pytest.raises(ParameterError, match='planes'):
        Gust(0.1, planes=3)


def test_the_settings_are_checked_and_a_y_wind_needs_the_bridge():
    assert not Disturbances().active and Disturbances(gust=0.1).active and Disturbances(wind=[0.0, 0.2]).active
    assert Disturbances(wind=[1, 2]).wind == (1.0, 2.0)
    for kwargs, match in (({'wind': (0.1,)}, 'wind'), ({'wind': (0.1, math.nan)}, 'wind'), ({'wind': 'ab'}, 'wind'),
                          ({'gust': -1.0}, 'gust'), ({'gust_time': 0.0}, 'gust_time')):
        with pytest.raises(ParameterError, match=match):
            Disturbances(**kwargs)
    with pytest.raises(ParameterError, match='needs the bridge'):
        Disturbances(wind=(0.1, 0.2)).check_planes(bridge=False)
    assert Disturbances(wind=(0.1, 0.2)).check_planes(bridge=True).wind == (0.1, 0.2)
    # the wind plus a gust of one plane (x) or two (x, y)
    assert Disturbances(wind=(0.1, 0.2)).plus((0.5, -0.5)) == (0.6, -0.3)
    assert Disturbances(wind=(0.1, 0.0)).plus((0.5,)) == (0.6, 0.0)


def test_sampled_disturbances_drive_the_batch_simulation_wind_as_the_constant_and_gusts_seeded():
    P = CraneParams()
    t = [0.0, 4.0]
    steady = simulate(t, [0.0, 0.0], P, disturbance=(0.3, 0.0))
    sampled = simulate(t, [0.0, 0.0], P, disturbance=Disturbances(wind=(0.3, 0.0)).sampled(0.0, 4.0, 0.01))
    assert sampled.theta1 == pytest.approx(steady.theta1, rel=1e-12, abs=1e-16)
    gusty = Disturbances(wind=(0.3, -0.1), gust=0.5, gust_time=0.5)
    runs = [simulate(t, {'cart': [0.0, 0.0], 'bridge': [0.0, 0.0]}, P,
                     disturbance=gusty.sampled(0.0, 4.0, 0.01, bridge=True, seed=s)) for s in (1, 1, 2)]
    assert np.array_equal(runs[0].phi1, runs[1].phi1) and not np.array_equal(runs[0].phi1, runs[2].phi1)
    assert np.abs(runs[0].phi1).max() > 1e-3 and np.abs(runs[0].theta1 - steady.theta1).max() > 1e-3
    # linear between the samples, held beyond them
    w = SampledDisturbance([0.0, 1.0], [[0.0, 2.0], [1.0, 1.0]])
    assert w([-1.0, 0.25, 3.0]).tolist() == [[0.0, 0.5, 2.0], [1.0, 1.0, 1.0]]
    with pytest.raises(ParameterError, match='shape'):
        SampledDisturbance([0.0, 1.0], [0.0, 1.0])
