"""crane_sim.metrics on synthetic signals with known peaks, RMS and load excursion."""
import math

import numpy as np
import pytest

from crane_msgs_py.crane.params import CraneParams
from crane_sim.metrics import peak, residual_load_mm, rms, swing_metrics, window
from crane_sim.simulator import STATE_NAMES, PlantBatch, SimResult, SimulationError

P = CraneParams()


def test_peak_and_rms_of_a_sinusoid():
    A, w = 0.07, 2 * math.pi * 1.3
    t = np.linspace(0.0, 10.0 / 1.3, 5001)           # whole periods
    x = A * np.cos(w * t)
    assert peak(x) == pytest.approx(A, rel=1e-12)
    assert rms(x, t) == pytest.approx(A / math.sqrt(2), rel=1e-12)
    assert rms(x[:-1]) == pytest.approx(A / math.sqrt(2), rel=1e-12)  # evenly over whole periods
    assert peak(-3.0 * np.ones(4)) == 3.0 and rms([3.0, -4.0]) == pytest.approx(math.sqrt(12.5))
    rows = np.stack([x, 2 * x])
    assert peak(rows) == pytest.approx([A, 2 * A], rel=1e-12)
    assert rms(rows, t) == pytest.approx([A / math.sqrt(2), 2 * A / math.sqrt(2)], rel=1e-12)


def test_time_weighted_rms_ignores_sampling_density():
    t = np.concatenate([np.linspace(0.0, 1.0, 1001), np.linspace(1.1, 2.0, 4)])
    x = np.where(t <= 1.0, 1.0, 0.0)
    # x^2 = 1 on [0, 1], 0 on [1.1, 2], trapezoid in between: mean square (1 + 0.05) / 2,
    # whatever the number of samples on either stretch
    assert rms(x, t) == pytest.approx(math.sqrt((1.0 + 0.05) / 2.0), rel=1e-12)


def test_window_includes_ends_despite_rounding_and_checks_coverage():
    t = 1e-3 * np.arange(3001) * (1 + 1e-15)
    mask = window(t, 1.0, 3.0)
    assert mask.sum() == 2001
    with pytest.raises(SimulationError, match='window'):
        window(t, 0.0, 3.5)


def test_residual_load_mm_of_a_known_swing():
    """theta1 = A sin, theta2 = -theta1 / 2: excursion L1 sin th1 + L2 sin(th1/2), peak at th1 = A."""
    A = 0.05
    t = np.arange(0.0, 20.0, 0.02)                   # 50 Hz, as joint_states
    th1 = np.where(t >= 5.0, A * np.cos(2 * math.pi * 0.5 * (t - 5.0)), 0.3 * np.sin(t))
    th2 = -0.5 * th1
    expected = 1e3 * (P.L1 * math.sin(A) + P.L2 * math.sin(A / 2))
    assert residual_load_mm(t, th1, th2, P.L1, P.L2, after=5.0) == pytest.approx(expected, rel=1e-12)
    # the large swing before 5 s counts only when the window includes it
    assert residual_load_mm(t, th1, th2, P.L1, P.L2, after=0.0) > 100.0
    with pytest.raises(SimulationError):
        residual_load_mm(t, th1, th2, P.L1, P.L2, after=5.0, until=30.0)


def test_swing_metrics_on_a_synthetic_result():
    T, S = 3.0, 10.0
    t = 1e-3 * np.arange(13001)
    plants = [P, P.replace(L1=0.6)]
    A1, A2, B = 0.04, 0.01, 0.002
    w = 2 * math.pi / 0.6        # 5 whole periods in [0, T], crests on the 1 ms grid, 0 at T
    th1 = np.where(t <= T, A1 * np.sin(w * t), B * np.cos(4 * math.pi * (t - T)))
    th2 = np.where(t <= T, A2 * np.sin(w * t), -B * np.cos(4 * math.pi * (t - T)))
    zero = np.zeros((2, t.size))
    rows = np.stack([th1, 2 * th1]), np.stack([th2, 2 * th2])
    states = dict(zip(STATE_NAMES, (zero, zero, zero, rows[0], rows[1], zero, zero)))
    result = SimResult(t, states, plants=PlantBatch.of(plants))
    m = swing_metrics(result, plants, T, S)
    assert len(m) == 2
    for i, k in enumerate((1.0, 2.0)):
        p = plants[i]
        assert m[i]['peak']['theta1'] == pytest.approx(k * A1, rel=1e-12)
        assert m[i]['peak']['theta2'] == pytest.approx(k * A2, rel=1e-12)
        assert m[i]['rms']['theta1'] == pytest.approx(k * A1 / math.sqrt(2), rel=1e-9)
        assert m[i]['rms']['theta2'] == pytest.approx(k * A2 / math.sqrt(2), rel=1e-9)
        assert m[i]['residual']['theta1'] == pytest.approx(k * B, rel=1e-12)
        assert m[i]['residual']['theta2'] == pytest.approx(k * B, rel=1e-12)
        # theta1 + theta2 = 0 after T: the lower cable hangs vertical, only L1 contributes
        assert m[i]['residual']['load_mm'] == pytest.approx(1e3 * p.L1 * math.sin(k * B), rel=1e-9)
    assert m == swing_metrics(result, None, T, S)
    with pytest.raises(SimulationError, match='window'):
        swing_metrics(result, plants, T, S + 1.0)
    with pytest.raises(SimulationError, match='plants'):
        swing_metrics(result, [P], T, S)
