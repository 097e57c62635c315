"""planning.profiles: the paper's quintic base and ruckig's jerk-limited base, against closed forms and
finite differences of their own positions."""
import math

import numpy as np
import pytest

from crane_planner.planning.plan import PlanError
from crane_planner.planning.profiles import limited_base, quintic, quintic_base, quintic_duration


def evaluate(base, t):
    """Position, velocity, acceleration, jerk of a BaseProfile at times t, from its Taylor coefficients."""
    c = base.taylor(t)
    return c[:, 0], c[:, 1], 2.0 * c[:, 2], 6.0 * c[:, 3]


def test_the_quintic_peaks_are_the_closed_forms():
    D, T = 0.3, 3.0
    p, v, a, j = quintic(np.linspace(0.0, T, 600_001), D, T)
    assert p[0] == 0.0 and p[-1] == pytest.approx(D, abs=1e-15)
    assert np.abs(v).max() == pytest.approx(15 / 8 * D / T, rel=1e-9)  # at T/2
    assert np.abs(a).max() == pytest.approx(10 / math.sqrt(3) * D / T ** 2, rel=1e-9)  # at (1/2 -+ sqrt(3)/6) T
    assert np.abs(j).max() == pytest.approx(60 * D / T ** 3, rel=1e-9)  # at both ends


def test_the_quintic_base_is_the_quintic_and_its_shortest_duration_makes_one_limit_bind():
    D, T = -0.4, 2.5
    t = np.linspace(0.0, T, 1001)[:-1]  # [0, T): at T quintic() is at rest, its jerk right-continuous
    for ours, theirs in zip(evaluate(quintic_base(D, T), t), quintic(t, D, T)):
        assert ours == pytest.approx(theirs, abs=1e-12)
    limits = (0.25, 0.5, 2.0)
    T_min = quintic_duration(D, *limits)
    peaks = [np.abs(x).max() for x in quintic(np.linspace(0.0, T_min, 200_001), D, T_min)[1:]]
    ratios = [peak / limit for peak, limit in zip(peaks, limits)]
    assert max(ratios) == pytest.approx(1.0, abs=1e-6)


@pytest.mark.parametrize('D, v, a, j', [(0.3, 0.25, 0.5, 2.0), (-1.2, 0.4, 0.3, None), (0.05, None, 0.5, 5.0)])
def test_the_limits_base_rests_at_both_ends_within_its_limits_with_one_binding(D, v, a, j):
    base = limited_base(D, v, a, j)
    t = np.linspace(0.0, base.duration, 200_001)
    p, vel, acc, jerk = evaluate(base, t)
    assert p[0] == pytest.approx(0.0, abs=1e-12) and p[-1] == pytest.approx(D, abs=1e-9)
    assert abs(vel[-1]) < 1e-9
    if j is not None:  # without a jerk limit the acceleration jumps to 0 only after the end
        assert abs(acc[-1]) < 1e-9
    # the velocity is the derivative of the position: one consistent trajectory
    assert np.gradient(p, t)[1:-1] == pytest.approx(vel[1:-1], abs=1e-6)
    binding = [np.abs(x).max() / lim for x, lim in zip((vel, acc, jerk), (v, a, j)) if lim is not None]
    assert max(binding) <= 1.0 + 1e-9 and max(binding) == pytest.approx(1.0, abs=1e-6)


def test_a_stretched_base_lasts_longer_with_peaks_falling_as_powers_of_the_stretch():
    base = limited_base(0.3, 0.25, 0.5, 2.0)
    slow = base.stretched(2.0 * base.duration)
    t = np.linspace(0.0, base.duration, 20_001)
    for k, (fast, stretched) in enumerate(zip(evaluate(base, t), evaluate(slow, 2.0 * t))):
        assert stretched == pytest.approx(fast / 2.0 ** k, abs=1e-12)
    with pytest.raises(PlanError, match='cannot be shorter'):
        base.stretched(0.5 * base.duration)
    with pytest.raises(PlanError, match='needs max_velocity or max_acceleration'):
        limited_base(0.3, None, None, 2.0)
