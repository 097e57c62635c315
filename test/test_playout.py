"""The simulator's reference jitter buffer (crane_sim.playout)."""
import math

import numpy as np
import pytest

from crane_sim.playout import ReferencePlayout
from crane_sim.simulator import SimulationError

DT = 1e-3


def play(playout, arrivals, steps, phase=0.37e-3):
    """Feed samples (t, p, a) when the step clock passes their arrival time; return per-step (a0, a1)."""
    out, k = [], 0
    for n in range(steps):
        t0 = n * DT + phase
        while k < len(arrivals) and arrivals[k][0] <= t0:
            playout.push(*arrivals[k][1])
            k += 1
        out.append(playout.step(t0, t0 + DT))
    return np.array(out)


def samples(a_of_t, n):
    return [(k * DT, 0.0, a_of_t(k * DT)) for k in range(n)]


def test_each_sample_counts_once_however_late_and_bunched_it_arrives():
    rng = np.random.default_rng(0)
    stamped = samples(lambda t: math.sin(7 * t), 2000)
    # arrivals: a 0.5 ms latency, random hiccups bunching up to 8 ms of samples
    arrival = np.array([t for t, *_ in stamped]) + 0.5e-3 + rng.exponential(1e-3, len(stamped))
    arrival = np.maximum.accumulate(arrival)  # in order
    assert np.max(arrival - np.arange(len(stamped)) * DT) > 5e-3
    playout = ReferencePlayout(delay=0.01, timeout=0.1)
    a = play(playout, [(arr, s) for arr, s in zip(arrival, stamped)], 2000 + 20)
    # the step at t uses the sample stamped at floor(t - delay): a pure 10 ms shift of the samples
    shifted = a[10:2010, 0]
    assert np.array_equal(shifted, [s[2] for s in stamped])
    assert np.all(a[:10, 0] == 0.0)  # nothing stamped before t - delay yet


def test_on_arrival_playout_would_drift_where_the_buffer_does_not():
    # the same hiccup with no delay: steps reuse a stale sample and skip the bunched ones
    stamped = samples(lambda t: t, 100)  # a ramp: constant jerk 1
    arrival = [max(k * DT, 0.05) if 30 <= k < 50 else k * DT for k in range(100)]  # 20 ms bunched
    a0 = play(ReferencePlayout(delay=0.0, timeout=0.1), list(zip(arrival, stamped)), 100)[:, 0]
    a10 = play(ReferencePlayout(delay=0.03, timeout=0.1), list(zip(arrival, stamped)), 130)[:, 0]
    exact = sum(s[2] for s in stamped) * DT
    assert abs(np.sum(a10) * DT - exact) < 1e-12
    assert abs(np.sum(a0) * DT - exact) > 1e-5


def test_linear_interpolates_between_bracketing_samples():
    stamped = samples(lambda t: 2.0 * t, 50)
    playout = ReferencePlayout(delay=0.005, timeout=0.1, interpolation='linear')
    a = play(playout, [(s[0], s) for s in stamped], 40, phase=0.25e-3)
    t0 = np.arange(10, 40) * DT + 0.25e-3 - 0.005
    assert np.allclose(a[10:, 0], 2.0 * t0) and np.allclose(a[10:, 1], 2.0 * (t0 + DT))


def test_positions_give_second_differences():
    # p = t^2 / 2 * 3: acceleration 3, known one sample late
    stamped = [(k * DT, 1.5 * (k * DT) ** 2, math.nan) for k in range(30)]
    playout = ReferencePlayout(delay=0.0, timeout=0.1, source='position')
    a = play(playout, [(s[0], s) for s in stamped], 30, phase=0.0)
    assert a[0, 0] == 0.0 and np.allclose(a[2:, 0], 3.0)


def test_a_stopped_stream_falls_back_to_zero_once():
    playout = ReferencePlayout(delay=0.0, timeout=0.02)
    a = play(playout, [(s[0], s) for s in samples(lambda t: 1.0, 10)], 100)[:, 0]
    assert np.all(a[:10] == 1.0) and np.all(a[40:] == 0.0) and playout.timeouts == 1


def test_stamps_must_increase_and_choices_are_checked():
    playout = ReferencePlayout(delay=0.0, timeout=0.1)
    playout.push(1.0, 0.0, 0.0)
    with pytest.raises(SimulationError, match='increase'):
        playout.push(1.0, 0.0, 0.0)
    with pytest.raises(SimulationError, match='interpolation'):
        ReferencePlayout(0.0, 0.1, interpolation='cubic')
