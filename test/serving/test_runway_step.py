"""The planner's side of a shared runway (serving.runway_step) through the goal service, on the fake clock and a
fake streamer of a crane with a bridge: a goal that would meet another crane's published motion starts later by the
least delay (its preview says the same), ``refuse`` names the crane, a motion published earlier heard during the
claim window moves the goal later (first published, first served) and one published later does not, holds are
published where the streamer holds, and with ``runway`` off nothing is. The other cranes are occupancies made
here; every distance is checked again every millisecond, apart from the samples the schedule used."""
from types import SimpleNamespace

import numpy as np
import pytest

from crane_msgs_py.crane.params import CraneParams
from crane_planner.planning.dispatch import plan
from crane_planner.runway.guard import PLAN_MARGIN
from crane_planner.runway.occupancy import Footprint, Shape, closest, holding, separation
from crane_planner.runway.prediction import plan_occupancy
from crane_planner.runway.schedule import DELAY_STEP, required
from crane_planner.serving.config import PARAMETERS, Config
from crane_planner.serving.crane_view import StreamSample
from crane_planner.serving.goals import GoalState
from crane_planner.serving.moves import Move, summarize
from crane_planner.serving.runway_step import (
    MIN_CLAIM_WINDOW,
    IllegalTransition,
    Published,
    RunwayConflict,
    RunwayStep,
    startup_conflict,
)
from serving.fake_crane import MS, T0, Crane, FakePlanner

P = CraneParams()
SHAPE = Shape()
SECOND = 1_000_000_000
#: Two cranes 2 m apart; each bridge goes 0.76 m towards the other by ZV in 1.4 s: the final gap (0.38 m less
#: the girders' half-widths) clears 0.2 m, but the loads lead by up to 0.2 m as they brake (offline numbers).
#: (ZV this fast leaves the loads swinging by 5 cm on the planning model, which the occupancies' discs grow by:
#: in 1.3 s, 12 cm each, and the two loads would meet for good.)
D, T = 0.755, 1.4


class BridgePlanner(FakePlanner):
    def plan(self, method, displacement, duration, params=None, options=None, hoist=None, bridge=None):
        return plan(method, displacement, duration, params, options, bridge=bridge)


class BridgeCrane(Crane):
    """The fake crane with joints [cart, bridge] on a runway (``published``: its occupancies)."""

    def __init__(self, runway=True, **parameters):
        self.bridge, self.occupancies = 0.0, []
        super().__init__(planner=BridgePlanner(), joints=['cart', 'bridge'], runway=runway, crane_name='crane_a',
                         **parameters)
        self.step = RunwayStep(lambda: self.config, self.clock, self.occupancies.append)
        self.service.serving.runway = self.service.runway = self.step
        self.tick(self.clock())

    def tick(self, now):
        if self.pending is not None and now >= self.pending.start:
            self.current, self.pending = self.pending, None
        m = self.current
        if m is not None and now >= m.start + round(m.duration * 1e9):
            ends = [s0 + s.position[-1] for s0, s in zip(m.trajectory.starts, m.trajectory.samples)]
            self.hold, self.bridge = float(ends[0]), float(ends[1])
        if now >= self.next_state and hasattr(self, 'step'):
            self.next_state = now + 20 * MS
            streaming = m is not None and now < m.start + round(m.duration * 1e9)
            self.service.on_stream_state(StreamSample(now, 'streaming' if streaming else 'holding',
                                                      {'cart': self.hold, 'bridge': self.bridge},
                                                      m.start if m else 0, m.duration if m else 0.0,
                                                      m.origin if m else 0))

    def claims(self):
        return [o for o in self.occupancies if len(o.t) > 1]

    def holds(self):
        return [o for o in self.occupancies if len(o.t) == 1]


def towards_b(start_ns=0, method='zv'):
    return Move(method, joint_names=('bridge',), goal=(D,), duration=T, start_ns=start_ns)


def crane_b_moving(start_ns, published_ns):
    """Crane b, 2 m along the runway, going 0.755 m towards a by ZV in 1.4 s from ``start_ns``."""
    return plan_occupancy('crane_b', plan('zv', 0.0, T, P, bridge=-D), P, {'cart': 0.0, 'bridge': 0.0}, (0.0, 2.0),
                          start_ns, published_ns, SHAPE, settle=1.0)


def crane_b_holding(published_ns=T0 - SECOND):
    return holding('crane_b', published_ns, Footprint.at_rest(2.0, 0.0), SHAPE)


def dense_min_distance(a, b):
    stamps = np.arange(min(a.start_ns, b.start_ns), max(a.end_ns, b.end_ns) + 1, MS)
    return float(separation(a.at(stamps), a.shape, b.at(stamps), b.shape).min())


def test_with_runway_off_nothing_is_published_and_a_goal_starts_when_asked():
    crane = BridgeCrane(runway=False)
    crane.step.book.heard(crane_b_moving(T0 + SECOND, T0 - MS))
    planned = crane.service.plan(towards_b(T0 + SECOND), 'plan_move')
    assert planned.placement is None and planned.trajectory.stamp_ns == T0 + SECOND
    goal = crane.goal('a', towards_b(T0 + SECOND))
    outcome, _ = crane.execute(goal, towards_b(T0 + SECOND))
    assert outcome.success, outcome.message
    assert crane.occupancies == [] and crane.published[0][1].stamp_ns == T0 + SECOND


def test_a_goal_that_would_meet_another_crane_s_motion_waits_the_least_delay_its_preview_says_the_same():
    crane = BridgeCrane()
    b = crane_b_moving(T0 + SECOND, T0 - MS)
    crane.step.book.heard(b)
    start = T0 + SECOND
    preview = crane.service.plan(towards_b(start), 'plan_move')
    info = summarize(preview.plan, preview.checked.joints)
    assert info.runway_waited_for == 'crane_b' and info.runway_delay > 0.3
    assert preview.trajectory.stamp_ns == start + round(info.runway_delay * 1e9)
    assert crane.claims() == []  # a preview publishes nothing
    goal = crane.goal('a', towards_b(start))
    outcome, _ = crane.execute(goal, towards_b(start))
    assert outcome.success, outcome.message
    [claim] = crane.claims()
    sent_at, trajectory = crane.published[0]
    assert trajectory.stamp_ns == claim.start_ns == preview.trajectory.stamp_ns  # the same delay as previewed
    assert summarize(outcome.plan.plan, outcome.plan.checked.joints).runway_delay == pytest.approx(info.runway_delay)
    assert trajectory.stamp_ns - sent_at == pytest.approx(300 * MS, abs=25 * MS)  # sent publish_lead ahead
    # clear every millisecond by the minimum and the planner's margin (the guard's, for its live estimates)
    assert dense_min_distance(claim, b) >= 0.2 + PLAN_MARGIN
    # and a step earlier it would not be, by the samples' check the planner makes (which leaves room for what lies
    # between them: runway.schedule.required)
    earlier = claim.delayed(-DELAY_STEP)
    assert closest(earlier, b).distance < required(earlier, b, 0.2 + PLAN_MARGIN)
    assert dense_min_distance(claim.delayed(-info.runway_delay), b) < 0.19  # as asked: the loads would meet
    # ended: a hold where the streamer holds, at the goal, published after the claim
    crane.clock.sleep(0.05)
    assert crane.holds()[-1].footprint.girder[0] == pytest.approx(D)
    assert crane.occupancies.index(crane.holds()[-1]) > crane.occupancies.index(claim)


def test_the_refuse_policy_refuses_naming_the_crane_as_a_preview_and_as_a_goal():
    crane = BridgeCrane(runway_policy='refuse')
    crane.step.book.heard(crane_b_moving(T0 + SECOND, T0 - MS))
    with pytest.raises(RunwayConflict, match=r"^runway: the move would come within 0\.\d+ m of crane 'crane_b' "
                                             r'\(runway_min_distance 0\.2 m and a margin of 0\.02 m\): '
                                             r'refused$') as refused:
        crane.service.plan(towards_b(T0 + SECOND), 'plan_move')
    assert refused.value.crane == 'crane_b'
    goal = crane.goal('a', towards_b(T0 + SECOND))
    outcome, _ = crane.execute(goal, towards_b(T0 + SECOND))
    assert outcome.how == 'abort' and "crane 'crane_b'" in outcome.message and crane.published == []
    assert crane.claims() == []


def crane_b_leaving(start_ns, published_ns):
    """Crane b from 0.25 m beyond a's goal (a's girder would come within 0.15 m of it), 0.8 m away in 4 s."""
    return plan_occupancy('crane_b', plan('zv', 0.0, 4.0, P, bridge=0.8), P, {'cart': 0.0, 'bridge': 0.0},
                          (0.0, D + 0.25), start_ns, published_ns, SHAPE, settle=1.0)


def test_a_goal_that_a_crane_holding_still_blocks_waits_for_its_motion_a_while_then_is_refused_naming_it():
    """b holds where a's goal would end: a preview is refused at once; a goal is placed again for as long as a
    planner may plan and a claim window (b may be sending a motion out of the way), then refused naming b, nothing
    published nor sent."""
    crane = BridgeCrane()
    crane.step.book.heard(holding('crane_b', T0 - SECOND, Footprint.at_rest(D + 0.25, 0.0), SHAPE))
    with pytest.raises(RunwayConflict, match="crane 'crane_b'.*no start within"):
        crane.service.plan(towards_b(T0 + SECOND), 'plan_move')
    goal = crane.goal('a', towards_b(T0 + SECOND))
    outcome, _ = crane.execute(goal, towards_b(T0 + SECOND))
    assert outcome.how == 'abort' and "crane 'crane_b'" in outcome.message and 'no start within' in outcome.message
    waited = crane.config.options.max_solve_time + crane.config.publish_lead  # (a planner's planning, a claim)
    assert crane.clock() - T0 == pytest.approx(waited * 1e9, abs=60 * MS)
    assert crane.claims() == [] and crane.published == []


def test_a_goal_that_a_crane_holding_still_blocks_follows_it_once_its_motion_out_of_the_way_is_heard():
    """Sent together, a's goal into the space b leaves: placed against b's hold it is blocked; b's motion, heard
    100 ms later, makes room: a waits behind it, the least delay, and says so."""
    crane = BridgeCrane()
    crane.step.book.heard(holding('crane_b', T0 - SECOND, Footprint.at_rest(D + 0.25, 0.0), SHAPE))
    start = T0 + SECOND
    b = crane_b_leaving(start, T0 + 50 * MS)
    crane.at(T0 + 100 * MS, lambda: crane.step.book.heard(b))
    goal = crane.goal('a', towards_b(start))
    outcome, _ = crane.execute(goal, towards_b(start))
    assert outcome.success, outcome.message
    [claim] = crane.claims()
    info = summarize(outcome.plan.plan, outcome.plan.checked.joints)
    assert info.runway_waited_for == 'crane_b' and info.runway_delay >= 0.1
    assert crane.published[0][1].stamp_ns == claim.start_ns == start + round(info.runway_delay * 1e9)
    assert dense_min_distance(claim, b) >= 0.2 and dense_min_distance(claim.delayed(-info.runway_delay), b) < 0.2


def test_a_motion_published_before_the_claim_heard_in_its_window_moves_the_goal_later_one_published_after_not():
    """Both cranes plan at once, each against the other's hold: b's motion, published 1 ms before a's claim,
    reaches a during a's claim window: a is placed again after it and published again (its stamp kept); the
    trajectory goes with the new stamp. The same motion published 1 ms after a's claim changes nothing: a's
    goal is b's to avoid."""
    start = T0 + SECOND
    for published, moved in ((T0 - MS, True), (T0 + MS, False)):
        crane = BridgeCrane()
        crane.step.book.heard(crane_b_holding())
        b = crane_b_moving(start, published)
        crane.at(T0 + 100 * MS, lambda: crane.step.book.heard(b))
        goal = crane.goal('a', towards_b(start))
        outcome, _ = crane.execute(goal, towards_b(start))
        assert outcome.success, outcome.message
        claims = crane.claims()
        assert claims[0].start_ns == start and claims[0].published_ns == T0  # first placed against b's hold
        trajectory = crane.published[0][1]
        info = summarize(outcome.plan.plan, outcome.plan.checked.joints)
        if moved:
            assert len(claims) == 2 and claims[1].published_ns == claims[0].published_ns
            assert trajectory.stamp_ns == claims[1].start_ns > start and dense_min_distance(claims[1], b) >= 0.2
            assert info.runway_waited_for == 'crane_b' and info.runway_delay == pytest.approx(
                (claims[1].start_ns - start) * 1e-9)
            assert any('another crane published first' in line for _, line in crane.log.lines)
        else:
            assert len(claims) == 1 and trajectory.stamp_ns == start and info.runway_delay == 0.0


def test_a_goal_as_soon_as_possible_starts_after_the_claim_window_and_publish_lead():
    crane = BridgeCrane()
    goal = crane.goal('a', towards_b())
    outcome, _ = crane.execute(goal, towards_b())
    assert outcome.success, outcome.message
    [claim] = crane.claims()
    lead = crane.config.publish_lead
    assert claim.start_ns - claim.published_ns == pytest.approx(2 * lead * 1e9, abs=5 * MS)  # window 0.3 + lead 0.3
    assert crane.published[0][0] - claim.published_ns >= round(max(lead, MIN_CLAIM_WINDOW) * 1e9) - 5 * MS
    assert summarize(outcome.plan.plan, outcome.plan.checked.joints).runway_delay == 0.0


def test_holds_are_published_once_per_place_and_not_over_a_claim():
    crane = BridgeCrane(runway_offset=[0.5, 3.0])
    [first] = crane.holds()  # at start-up, once the streamer holds
    assert first.footprint.girder[0] == 3.0 and first.footprint.masses[0, 1].tolist() == [0.5, 3.0]
    crane.clock.sleep(0.2)  # ten stream_states more, the same place
    assert crane.holds() == [first] and crane.step.state is Published.HOLD
    goal = crane.goal('a', towards_b(T0 + SECOND))
    crane.execute(goal, towards_b(T0 + SECOND))
    crane.clock.sleep(0.05)
    kinds = ['hold' if len(o.t) == 1 else 'motion' for o in crane.occupancies]
    assert kinds == ['hold', 'motion', 'hold']  # none while claimed or moving
    assert crane.occupancies[-1].footprint.girder[0] == pytest.approx(3.0 + D)


def test_what_is_published_changes_only_as_its_transitions_allow():
    step = RunwayStep(lambda: SimpleNamespace(runway=SimpleNamespace(on=True)), lambda: T0, lambda o: None)
    with pytest.raises(IllegalTransition, match='nothing -> released'):
        step._change(Published.RELEASED)


class StopFollowing(Exception):
    pass


def bridge_motion_until(crane, ns, goal=0.6, duration=3.0):
    """A ZV goal of the bridge to ``goal`` streaming, left at ``ns`` (its follower stopped there)."""
    first = Move('zv', joint_names=('bridge',), goal=(goal,), duration=duration)
    old = crane.goal('old', first)

    def stop_following():
        raise StopFollowing()
    crane.at(ns, stop_following)
    with pytest.raises(StopFollowing):
        crane.execute(old, first)
    return old


def streamed_bridge(trajectory):
    """(ROS times ns, the bridge's positions m) at a trajectory's knots."""
    bridge = trajectory.samples[1]
    return trajectory.stamp_ns + np.round(np.asarray(bridge.t) * 1e9).astype(np.int64), \
        trajectory.starts[1] + np.asarray(bridge.position)


def assert_published_as_streamed(crane, first, second):
    """``second`` (a motion sent from a state) is ``first`` from when it was sent until its handover, then the
    handover's trajectory: its girder where the bridge streams, its masses going on from where ``first`` had
    them."""
    trajectory = crane.published[-1][1]
    handover = trajectory.stamp_ns
    # from the first's last sample before it was sent (the past dropped: a chain of them does not grow)
    assert second.published_ns > first.published_ns
    assert 0 <= second.published_ns - second.start_ns < 20 * MS and second.start_ns >= first.start_ns
    before = np.arange(second.start_ns, handover, 5 * MS)
    assert second.at(before).girder == pytest.approx(first.at(before).girder, abs=1e-9)
    stamps, bridge = streamed_bridge(trajectory)
    assert second.at(stamps).girder == pytest.approx(bridge, abs=2e-4)  # (its 20 ms samples, linear between)
    # the swing at the handover predicted from there on (not from rest): where the first motion had the masses
    assert np.abs(second.at([handover + 20 * MS]).masses - first.at([handover + 20 * MS]).masses).max() < 1e-3


def test_a_goal_during_a_motion_is_published_from_its_handover_on_after_the_motion_it_takes_over():
    crane = BridgeCrane()
    bridge_motion_until(crane, T0 + 1_600 * MS)
    new = Move('zv', joint_names=('bridge',), goal=(0.3,), duration=3.0)
    goal = crane.goal('new', new)  # (a shaper's: handed over on arrival)
    outcome, _ = crane.execute(goal, new)
    assert outcome.success and 'taking over the motion' in outcome.message
    crane.clock.sleep(0.05)
    kinds = ['hold' if len(o.t) == 1 else 'motion' for o in crane.occupancies]
    assert kinds == ['hold', 'motion', 'motion', 'hold']
    first, second = crane.claims()
    assert_published_as_streamed(crane, first, second)
    assert second.footprint.girder[-1] == pytest.approx(0.3)
    assert crane.holds()[-1].footprint.girder[0] == pytest.approx(0.3)


def test_a_cancels_stop_is_published_and_the_hold_where_it_stopped():
    crane = BridgeCrane()
    first = Move('zv', joint_names=('bridge',), goal=(0.6,), duration=3.0)
    goal = crane.goal('a', first)
    canceled = []
    crane.at(T0 + 1_600 * MS, lambda: canceled.append(True))
    outcome, _ = crane.execute(goal, first, canceled=lambda: bool(canceled))
    assert outcome.how == 'cancel' and 'stopped at' in outcome.message
    crane.clock.sleep(0.05)
    motion, stop = crane.claims()
    assert_published_as_streamed(crane, motion, stop)
    assert stop.footprint.girder[-1] == pytest.approx(crane.bridge) and 0.1 < crane.bridge < 0.6
    assert crane.holds()[-1].footprint.girder[0] == pytest.approx(crane.bridge)


def config(**values):
    defaults = {name: default for name, (default, _, _) in PARAMETERS.items()}
    return Config.from_values({**defaults, 'runway': True, 'crane_name': 'crane_b', **values})


@pytest.mark.parametrize('offset, refused', [([0.0, 0.25], True), ([0.0, 0.31], False), ([4.0, -0.2], True)])
def test_a_runway_offset_that_puts_the_girder_too_near_another_s_is_refused_naming_both(offset, refused):
    a = holding('crane_a', T0, Footprint.at_rest(0.0, 0.0), SHAPE)
    why = startup_conflict(config(runway_offset=offset), [a], 0.0, T0)
    if refused:
        assert why.startswith(f'runway_offset {offset}: crane \'crane_b\'\'s girder at y {offset[1]:g} m would be ')
        assert "from crane 'crane_a''s at y 0 m, closer than runway_min_distance 0.2 m" in why
    else:
        assert why is None


def test_a_crane_holding_in_the_way_heard_during_the_claim_window_aborts_the_goal_naming_it():
    """A crane that holds (heard during the window: its stop) where a's goal would end: no start keeps clear,
    a's goal is aborted naming it, nothing streamed, and a hold is published again."""
    crane = BridgeCrane()
    start = T0 + SECOND
    crane.at(T0 + 100 * MS, lambda: crane.step.book.heard(
        holding('crane_b', T0 + 100 * MS, Footprint.at_rest(1.0, 0.0), SHAPE)))
    goal = crane.goal('a', towards_b(start))
    outcome, _ = crane.execute(goal, towards_b(start))
    assert outcome.how == 'abort' and "crane 'crane_b'" in outcome.message and crane.published == []
    assert goal.history[-1] is GoalState.HELD and goal.state is GoalState.ENDED
    crane.clock.sleep(0.05)
    assert crane.step.state is Published.HOLD and len(crane.holds()) == 2


def test_a_motion_from_a_state_sent_while_a_goal_waits_in_its_claim_window_leaves_that_claim_published():
    """A settle (a motion no goal ends) sent while a goal is held for its start: the goal's claim stands (its
    motion is what the other cranes plan around; the settle is judged by its envelope), and the goal's motion
    is published and followed as claimed."""
    from crane_planner.planning.continuation import AxisState, MotionState
    from crane_planner.planning.signals import Swing
    crane = BridgeCrane()
    start = T0 + 2 * SECOND
    goal = crane.goal('a', towards_b(start))
    settle = plan('nvf', 0.0, 1.0, P, bridge=0.0)
    at_rest = MotionState({'cart': AxisState(0.0), 'bridge': AxisState(0.0)}, Swing.rest(spatial=True))
    answers = []
    crane.at(start - SECOND, lambda: answers.append(crane.step.moving(object(), settle, at_rest,
                                                                      crane.clock() + 100 * MS, 1.0)))
    outcome, _ = crane.execute(goal, towards_b(start))
    assert outcome.success and answers == [None]
    crane.clock.sleep(0.05)
    assert ['hold' if len(o.t) == 1 else 'motion' for o in crane.occupancies] == ['hold', 'motion', 'hold']
