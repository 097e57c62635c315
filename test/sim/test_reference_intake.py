"""The simulator's reference intake (crane_sim.reference_intake): checks, stamps and counts, without ROS."""
import math

import numpy as np
import pytest

from crane_sim.reference_intake import COUNTS, MAX_BRIDGED, ReferenceIntake, bridge

MS = 1_000_000                        # ns
T0 = 1_700_000_000_000_000_000        # ns of ROS time


@pytest.fixture
def intake():
    return ReferenceIntake(timeout=0.5, playout_delay=0.2, unstamped_period=1e-3)


def counted(intake, *keys):
    return {k: intake.counts[k] for k in keys}


def test_a_stale_sample_is_counted_and_ignored(intake):
    assert intake.receive(T0 + 600 * MS, T0, 0.1, 0.0) == ()  # 0.6 s old, timeout 0.5 s
    assert intake.receive(T0 + 500 * MS, T0, 0.1, 0.0) == ((T0, 0.1, 0.0),)  # exactly the timeout: not stale
    assert intake.receive(T0 + 1000 * MS, T0 + 400 * MS, 0.1, 0.0) == ()
    assert counted(intake, 'received', 'stale', 'accepted') == {'received': 3, 'stale': 2, 'accepted': 1}
    assert intake.receive(T0 + 1000 * MS, T0 + 600 * MS, 0.1, 0.0) != ()
    assert intake.take_latencies() == [400 * MS]  # only accepted samples are measured (from the second on)


def test_a_sample_is_stale_by_the_plant_s_time_when_the_loop_runs_behind(intake):
    """The sim's loop stalled and catches up, its step 0.8 s behind the arrival: a sample 0.6 s old on arrival
    is 0.2 s ahead of the plant, not stale (timeout 0.5 s); on time again, the same age is."""
    assert intake.receive(T0 + 600 * MS, T0, 0.1, 0.0, played_ns=T0 - 200 * MS) == ((T0, 0.1, 0.0),)
    assert intake.receive(T0 + 1200 * MS, T0 + 600 * MS, 0.1, 0.0, played_ns=T0 + 1200 * MS) == ()
    assert intake.receive(T0 + 1200 * MS, T0 + 601 * MS, 0.1, 0.0, played_ns=T0 + 1500 * MS) == ()  # arrival
    assert counted(intake, 'stale', 'accepted') == {'stale': 2, 'accepted': 1}


def test_an_out_of_order_sample_is_counted_and_ignored(intake):
    assert intake.receive(T0, T0 + 5 * MS, 0.1, 0.2) == ((T0 + 5 * MS, 0.1, 0.2),)
    assert intake.receive(T0, T0 + 5 * MS, 0.1, 0.2) == ()   # a duplicate
    assert intake.receive(T0, T0 + 3 * MS, 0.1, 0.2) == ()   # overtaken
    assert intake.receive(T0, T0 + 6 * MS, 0.1, 0.2) == ((T0 + 6 * MS, 0.1, 0.2),)
    assert counted(intake, 'out_of_order', 'accepted', 'missing') == {'out_of_order': 2, 'accepted': 2, 'missing': 0}


def test_a_nonfinite_sample_is_counted_and_ignored_and_moves_nothing(intake):
    assert intake.receive(T0, T0, math.nan, 0.0) == ()
    assert intake.receive(T0, T0, 0.1, math.inf) == ()
    assert intake.receive(T0, T0, 0.1, -math.inf) == ()
    assert counted(intake, 'nonfinite', 'accepted') == {'nonfinite': 3, 'accepted': 0}
    assert intake.receive(T0, T0, 0.1, 0.0) == ((T0, 0.1, 0.0),)  # its stamp is still free
    assert intake.sender_period_ns == math.inf and intake.counts['accepted'] == 1


def test_missing_samples_are_counted_from_the_gaps_of_the_shortest_interval(intake):
    stamps = [0, 1, 2, 5, 6, 10]  # ms: 2 missing after 2, 3 after 6
    for ms in stamps:
        assert intake.receive(T0 + ms * MS + 7 * MS, T0 + ms * MS, 0.0, 0.0) != ()
    assert intake.sender_period_ns == 1 * MS
    assert counted(intake, 'missing', 'accepted', 'bridged') == {'missing': 5, 'accepted': 6, 'bridged': 0}
    # the first sample has no interval, and no latency is taken of it either
    assert intake.take_latencies() == [7 * MS] * 5 and intake.take_latencies() == []  # taken: a fresh window


def test_the_sender_period_is_the_shortest_interval_seen_so_far(intake):
    for ms in (0, 2, 3, 5):  # 2 ms (no gap yet: the period is 2 ms), 1 ms, then 2 ms: one missing
        intake.receive(T0 + ms * MS, T0 + ms * MS, 0.0, 0.0)
    assert intake.sender_period_ns == 1 * MS and intake.counts['missing'] == 1


def test_unstamped_samples_go_on_the_grid_and_are_reanchored_after_a_pause(intake):
    stamps = [intake.receive(T0, 0, 0.0, 0.0)[-1][0]]                                 # the first: at its arrival
    stamps += [intake.receive(T0 + 50 * MS, None, 0.0, 0.0)[-1][0] for _ in range(4)]  # bunched: on the grid
    stamps += [intake.receive(T0 + 205 * MS, 0, 0.0, 0.0)[-1][0]]  # 200 ms after its place (5 ms): still on it
    stamps += [intake.receive(T0 + 500 * MS, 0, 0.0, 0.0)[-1][0]]  # 494 ms > 200 ms after: re-anchored
    stamps += [intake.receive(T0 + 500 * MS + 300_000, 0, 0.0, 0.0)[-1][0]]  # on the new grid
    assert [s - T0 for s in stamps] == [0, 1 * MS, 2 * MS, 3 * MS, 4 * MS, 5 * MS, 500 * MS, 501 * MS]
    # no latency, no gaps seen, never stale (an unstamped sample's age is unknown)
    assert intake.take_latencies() == [] and intake.sender_period_ns == math.inf
    assert counted(intake, 'accepted', 'missing', 'stale') == {'accepted': 8, 'missing': 0, 'stale': 0}


def test_the_grid_follows_a_changed_period_and_delay(intake):
    intake.receive(T0, 0, 0.0, 0.0)
    intake.configure(timeout=0.5, playout_delay=0.01, unstamped_period=2e-3)
    assert intake.receive(T0 + 10 * MS, 0, 0.0, 0.0)[-1][0] == T0 + 2 * MS    # 8 ms after its place: on the grid
    assert intake.receive(T0 + 20 * MS, 0, 0.0, 0.0)[-1][0] == T0 + 20 * MS   # 16 ms > 10 ms: re-anchored
    assert intake.counts['accepted'] == 3  # counts stay


def test_positions_only_zeroes_the_acceleration(intake):
    assert intake.receive(T0, T0, 0.1, math.nan) == ()  # counting the acceleration: NaN is non-finite
    intake.configure(timeout=0.5, playout_delay=0.2, unstamped_period=1e-3, positions_only=True)
    assert intake.receive(T0, T0, 0.1, math.nan) == ((T0, 0.1, 0.0),)  # a Float64MultiArray has none
    assert intake.receive(T0, T0 + 1 * MS, 0.2, 2.5) == ((T0 + 1 * MS, 0.2, 0.0),)
    assert intake.receive(T0, T0 + 2 * MS, math.inf, 0.0) == ()  # positions still count
    assert counted(intake, 'nonfinite', 'accepted') == {'nonfinite': 2, 'accepted': 2}


def test_a_positions_only_intake_from_the_start():
    intake = ReferenceIntake(0.5, 0.2, 1e-3, positions_only=True)
    assert intake.positions_only and intake.receive(T0, 0, 0.3, math.nan) == ((T0, 0.3, 0.0),)


def test_malformed_messages_are_received_and_counted(intake):
    intake.count_malformed()
    intake.receive(T0, T0, 0.0, 0.0)
    assert intake.counts == {**dict.fromkeys(COUNTS, 0), 'received': 2, 'malformed': 1, 'accepted': 1}


def cubic(ms):
    """A reference of constant jerk on two axes at ``ms``: (stamp, then position and acceleration per axis)."""
    t = ms * 1e-3
    return (T0 + ms * MS, 0.1 + 0.2 * t + 1.5 * t**2 - 4.0 * t**3, 3.0 - 24.0 * t,
            0.47 - 0.3 * t**2 + 2.0 * t**3, -0.6 + 12.0 * t)


@pytest.mark.parametrize('n', [1, 2, 3])
def test_a_bridge_is_exact_on_a_reference_of_constant_jerk(n):
    """The samples filling a gap are the cubic's own, on the grid, whatever the gap's length."""
    got = bridge(cubic(4), cubic(5 + n), n)
    assert [g[0] for g in got] == [cubic(4 + i)[0] for i in range(1, n + 1)]
    assert np.allclose([g[1:] for g in got], [cubic(4 + i)[1:] for i in range(1, n + 1)], rtol=0, atol=1e-12)


def test_a_single_lost_sample_is_bridged_and_two_are_not(intake):
    """A sample lost between two stamped ones on the sender's grid comes back, bridged, before the sample after
    it; two lost in a row, a gap off the grid, or one after an unstamped sample are left for the judgement of
    the stream (``playout.moved_across_gap``)."""
    got = []
    for ms in (0, 1, 3, 4):  # one lost
        got += intake.receive(T0 + ms * MS, *cubic(ms)[:3], others=[cubic(ms)[3:]])
    assert [g[0] for g in got] == [cubic(ms)[0] for ms in range(5)]
    assert np.allclose([g[1:] for g in got], [cubic(ms)[1:] for ms in range(5)], rtol=0, atol=1e-12)
    assert MAX_BRIDGED == 1 and counted(intake, 'missing', 'bridged', 'accepted') == {
        'missing': 1, 'bridged': 1, 'accepted': 4}
    assert len(intake.receive(T0 + 7 * MS, *cubic(7)[:3], others=[cubic(7)[3:]])) == 1  # two lost
    assert len(intake.receive(T0 + 8 * MS + MS // 2, T0 + 8 * MS + MS // 2, 0.9, 1.0)) == 1  # 1.5 periods
    assert len(intake.receive(T0 + 10 * MS, 0, 0.9, 1.0)) == 1  # unstamped: on its grid
    assert len(intake.receive(T0 + 12 * MS, T0 + 12 * MS, 0.9, 1.0)) == 1  # no stamped sample just before it
    assert counted(intake, 'bridged') == {'bridged': 1}
