"""Cranes sharing a runway, the pure core (runway.occupancy, prediction, schedule, guard): distances against
closed forms, a plan's occupancy against crane_sim's independent simulation of the same plan, the least delay
against a brute-force dense check, the stopping envelope against the braking's closed form."""
import math

import numpy as np
import pytest

from crane_msgs_py.crane.braking import stopping_distance
from crane_msgs_py.crane.params import CraneParams
from crane_planner.planning.dispatch import plan
from crane_planner.runway import guard as G
from crane_planner.runway.occupancy import Footprint, Occupancy, Shape, holding, separation
from crane_planner.runway.prediction import plan_occupancy
from crane_planner.runway.schedule import DELAY_STEP, Conflict, conflicts, schedule

P = CraneParams()
SHAPE = Shape(girder_half_width=0.05, load_half_size=0.05)


def footprint(girder, masses):
    return Footprint(np.array([girder], dtype=float), np.array([masses], dtype=float))


def test_separation_is_the_least_of_girder_girder_girder_load_and_load_load_by_closed_forms():
    # girders 2 m apart, loads below their trolleys: the girders' gap less both half-widths
    a = footprint(0.0, [[1.0, 0.0], [1.0, 0.0]])
    b = footprint(2.0, [[3.0, 2.0], [3.0, 2.0]])
    assert separation(a, SHAPE, b, SHAPE)[0] == pytest.approx(2.0 - 0.1)
    # a's load swung 1.7 m towards b (under b's girder's strip nearly): girder b to load a = 0.3 - 0.05 - 0.05
    a = footprint(0.0, [[1.0, 0.5], [1.0, 1.7]])
    assert separation(a, SHAPE, b, SHAPE)[0] == pytest.approx(0.2)
    # both loads swung towards each other at the same x: load to load
    a = footprint(0.0, [[1.0, 0.0], [1.0, 0.9]])
    b = footprint(2.0, [[1.0, 2.0], [1.0, 1.2]])
    assert separation(a, SHAPE, b, SHAPE)[0] == pytest.approx(min(0.3 - 0.1, 2.0 - 0.9 - 0.1, 1.2 - 0.1))
    # symmetric
    assert separation(b, SHAPE, a, SHAPE)[0] == pytest.approx(separation(a, SHAPE, b, SHAPE)[0])


def test_an_occupancy_interpolates_between_its_samples_and_holds_outside_them():
    f = Footprint(np.array([0.0, 1.0]), np.array([[[0.0, 0.0], [0.0, 0.0]], [[2.0, 1.0], [2.0, 1.0]]]))
    o = Occupancy('a', 0, 1_000_000_000, np.array([0.0, 2.0]), f, SHAPE)
    at = o.at(np.array([0, 1_000_000_000, 2_000_000_000, 3_000_000_000, 9_000_000_000]))
    assert at.girder.tolist() == pytest.approx([0.0, 0.0, 0.5, 1.0, 1.0])
    assert at.masses[2, 1].tolist() == pytest.approx([1.0, 0.5])
    assert o.end_ns == 3_000_000_000 and o.delayed(0.5).end_ns == 3_500_000_000
    with pytest.raises(ValueError, match='increase'):
        Occupancy('a', 0, 0, np.array([0.0, 0.0]), f, SHAPE)
    with pytest.raises(ValueError, match='finite'):
        Occupancy('a', 0, 0, np.array([0.0, 1.0]), Footprint(np.array([0.0, math.nan]), f.masses), SHAPE)


def test_an_occupancy_since_an_instant_and_spliced_with_a_later_one_is_each_where_it_holds():
    """``since`` drops the samples before the one at or before the instant, and is the same from there on;
    ``spliced`` is the first until the later one starts, then the later one."""
    S = 1_000_000_000
    t = np.arange(0.0, 2.01, 0.5)
    girder = t ** 2  # (samples of a curve: the linear interpolation differs from it between them)
    o = Occupancy('a', 0, S, t, Footprint(girder, np.zeros((len(t), 2, 2))), SHAPE)
    cut = o.since(S + 1_200_000_000)
    assert cut.start_ns == S + 1_000_000_000 and cut.t.tolist() == [0.0, 0.5, 1.0]
    stamps = np.arange(S + 1_000_000_000, 4 * S, 10_000_000)
    assert cut.at(stamps).girder == pytest.approx(o.at(stamps).girder, abs=1e-12)
    assert o.since(0) is o and o.since(S) is o
    later = Occupancy('a', 7, S + 1_700_000_000, np.array([0.0, 1.0]),
                      Footprint(np.array([5.0, 6.0]), np.zeros((2, 2, 2))), SHAPE)
    both = cut.spliced(later)
    assert (both.published_ns, both.start_ns) == (7, cut.start_ns)
    assert both.t.tolist() == pytest.approx([0.0, 0.5, 0.7, 1.7])  # (1.5 s, after the handover: dropped)
    assert both.at([S + 1_500_000_000]).girder[0] == pytest.approx(2.25)  # the first's sample
    assert both.at([S + 2_200_000_000]).girder[0] == pytest.approx(5.5)  # the later one's
    assert later.spliced(later) is later  # (nothing of the first before the later one's start)


@pytest.mark.parametrize('method', ['zv', 'nvf'])
def test_a_plans_occupancy_follows_its_bridge_and_its_masses_as_crane_sim_simulates_them(method):
    """The occupancy's masses against crane_sim's batch simulation of the same reference (its own numpy model):
    within a few millimetres at every sample; the girder on the bridge's reference, offset into the runway."""
    from crane_msgs_py.crane.geometry import load_offset
    from crane_sim.simulator import simulate
    p = plan(method, 0.0, 3.0, P, bridge=0.6)
    offset = (1.5, 4.0)
    occ = plan_occupancy('a', p, P, {'cart': 0.5, 'bridge': 0.2}, offset, 0, 0, SHAPE)
    assert occ.footprint.girder[0] == pytest.approx(4.2) and occ.footprint.girder[-1] == pytest.approx(4.8)
    t = np.arange(0.0, p.duration + 1e-9, 1e-3)
    refs = {name: p.evaluate_axis(name, t).acceleration for name in ('cart', 'bridge')}
    sim = simulate(t, refs, P, dt=1e-3, t_end=float(occ.t[-1]))
    s = {k: v[0] for k, v in sim.states.items()}
    _, dy = load_offset(s['theta1'], s['theta2'], s['phi1'], s['phi2'], P.L1, P.L2)
    y = s['yb'] + dy + 0.2 + offset[1]
    assert np.abs(np.interp(occ.t, sim.t, y) - occ.footprint.masses[:, 1, 1]).max() < 3e-3
    # (the girder where its reference is: the servo lags it by v tau, 3 mm here)
    assert np.abs(np.interp(occ.t, sim.t, s['yb']) + 4.2 - occ.footprint.girder).max() < 5e-3
    assert np.abs(dy).max() > 0.01  # the load swings on the way: the comparison is not vacuous
    assert occ.footprint.masses[-1, 1].tolist() == pytest.approx([2.0, 4.8], abs=1e-4)  # at rest below the trolley


def moving(crane: str, distance: float, at: float, method: str = 'zv', duration: float = 3.0) -> Occupancy:
    p = plan(method, 0.0, duration, P, bridge=distance)
    return plan_occupancy(crane, p, P, {'cart': 0.5, 'bridge': 0.0}, (0.0, at), 0, 0, SHAPE)


def dense_min_distance(a: Occupancy, b: Occupancy) -> float:
    stamps = np.arange(min(a.start_ns, b.start_ns), max(a.end_ns, b.end_ns) + 1, 1_000_000)
    return float(separation(a.at(stamps), a.shape, b.at(stamps), b.shape).min())


def test_a_goal_that_would_come_too_close_waits_the_least_that_keeps_it_clear_by_a_dense_check():
    """Crane a leaves slowly (1 m in 4 s) where crane b, 1.5 m away, goes quickly (1.8 m in 2 s), sent
    together: b would catch up with a; b waits. Checked every millisecond (independent of the samples the
    schedule used): clear by the minimum with the delay given, not with one step less."""
    a = moving('a', -1.0, 1.0, 'nvf', 4.0)
    b = moving('b', -1.8, 2.5, 'nvf', 2.0)
    assert dense_min_distance(a, b) < 0.2  # the conflict is real
    scheduled = schedule(b, [a], 0.2)
    assert scheduled.delay > 0 and scheduled.waited_for == 'a'
    assert dense_min_distance(a, b.delayed(scheduled.delay)) >= 0.2
    assert dense_min_distance(a, b.delayed(scheduled.delay - DELAY_STEP)) < 0.2 + 1e-3
    with pytest.raises(Conflict, match="crane 'a'") as refused:
        schedule(b, [a], 0.2, policy='refuse')
    assert refused.value.crane == 'a'


def test_a_goal_into_a_crane_that_stays_is_refused_naming_it_whatever_the_delay():
    a = holding('a', 0, footprint(1.0, [[0.5, 1.0], [0.5, 1.0]]), SHAPE)
    b = moving('b', -1.0, 2.0)  # ends with its girder at 1.0: on a's
    with pytest.raises(Conflict, match="crane 'a'"):
        schedule(b, [a], 0.2)


def test_the_stopping_envelope_widens_towards_the_motion_by_the_braking_distance_and_covers_the_load():
    shape = Shape(0.05, 0.05)
    r = G.reach(1.0, 0.3, 0.0, [1.02, 1.08], shape, 0.5, 5.0)
    d = stopping_distance(0.3, 0.0, 0.5, 5.0)
    assert d == pytest.approx(0.3 ** 2 / (2 * 0.5) + 0.3 * 0.5 / (2 * 5.0), rel=1e-9)  # trapezoid + jerk ramps
    assert r.low == pytest.approx(0.95) and r.high == pytest.approx(1.08 + 0.05 + d)
    at_rest = G.reach(1.0, 0.0, 0.0, [0.9, 1.0], shape, 0.5, 5.0)
    assert (at_rest.low, at_rest.high) == pytest.approx((0.85, 1.05))


def test_the_guard_says_info_warning_stop_as_the_gap_closes_and_blocks_only_towards_that_crane():
    g = G.Guard(0.2, 0.5, reach=1.0)
    g.heard('b', G.Reach(2.0, 2.1), 0)
    for high, level in ((0.9, G.Level.CLEAR), (1.3, G.Level.INFO), (1.7, G.Level.WARNING), (1.85, G.Level.STOP)):
        verdict = g.check(G.Reach(0.0, high), 1)
        assert verdict.level is level, (high, verdict)
    assert verdict.crane == 'b' and verdict.refuses(+0.1) and not verdict.refuses(-0.1)
    # silent past the timeout within reach: lost (a stop); out of reach it is no reason to stop
    assert g.check(G.Reach(0.0, 1.5), 600_000_000).level is G.Level.LOST
    assert g.check(G.Reach(-2.0, -1.0), 600_000_000).level is G.Level.CLEAR
    g.heard('b', G.Reach(2.0, 2.1), 600_000_000)
    assert g.check(G.Reach(0.0, 1.5), 600_000_001).level is G.Level.INFO  # heard again: its gap 0.5 m


def test_a_stop_holds_until_the_way_is_clear_so_a_crane_stopped_at_the_minimum_does_not_creep_on():
    g = G.Guard(0.2, 0.5, reach=1.0)
    g.heard('b', G.Reach(2.0, 2.1), 0)
    assert g.check(G.Reach(0.0, 1.85), 1).level is G.Level.STOP  # 0.15 m: under the minimum
    at_rest = g.check(G.Reach(0.0, 1.78), 2)  # stopped 0.22 m away: over the minimum, yet not clear
    assert at_rest.level is G.Level.STOP and at_rest.refuses(+1.0) and not at_rest.refuses(-1.0)
    assert g.check(G.Reach(0.0, 1.61), 3).level is G.Level.STOP  # 0.39 m
    clear = g.check(G.Reach(0.0, 1.59), 4)  # past twice the minimum: the way is clear
    assert clear.level is G.Level.INFO and not clear.blocked
    assert g.check(G.Reach(0.0, 1.7), 5).level is G.Level.WARNING  # (no longer held: 0.3 m is a warning again)


def test_the_envelope_takes_its_callers_stopping_travel_on_the_side_it_moves_to():
    shape = Shape(0.05, 0.05)
    assert G.envelope(1.0, [1.0, 1.0], shape, 0.3) == G.Reach(0.95, 1.35)
    assert G.envelope(1.0, [0.9, 1.08], shape, -0.2) == G.Reach(pytest.approx(0.65), pytest.approx(1.13))
    d = stopping_distance(0.3, 0.1, 0.5, 5.0)
    assert G.reach(1.0, 0.3, 0.1, [1.0], shape, 0.5, 5.0) == G.envelope(1.0, [1.0], shape, d)
    # a silent crane within reach: both cranes' travel at full speed through the timeout and a lag, and their stops
    lagging = G.within_reach(0.2, 0.3, 0.5, 0.5, 5.0, lag=1.0)
    assert lagging == pytest.approx(G.within_reach(0.2, 0.3, 0.5, 0.5, 5.0) + 2 * 0.3 * 1.0)


def test_two_cranes_that_both_follow_their_plans_are_judged_on_their_footprints_either_deviating_on_envelopes():
    """A follows b into the space b leaves: a's stopping envelope already reaches where b still is (gap 0.05 m),
    their footprints are 0.3 m apart. Both on their plans: a warning, no stop (their planners placed them
    apart in time); b not on its plan (an operator, a stop), or a not: the envelopes count, a stop."""
    g = G.Guard(0.2, 0.5, reach=1.0)
    b_envelope, b_footprint = G.Reach(1.95, 2.3), G.Reach(1.95, 2.05)
    a_envelope, a_footprint = G.Reach(1.4, 1.9), G.Reach(1.4, 1.65)
    g.heard('b', b_envelope, 0, b_footprint, planned=True)
    verdict = g.check(a_envelope, 1, a_footprint, planned=True)
    assert verdict.level is G.Level.WARNING and verdict.gap == pytest.approx(0.3)
    assert g.check(a_envelope, 2, a_footprint, planned=False).level is G.Level.STOP
    g.heard('b', b_envelope, 3, b_footprint, planned=False)
    stop = g.check(a_envelope, 4, a_footprint, planned=True)
    assert stop.level is G.Level.STOP and stop.gap == pytest.approx(0.05) and stop.refuses(+1.0)
    # on their plans again, the footprints 0.3 m apart: the stop holds until the way is clear (2x the minimum)
    g.heard('b', b_envelope, 5, b_footprint, planned=True)
    assert g.check(a_envelope, 6, a_footprint, planned=True).level is G.Level.STOP
    g.heard('b', b_envelope, 7, G.Reach(2.1, 2.2), planned=True)
    assert g.check(a_envelope, 8, a_footprint, planned=True).level is G.Level.INFO  # 0.45 m: clear of the stop
    # footprints within the minimum stop planned cranes too: the guard is the last word
    g.heard('b', b_envelope, 9, G.Reach(1.8, 1.9), planned=True)
    assert g.check(a_envelope, 10, a_footprint, planned=True).level is G.Level.STOP


def test_the_crane_waited_for_is_the_one_that_set_the_delay_not_the_first_in_the_way():
    """Two cranes ahead of a goal along y: p stands in its way only until 0.3 s, q, further on, leaves later;
    the goal waits for q (in its way a step before the delay found), though p was the first in its way."""
    t = np.linspace(0.0, 4.0, 201)

    def crane(name, y):
        g = np.asarray(y, dtype=float)
        masses = np.stack([np.stack([np.zeros_like(g), g], -1)] * 2, axis=1)
        return Occupancy(name, 0, 0, t, Footprint(g, masses), Shape())

    mine = crane('mine', np.clip(t, 0.0, 1.0) * 1.0)  # 0 -> 1 m in 1 s
    p = crane('p', 0.5 + 5.0 * np.clip(t - 0.3, 0.0, None))  # in the way at once, off at 5 m/s from 0.3 s
    q = crane('q', 1.25 + 5.0 * np.clip(t - 1.5, 0.0, None))  # where mine ends, off from 1.5 s
    assert [c.crane for c in conflicts(mine, [p, q], 0.2)][0] == 'p'
    s = schedule(mine, [p, q], 0.2)
    assert s.waited_for == 'q' and s.delay > 0.5, s
