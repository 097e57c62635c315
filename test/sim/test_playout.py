"""The simulator's reference jitter buffer (crane_sim.playout)."""
import math

import numpy as np
import pytest

from crane_sim.playout import MAX_GAP, MAX_VELOCITY_ERROR, ReferencePlayout, StallAllowance, moved_across_gap
from crane_sim.simulator import SimulationError

DT = 1e-3


def play(playout, arrivals, steps, phase=0.37e-3, ticks=None):
    """Feed samples (t, p, a) when the step clock passes their arrival time; return per-step (a0, a1).

    The steps run at ``ticks`` (step indices, increasing; skipped ones as a late loop skips them), by default 0, 1, ...
    """
    out, k = [], 0
    for n in range(steps) if ticks is None else ticks:
        t0 = n * DT + phase
        while k < len(arrivals) and arrivals[k][0] <= t0:
            playout.push(*arrivals[k][1])
            k += 1
        out.append(playout.step(t0, t0 + DT))
    return np.array(out)


def samples(a_of_t, n):
    return [(k * DT, 0.0, a_of_t(k * DT)) for k in range(n)]


def integrate(a):
    """Cart velocity and position from rest at 0 under per-step accelerations over DT.

    ``a``: (n,) held over each step, or (n, 2) ramps from a[:, 0] to a[:, 1].
    """
    a = np.asarray(a, dtype=float)
    a0, a1 = (a, a) if a.ndim == 1 else a.T
    v = np.concatenate(([0.0], np.cumsum(a0 + a1) * DT / 2))
    return v[-1], np.sum(v[:-1]) * DT + np.sum(a0 / 3 + a1 / 6) * DT * DT


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


def on_time(stamped):
    """Arrivals before the first step: the playout as it runs with every sample on time."""
    return [(-math.inf, s) for s in stamped]


def bump(n=100):
    """A ramp (constant jerk 1) with 0 around it, so its integral is DT * sum for zoh and linear alike."""
    return [(k * DT, 0.0, (k - 5) * DT if 5 <= k < 90 else 0.0) for k in range(n)]


@pytest.mark.parametrize('interpolation', ['zoh', 'linear'])
@pytest.mark.parametrize('delay', [0.0, 0.005])  # no buffer, and one too short for the hiccup
def test_late_samples_leave_no_lasting_velocity_or_position_error(delay, interpolation):
    # a 20 ms hiccup: samples 30..49 arrive together at 50 ms, after the steps that needed them
    stamped = bump()
    arrival = [max(k * DT, 0.05) if 30 <= k < 50 else k * DT for k in range(100)]
    late_playout, exact_playout = (ReferencePlayout(delay, 0.1, interpolation) for _ in range(2))
    late = play(late_playout, list(zip(arrival, stamped)), 150)
    exact = play(exact_playout, on_time(stamped), 150)
    # counted for the diagnostics: made up once, the first of them 20 ms (less the delay) past its playout
    assert (late_playout.made_up, exact_playout.made_up) == (1, 0)
    assert late_playout.made_up_late == pytest.approx(0.05 + 0.37e-3 - delay - 0.03, abs=1e-9)
    assert integrate(exact)[0] == pytest.approx(sum(s[2] for s in stamped) * DT, abs=1e-15)  # the reference
    assert not np.array_equal(late, exact)  # the steps in the hiccup did run without their samples
    v, y = integrate(late)
    v_exact, y_exact = integrate(exact)
    assert abs(v - v_exact) < 1e-15 and abs(y - y_exact) < 1e-15
    if interpolation == 'zoh' or delay >= 2 * DT:  # on time again after the hiccup: two steps make it up
        assert not np.array_equal(late[50:52], exact[50:52]) and np.array_equal(late[52:], exact[52:])


@pytest.mark.parametrize('interpolation', ['zoh', 'linear'])
def test_samples_on_time_play_out_unchanged(interpolation):
    # bit for bit what the buffer gives with every sample there from the start, whatever the latency within it
    rng = np.random.default_rng(1)
    stamped = [(k * DT, 0.0, a) for k, a in enumerate(rng.normal(size=300))]
    arrival = np.arange(300) * DT + rng.uniform(0.0, 3e-3, 300)
    runs = [play(ReferencePlayout(0.005, 0.05, interpolation), arrivals, 360)
            for arrivals in (list(zip(arrival, stamped)), on_time(stamped))]
    assert np.array_equal(*runs)
    # each zoh step with no delay runs ahead of the samples, none of which turns out late
    runs = [play(ReferencePlayout(0.0, 0.05), arrivals, 360) for arrivals in ([(s[0], s) for s in stamped],
                                                                              on_time(stamped))]
    assert np.array_equal(*runs)


def test_what_a_timeout_declared_dead_is_not_made_up():
    stamped = [(k * DT, 0.0, 1.0 if k == 0 else 2.0) for k in range(80)]
    # sample 0 on time, 1..21 only at 21 ms: the buffer ran dry 1.5 ms after sample 0 (the velocity held), the
    # stream timed out at 20 ms, and what it missed stays missed
    playout = ReferencePlayout(delay=0.0, timeout=0.02)
    a = play(playout, [(max(s[0], 0.021) if s[0] > 0 else 0.0, s) for s in stamped], 80)[:, 0]
    assert np.array_equal(a, [1.0] * 2 + [0.0] * 19 + [2.0] * 59) and playout.timeouts == 1
    # the first samples of a stream, 0..30 ms, all more than the timeout late (at 60 ms): dead on arrival;
    # it goes on, on time, at 61 ms
    playout = ReferencePlayout(delay=0.0, timeout=0.02)
    a = play(playout, [(max(s[0], 0.06), s) for s in stamped if not 0.03 < s[0] < 0.061], 80)[:, 0]
    assert np.array_equal(a, [0.0] * 61 + [2.0] * 19) and playout.timeouts == 0
    # 0 and 30..45 ms, the first of a stream, at 45 ms: as on time, but for sample 0, which timed out on time
    # at 20 ms and came more than the timeout after that (the steps are final then)
    stamped = [s for s in stamped if not 0.0 < s[0] < 0.03]
    late = play(ReferencePlayout(0.0, 0.02), [(max(s[0], 0.045), s) for s in stamped], 100)[:, 0]
    without_0 = play(ReferencePlayout(0.0, 0.02), on_time(stamped[1:]), 100)[:, 0]
    assert np.array_equal(late[:45], np.zeros(45)) and not np.array_equal(late, without_0)
    (v, y), (v_exact, y_exact) = integrate(late), integrate(without_0)
    assert abs(v - v_exact) < 1e-15 and abs(y - y_exact) < 1e-15


@pytest.mark.parametrize('seed', range(24))
def test_random_arrivals_end_with_the_on_time_velocity_and_position(seed):
    rng = np.random.default_rng(seed)
    interpolation = ('zoh', 'linear')[seed % 2]
    delay, timeout, phase = rng.choice([0.0, 1e-3, 2.5e-3, 6e-3]), 0.05, rng.uniform(0.0, DT)
    n = 400
    stamped = [(k * DT, 0.0, a) for k, a in enumerate(np.cumsum(rng.normal(size=n)) * 0.3)]
    # latency, and hiccups holding back everything up to their end; in order, within the timeout
    arrival = np.arange(n) * DT + rng.exponential(rng.choice([0.3e-3, 2e-3, 5e-3]), n)
    for start in rng.uniform(0.0, n * DT, rng.integers(1, 6)):
        arrival[np.abs(arrival - start - 0.01) < 0.01] = start + 0.02 + rng.uniform(0.0, 0.01)
    arrival = np.minimum(np.maximum.accumulate(arrival), np.arange(n) * DT + 0.04)
    ticks = np.cumsum(1 + (rng.uniform(size=n + 100) < 0.02) * rng.integers(1, 4, n + 100)) - 1  # some skipped
    runs = [play(ReferencePlayout(delay, timeout, interpolation), arrivals, 0, phase, ticks)
            for arrivals in (list(zip(arrival, stamped)), on_time(stamped))]
    assert not np.array_equal(*runs)  # some samples were late
    (v, y), (v_exact, y_exact) = integrate(runs[0]), integrate(runs[1])
    assert abs(v - v_exact) < 1e-12 * max(1.0, abs(v_exact)) and abs(y - y_exact) < 1e-12 * max(1.0, abs(y_exact))


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


def test_a_gap_while_the_reference_moves_is_told_from_one_while_it_holds():
    """(stamp s, position, acceleration per axis): samples missing mid-motion cannot be made up; missing while
    the reference holds (the same position, no acceleration) they changed nothing."""
    held = (1.0, 0.3, 0.0, 0.47, 0.0)
    assert not moved_across_gap(held, (1.005, 0.3, 0.2, 0.47, 0.0))  # a few ticks on: 0.5 mm/s off at most
    assert not moved_across_gap(held, (1.5, 0.3, 0.0, 0.47, 0.0))  # holding on both sides
    assert moved_across_gap(held, (1.0 + MAX_GAP * 1.1, 0.3, 0.0, 0.46, 0.0))  # the hoist moved across it
    assert moved_across_gap(held, (1.5, 0.3, 0.1, 0.47, 0.0))  # accelerating after it
    assert moved_across_gap((1.0, 0.3, -0.2, 0.47, 0.0), (1.5, 0.3, 0.0, 0.47, 0.0))  # and before it


def test_a_short_gap_loses_the_stream_only_if_holding_the_acceleration_across_it_errs():
    """Below MAX_GAP the error of holding the acceleration is what counts: none at a constant acceleration or
    cruising, |a_after - a_before| gap / 2 in velocity where it changes (MAX_VELOCITY_ERROR 5 mm/s)."""
    assert not moved_across_gap((1.0, 0.10, 0.3), (1.2, 0.11, 0.3))  # constant acceleration: exact
    assert not moved_across_gap((1.0, 0.10, 0.0), (1.2, 0.16, 0.0))  # cruising: exact
    assert not moved_across_gap((1.0, 0.10, 0.30), (1.027, 0.11, 0.33))  # 27 ms late, jerk 1.1: 0.4 mm/s
    assert moved_across_gap((1.0, 0.10, 0.30), (1.05, 0.11, 0.55))  # a step of 0.25 m/s^2 in 50 ms: 6 mm/s
    assert moved_across_gap((1.0, 0.10, 0.3), (1.0 + MAX_GAP * 1.1, 0.2, 0.3))  # too long to trust the estimate
    # the estimate against the playout's own error: a 50 ms gap of a ramp 0 -> 0.25 m/s^2 played holding 0
    t = np.arange(0.0, 0.05, DT)
    held_error = float(np.sum(0.25 * (t + DT) / 0.05) * DT)  # the velocity the held acceleration misses
    assert 0.25 * 0.05 / 2 == pytest.approx(held_error, rel=0.05) and held_error > MAX_VELOCITY_ERROR


def test_a_gap_mid_motion_leaves_a_lasting_error_which_is_why_it_counts_as_lost():
    """Played out, a 0.3 m, 3 s rest-to-rest stream with 0.3 s of its samples missing mid-move ends moving: the
    steps in the gap held the last acceleration, and nothing later makes it up (so the sim brakes instead,
    ``moved_across_gap``); the whole stream ends at rest at 0.3 m."""
    def acceleration(t):
        s = min(max(t / 3.0, 0.0), 1.0)
        return 0.3 / 9.0 * (60 * s - 180 * s ** 2 + 120 * s ** 3)
    stream = samples(acceleration, 3500)
    full = integrate(play(ReferencePlayout(delay=0.0, timeout=1.0), [(x[0], x) for x in stream], 3600))
    gap = integrate(play(ReferencePlayout(delay=0.0, timeout=1.0),
                         [(x[0], x) for x in stream if not 1.0 <= x[0] < 1.3], 3600))
    assert abs(full[0]) < 1e-4 and full[1] == pytest.approx(0.3, abs=1e-3)
    assert abs(gap[0]) > 1e-2  # still moving, for ever


def test_a_stall_of_the_plant_s_own_loop_is_not_the_stream_s_silence():
    """The sim's loop stalled (the host paused it) and catches up: a step 1.5 s late, its newest sample 1.6 s
    old, still plays it (timeout 1 s: the samples of the stall may be on their way); once the loop is on
    time again the same age is a lost stream, as it is without the lateness."""
    def stalled(late: float):
        playout = ReferencePlayout(delay=0.0, timeout=1.0)
        playout.push(0.0, 0.0, 0.5)
        playout.push(0.1, 0.0, 0.5)
        assert playout.step(0.1, 0.101) == (0.5, 0.5)
        playout.behind(late)
        return playout, playout.step(1.7, 1.701)

    playout, played = stalled(late=1.5)
    assert played == (0.5, 0.5) and playout.timeouts == 0
    playout.behind(0.0)  # on time again
    assert playout.step(1.701, 1.702) == (0.0, 0.0) and playout.timeouts == 1
    _, played = stalled(late=0.0)
    assert played == (0.0, 0.0)


def test_a_stall_is_forgiven_for_the_timeout_after_it_while_its_backlog_arrives():
    """The process stood still 1.5 s (SIGSTOP) and its loop caught up in 0.3 s: the samples of the stall are
    still in its executor's backlog, so for the timeout (1 s) after the stall its newest sample may be
    1 + 1.5 s old; after that the allowance is the loop's own lateness again."""
    allowance = StallAllowance(hold=1.0)
    assert allowance(0.0002, 10.0) == 0.0002  # on time: its jitter
    assert allowance(1.5, 11.5) == 1.5  # the first step after the stall
    assert allowance(0.0, 11.8) == 1.5  # caught up, the backlog still on its way
    assert allowance(0.0, 12.49) == 1.5
    assert allowance(0.0, 12.51) == 0.0  # the stall's timeout has passed
    assert allowance(0.2, 13.0) == 0.2 and allowance(0.1, 13.9) == 0.2 and allowance(0.0, 14.01) == 0.0
    assert allowance(0.05, 15.0) == 0.05 and allowance(0.0, 15.01) == 0.0  # jitter: its own step only
    playout = ReferencePlayout(delay=0.0, timeout=1.0)
    playout.push(0.0, 0.0, 0.5)
    playout.behind(StallAllowance(1.0)(1.5, 3.0))
    assert playout.step(1.5, 1.501) == (0.5, 0.5)  # the stall's own lateness: its samples are on their way
    assert playout.step(2.4, 2.401) == (0.0, 0.0)  # dry: the velocity holds ...
    assert playout.timeouts == 0  # ... but 2.4 s old is within 1 + 1.5 s: not lost


def test_stamps_must_increase_and_choices_are_checked():
    playout = ReferencePlayout(delay=0.0, timeout=0.1)
    playout.push(1.0, 0.0, 0.0)
    with pytest.raises(SimulationError, match='increase'):
        playout.push(1.0, 0.0, 0.0)
    with pytest.raises(SimulationError, match='interpolation'):
        ReferencePlayout(0.0, 0.1, interpolation='cubic')
