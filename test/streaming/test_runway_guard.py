"""streaming.runway_guard: the runway guard as one of the streamer's watches, on explicit ticks and a fake clock.

Crane ``a`` drives its bridge (+y) towards crane ``b``, whose stopping envelope stands at y 1.95-2.05 m; the
minimum distance is 0.2 m, so ``a``'s girder (half-width 0.05 m) may come to 1.70 m at most. Where ``a`` ends is
judged from the reference it streams, tick by tick, as the streamer's loop runs it (``streamer.Streamer``).
"""
import dataclasses
import math
import threading
import time

import numpy as np
import pytest

from crane_msgs_py.crane.axes import AxisLimits
from crane_msgs_py.crane.params import CraneParams
from crane_planner.runway.config import RunwayConfig
from crane_planner.runway.guard import STOP_MARGIN, Level, Reach
from crane_planner.streaming.braking_stop import brake, braking_stop
from crane_planner.streaming.operator import OperatorStream
from crane_planner.streaming.reference_stream import ReferenceStream
from crane_planner.streaming.runway_guard import (
    GUARD_LEAD,
    STOP_REACH,
    GuardStops,
    PlannedStop,
    RunwayGuard,
    first_period,
)
from crane_planner.streaming.streamer import Streamer
from crane_planner.streaming.streamer_state import Mode

from .test_reference_stream import EPOCH, MS, PERIOD, quintic

PARAMS = CraneParams()
JOINTS = ('cart', 'bridge')
LIMITS = AxisLimits(0.3, 0.5, 5.0)  # the operator's defaults: the bridge at full speed
D, J = 0.5, 5.0  # fault_deceleration, fault_jerk
B_LOW, B_HIGH = 1.95, 2.05  # crane b's envelope
MIN = 0.2
#: The farthest a's girder may come: b's envelope less the minimum distance (and the guard's margin before it)
#: and a's girder's half-width.
FARTHEST = B_LOW - MIN - STOP_MARGIN - 0.05
S = 1_000_000_000


def guard(offset=(0.0, 0.0), joints=JOINTS, wake=lambda: None) -> RunwayGuard:
    config = RunwayConfig(True, 'a', offset, MIN, 'wait', 0.5)
    return RunwayGuard(config, joints, PERIOD * 1e-9, PlannedStop(first_period(PARAMS), D, J), LIMITS.max_velocity,
                       LIMITS.max_acceleration, LIMITS.max_jerk, wake)


class Clock:
    def __init__(self):
        self.t = 0.0

    def __call__(self):
        return self.t


class Crane:
    """Crane a's streamer on explicit ticks, in operator mode with the guard watching; crane b heard every 20
    ms (``b_heard``: until when, s)."""

    def __init__(self, shaper='zv'):
        self.clock = Clock()
        self.stream = ReferenceStream(PERIOD, (0.0, 0.0), stopped=True)
        self.guard = guard()
        self.streamer = Streamer(self.stream, watches=(self.guard,))
        self.operator = OperatorStream(PERIOD * 1e-9, (0.0, 0.0), [LIMITS, LIMITS], shaper, PARAMS,
                                       clock=self.clock, joints=JOINTS)
        self.streamer.go(Mode.OPERATOR, self.operator)
        self.tick = 0
        assert self.streamer.start(EPOCH, lambda: self.tick)
        self.b_heard = math.inf

    def drive(self, seconds, bridge_velocity):
        """The stick at ``bridge_velocity`` (m/s, held: commanded every tick) for ``seconds``: the bridge's
        reference (y) at each tick; ``levels`` and ``highs`` (the envelope's far end) of the same ticks."""
        ys, self.levels, self.highs = [], [], []
        for _ in range(round(seconds * 1000)):
            self.clock.t = self.tick * 1e-3
            stamp = EPOCH + self.tick * PERIOD
            if self.tick % 20 == 0 and self.clock.t <= self.b_heard:
                self.guard.heard('b', B_LOW, B_HIGH, stamp)
            self.operator.command(0.0, bridge_velocity)
            ys.append(self.streamer.tick(self.tick, stamp).position[1])
            self.levels.append(self.guard.verdict.level)
            self.highs.append(self.guard.mine.high)
            self.tick += 1
        return np.array(ys)


def test_an_operator_at_full_speed_towards_a_crane_stops_just_short_of_the_minimum_distance_and_goes_only_away():
    crane = Crane()
    y = crane.drive(12.0, 0.3)  # 12 s at 0.3 m/s would take it 3.6 m: through b
    verdict = crane.guard.verdict
    assert verdict.level is Level.STOP and verdict.crane == 'b' and verdict.blocked == {1.0}
    assert np.all(np.diff(y) >= -1e-12)  # no step back: braked and shaped, not reversed
    assert np.ptp(y[-1000:]) == 0.0  # at rest for the last second
    # just short of the minimum: the guard's envelope is the stop's own travel (braking within the limits and the
    # shaper's lag), so it stops where it must, not a braking distance early
    assert FARTHEST - 1e-3 <= y[-1] <= FARTHEST, y[-1]
    assert np.max(y) <= FARTHEST
    # towards b again: held at zero (the stop holds until the way is clear); away: taken at once
    assert np.ptp(crane.drive(2.0, 0.3)) == 0.0
    away = crane.drive(1.0, -0.3)
    assert away[-1] < y[-1] - 0.05
    assert crane.guard.verdict.blocked == {1.0}  # within twice the minimum yet: still refused towards b
    crane.drive(1.0, -0.3)
    assert crane.guard.verdict.level is Level.INFO and not crane.guard.verdict.blocked  # the way is clear


def test_without_the_guard_the_same_stick_would_have_gone_through_the_other_crane():
    """The guard is what stops it: the same drive with b never heard."""
    crane = Crane()
    crane.guard.guard.neighbours.clear()
    crane.b_heard = -1.0
    assert crane.drive(12.0, 0.3)[-1] > B_HIGH


def test_a_crane_gone_silent_within_reach_stops_this_one_until_it_is_heard_again():
    crane = Crane()
    crane.guard.offset = (0.0, 0.8)  # a's crane_base 0.8 m along the runway: b within reach (1.73 m)
    crane.drive(2.0, 0.1)  # creeping towards b, far from the minimum
    assert crane.guard.verdict.level is Level.CLEAR
    crane.b_heard = 1.98  # b dies: its state of tick 1980 is its last
    y = crane.drive(4.0, 0.1)
    lost = crane.levels.index(Level.LOST)
    # lost once runway_timeout has passed since it was last heard, not before (ticks of 1 ms from tick 2000)
    assert 2000 + lost == 1980 + 501 and set(crane.levels[:lost]) == {Level.CLEAR}
    assert set(crane.levels[lost:]) == {Level.LOST} and crane.guard.verdict.blocked == {1.0}
    # it went on at 0.1 m/s until then, and stopped from there as the operator's stop does (braked, shaped):
    # where the envelope of that tick said, never further
    assert y[lost] - y[0] == pytest.approx(0.1 * lost * 1e-3, abs=1e-6)
    assert y[-1] + 0.8 == pytest.approx(crane.highs[lost] - 0.05 - 0.1e-3, abs=1e-9)
    assert np.ptp(y[-500:]) < 1e-12 and y[-1] + 0.8 < FARTHEST - 0.2  # at rest, far from b: silence, not distance
    # heard again: it moves on
    crane.b_heard = math.inf
    assert crane.drive(1.0, 0.1)[-1] > y[-1] + 0.02
    assert crane.guard.verdict.level in (Level.CLEAR, Level.INFO)


def test_a_crane_gone_silent_out_of_reach_is_no_reason_to_stop():
    crane = Crane()
    # reach: both cranes at 0.3 m/s through the timeout and the longest stop lag (0.41 s + 0.75 T1), then braking
    one = 0.3 * (0.5 + 0.41 + STOP_REACH * first_period(PARAMS)) + 0.3 ** 2 / (2 * 0.5) + 0.3 * 0.5 / (2 * 5.0)
    assert crane.guard.guard.reach == pytest.approx(MIN + 2 * one) and 1.7 < MIN + 2 * one < 1.8
    crane.drive(0.1, 0.0)
    crane.guard.offset = (0.0, -3.0)  # a stands 3 m further back: b is out of reach
    crane.b_heard = crane.clock.t
    y = crane.drive(3.0, 0.1)
    assert crane.guard.verdict.level is Level.CLEAR and y[-1] > y[0] + 0.2


def test_states_of_its_own_name_or_not_finite_are_ignored_and_counted():
    g = guard()
    assert not g.heard('a', 0.0, 1.0, 0) and not g.heard('b', math.nan, 1.0, 0) and not g.heard('b', 2.0, 1.0, 0)
    assert g.ignored == 3 and g.heard('b', 1.0, 2.0, 0)


def test_a_crane_without_a_bridge_stands_at_its_offset_and_its_masses_widen_its_envelope():
    g = guard(offset=(0.5, 1.0), joints=('cart',))
    g.measured((0.0, 0.02), (0.01, 0.08))  # the load swung 8 cm towards +y
    g.heard('b', 1.4, 1.5, 0)
    stream = ReferenceStream(PERIOD, 0.3)
    g.watch(1, stream.sample(0), stream)
    assert (g.mine.low, g.mine.high) == pytest.approx((0.95, 1.13))
    assert g.verdict.level is Level.WARNING and g.verdict.gap == pytest.approx(1.4 - 1.13)


class Trajectory:
    """Crane a's streamer on explicit ticks in trajectory mode, the guard watching and its stop (``take_over``:
    what ``GuardStops`` would hand the stream, a ``StopTrajectory``) taken over as soon as it is asked."""

    def __init__(self, take_over):
        self.stream = ReferenceStream(PERIOD, (0.0, 0.0))
        self.woken = []
        self.guard = guard(wake=lambda: self.woken.append(self.tick))
        self.streamer = Streamer(self.stream, watches=(self.guard,))
        self.stream.on_accept = self.guard.accepted  # (as the node wires it)
        self.tick = 0
        assert self.streamer.start(EPOCH, lambda: self.tick)
        self.take_over = take_over

    def now(self):
        return EPOCH + self.tick * PERIOD

    def run(self, seconds):
        ys = []
        for _ in range(round(seconds * 1000)):
            if self.tick % 20 == 0:
                self.guard.heard('b', B_LOW, B_HIGH, self.now())
            ys.append(self.streamer.tick(self.tick, self.now()).position[1])
            if len(self.woken) and self.woken[-1] == self.tick:  # the guard's thread, at once
                assert self.take_over(self) is not None
            self.tick += 1
        return np.array(ys)


def bridge_move(goal, duration):
    t = np.linspace(0.0, duration, 11)
    p, v, a = quintic(0.0, goal, duration, t)
    zero = np.zeros_like(t)
    return t, *(np.column_stack([zero, x]) for x in (p, v, a))


def soft_stop(crane):
    """A stop that travels about as far as an NVF stop may from that speed (0.59 m/s): a braking ramp at 0.25
    m/s^2 (0.72 m, within the bound), taken over at the guard's latest."""
    now = crane.now() + round((GUARD_LEAD - 0.005) * S)
    return brake(crane.stream, lambda: now, 0.25, J)


def test_a_motion_towards_a_crane_is_stopped_once_and_ends_short_of_the_minimum_and_the_next_is_refused():
    crane = Trajectory(soft_stop)
    crane.stream.accept(*bridge_move(1.9, 6.0), EPOCH + 2 * MS, EPOCH)  # into b (peak 0.59 m/s)
    y = crane.run(8.0)
    assert len(crane.woken) == 1 and crane.guard.verdict.level is Level.STOP
    assert crane.stream.at_rest and FARTHEST - 0.15 < y[-1] <= FARTHEST and np.max(y) <= FARTHEST
    assert 'the runway guard stopped it: b, ' in crane.guard.reason
    # a trajectory towards b is refused naming it; one away is taken
    towards = bridge_move(0.05, 1.0)[1] + np.array([0.0, y[-1]])
    why = crane.guard.refusal(towards)
    assert why.startswith('the runway guard refuses motions towards b, ') and 'moves the bridge 0.05 m' in why
    away = bridge_move(-0.3, 1.0)[1] + np.array([0.0, y[-1]])
    assert crane.guard.refusal(away) == '' and crane.guard.reason == ''


def test_a_motion_away_from_a_crane_stopped_for_is_not_stopped():
    crane = Trajectory(lambda crane: pytest.fail('stopped'))
    crane.guard.guard.heard('b', Reach(B_LOW, B_HIGH), EPOCH)
    assert crane.guard.guard.check(Reach(1.71, 1.81), EPOCH).level is Level.STOP  # it was stopped for b: held
    crane.stream.hold_at((0.0, 1.68))  # within the minimum's hysteresis of b
    crane.stream.accept(*(c + np.array([0.0, 1.68]) if k == 1 else c for k, c in enumerate(bridge_move(-0.5, 2.0))),
                        EPOCH + 2 * MS, EPOCH)
    y = crane.run(2.5)
    assert crane.woken == [] and y[-1] == pytest.approx(1.18)
    assert crane.guard.verdict.level is Level.INFO  # and the way is clear once it is far enough


#: The stop worker's solvers, shared by the tests of its stops (the spatial crane's, warmed once).
SOLVERS = {}


def stop_solvers():
    from crane_planner.planning.dispatch import SolverCache
    from crane_planner.serving.stops import warmups
    if not SOLVERS:
        SOLVERS['cache'] = cache = SolverCache()
        for request in warmups(PARAMS, bridge=True):
            cache(request)
    return SOLVERS['cache']


@pytest.mark.parametrize('method, travel, duration', [('nvf', 1.9, 5.0), ('rvf', 1.0, 3.0), ('zv', 2.0, 3.5),
                                                      ('zvd', 1.0, 3.0)])
def test_the_stop_table_covers_every_stop_the_stop_worker_plans_within_the_lead(method, travel, duration):
    """A bridge motion accepted by the stream: from every decision (every 0.4 s, from before its start to its
    end) the table's reach covers where the stop the stop worker plans (``serving.stops``: NVF on the spatial
    crane, from the model's swing) ends, taking over at the earliest (``WAKE``) and the latest (the lead) the
    guard allows. The motion is followed exactly until then: the extrapolation at constant acceleration it
    replaces fell short by up to 0.19 m (RVF) and 0.2 m (ZV 2 m in 3.5 s)."""
    from crane_planner.planning.dispatch import plan
    from crane_planner.serving.stops import StopRequest
    from crane_planner.streaming.knots import knot_columns, knot_times
    from crane_planner.streaming.runway_guard import WAKE
    solvers = stop_solvers()
    p = plan(method, 0.0, duration, PARAMS, variational=solvers, bridge=travel)
    t = knot_times(p)
    stream = ReferenceStream(PERIOD, (0.0, 0.0))
    assert stream.start(EPOCH, lambda: 0)
    motion = stream.accept(t, *knot_columns(p, t, (0.0, 0.0)), EPOCH + S, EPOCH)
    lead = GUARD_LEAD + WAKE
    table = PlannedStop(first_period(PARAMS), D, J).table(motion, 1, lead)
    checked = 0
    for decision in np.arange(motion.start_ns - round(0.3 * S), motion.start_ns + round(duration * S), 0.4 * S):
        low, high = table.at(int(decision))
        for handover in (decision + WAKE * S, decision + lead * S):
            h = int(handover)
            if h >= motion.start_ns + round(duration * S) or h < motion.start_ns:
                continue  # (the motion ends, or has not started: at rest where it is)
            stop = StopRequest(JOINTS, motion.interps, motion.origin_ns, h, PARAMS)(solvers)
            end = float(stop.position[-1, 1])
            assert low - 1e-9 <= end <= high + 1e-9, (method, (decision - motion.start_ns) / S, end, low, high)
            checked += 1
    assert checked >= 2 * duration  # (the motion's decisions, not only its ends)
    assert table.at(motion.start_ns + round((duration + 1.0) * S)) == pytest.approx((travel, travel))


def stop_of(method):
    """A stop's trajectory as the stream would take it (a braking from 0.3 m/s), named ``method``."""
    return dataclasses.replace(braking_stop(np.array([[0.0, 1.0], [0.0, 0.3], [0.0, 0.0]]), 0, D, J), method=method)


def guard_stops(planned, ready=True):
    """``GuardStops`` woken once: what it said (warning, text) and whether it ran the ramp."""
    g, said, ramps = guard(), [], []
    g.reason = 'the runway guard stopped it: b'

    def ramp():
        ramps.append(threading.current_thread().name)
        return stop_of('braking ramp')
    stops = GuardStops(g, planned, ramp, lambda: ready, lambda warning, text: said.append((warning, text)))
    g.stopping = True
    g.wake()
    deadline = time.monotonic() + 5.0
    while not said and time.monotonic() < deadline:
        time.sleep(0.01)
    stops.close()
    assert g.stopping  # (the loop asks no other stop until the stream is at rest)
    return said, ramps


def test_the_guards_stop_is_the_planned_one_when_the_stop_worker_has_it_in_time():
    said, ramps = guard_stops(lambda: stop_of('nvf'))
    assert ramps == [] and said == [(False, 'the runway guard stopped it: b: stopping without swing at (0, 1.105) m '
                                           'in 0.7 s (nvf)')]


def test_without_the_planned_stop_in_time_the_guards_stop_is_the_braking_ramp_before_its_lead_has_passed():
    # the planned stop comes only once the guard has spoken: it cannot be in time, however the host is paused
    released = threading.Event()

    def slow():
        released.wait(10.0)
        return stop_of('nvf')
    try:
        said, ramps = guard_stops(slow)
    finally:
        released.set()
    assert ramps == ['runway-guard-stops']
    assert said == [(True, 'the runway guard stopped it: b: stopping along the axes\' braking ramp (no stop without '
                           'swing within 0.4 s) at (0, 1.105) m in 0.7 s (braking ramp)')]
    refused, ramps = guard_stops(lambda: (_ for _ in ()).throw(ValueError('the stop planner process is not ready')))
    assert ramps and 'braking ramp (the stop planner process is not ready)' in refused[0][1]
    not_ready, ramps = guard_stops(lambda: pytest.fail('asked'), ready=False)
    assert ramps and 'braking ramp (the stop planner cannot have it in time)' in not_ready[0][1]


def test_the_crane_follows_its_plan_while_its_girder_is_where_its_own_published_occupancy_puts_it():
    """``follows_plan`` (said on /runway/state; two such cranes are judged on their footprints): the streamed
    girder within 2 mm of its own occupancy at that instant (interpolated between its samples, held after its
    last); nothing published, or another place, is not following it."""
    g = guard()
    stream = ReferenceStream(PERIOD, (0.3, 1.0))
    start = EPOCH + S
    g.watch(start, stream.sample(0), stream)
    assert not g.follows_plan  # nothing of its own heard
    g.own(start, [0.0], [1.0])  # a hold where it stands
    g.watch(start, stream.sample(1), stream)
    assert g.follows_plan and (g.footprint.low, g.footprint.high) == pytest.approx((0.95, 1.05))
    g.own(start, [0.0, 0.5, 1.0], [0.5, 1.0, 1.5])  # a motion through 1.0 m at 0.5 s
    for at, follows in ((0.5, True), (0.4985, True), (0.497, False), (0.0, False), (2.0, False)):
        g.watch(start + round(at * S), stream.sample(2), stream)
        assert g.follows_plan is follows, at
    g.own(start, [0.0, 1.0], [1.5, 1.0])  # ended at 1.0 m: held there after its last sample
    g.watch(start + 5 * S, stream.sample(3), stream)
    assert g.follows_plan
