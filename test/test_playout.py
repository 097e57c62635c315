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


def integrate(a):
    """Cart velocity and position under per-step constant accelerations a (zoh over DT), from rest at 0."""
    v = np.concatenate(([0.0], np.cumsum(a) * DT))
    return v[-1], np.sum(v[:-1]) * DT + np.sum(a) * DT * DT / 2


@pytest.mark.parametrize('interpolation', ['zoh', 'linear'])
def test_positions_with_a_gap_in_the_stamps_still_end_at_rest_at_the_goal(interpolation):
    # a quintic 0 -> 0.3 m in 1 s at 1 ms, the stamps re-anchored 0.3 s later halfway through (as the
    # sim node does for unstamped samples after a stall), at rest before and after
    from crane_planner.planning.profiles import quintic
    t = np.arange(-100, 1400) * DT
    p = quintic(np.clip(t, 0.0, 1.0), 0.3, 1.0)[0]
    stamps = np.where(np.arange(t.size) >= 600, t + 0.3, t) + 0.1
    playout = ReferencePlayout(delay=0.05, timeout=0.5, interpolation=interpolation, source='position')
    a = play(playout, [(ts, (ts, pk, 0.0)) for ts, pk in zip(stamps, p)], 2000)[:, 0]
    v, y = integrate(a)
    assert abs(v) < 1e-9 and y == pytest.approx(0.3, abs=1e-9)


def test_positions_hold_when_the_stream_stops_mid_motion():
    # a ramp at 0.1 m/s that stops arriving: the last position holds, the velocity returns to 0
    playout = ReferencePlayout(delay=0.0, timeout=0.02, source='position')
    a = play(playout, [(k * DT, (k * DT, 0.1 * k * DT, 0.0)) for k in range(50)], 200, phase=0.0)[:, 0]
    v, y = integrate(a)
    assert abs(v) < 1e-12 and y == pytest.approx(0.1 * 49 * DT, abs=1e-12) and playout.timeouts == 1


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
