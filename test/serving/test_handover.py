"""The handover's timing (serving.handover) on a fake clock: its lead, its slack, a late plan planned again
further ahead, a handover the streamer did not take sent again, a cancel meanwhile, a late arrival, a start
already past."""
from types import SimpleNamespace

import pytest

from crane_planner.serving import handover
from crane_planner.serving.execution import Execution
from crane_planner.serving.moves import MoveError
from crane_planner.serving.transitions import Running
from crane_planner.streaming.reference_stream import MAX_HANDOVER_SHIFT
from serving.fake_clock import FakeClock

T0 = 20_000_000_000
MS = 1_000_000


def motion(duration=3.0, origin_ns=T0 - 1_000_000_000):
    return Running(('cart',), [0.0, duration], [[0.0], [0.3]], [[0.0], [0.0]], [[0.0], [0.0]], origin_ns)


def planner(clock, takes, duration=1.0):
    """make_plan taking ``takes[k]`` s of the clock on its k-th call; the handovers it was asked for."""
    asked = []

    def make(handover_ns, state):
        asked.append((clock(), handover_ns))
        clock.advance(takes[min(len(asked), len(takes)) - 1])
        return SimpleNamespace(duration=duration)

    return make, asked


def plan(clock, running, lead, make, **kwargs):
    return handover.plan_handover(clock, running, lead, make, lambda ns: ('state at', ns), timer=clock.timer, **kwargs)


def test_a_plan_within_its_lead_hands_over_lead_s_after_it_was_asked_for():
    clock = FakeClock(T0)
    make, asked = planner(clock, [0.002])
    done = plan(clock, motion(), 0.042, make)
    assert done.handover_ns == T0 + 42 * MS and done.state == ('state at', T0 + 42 * MS)
    assert asked == [(T0, T0 + 42 * MS)]


def test_a_late_plan_is_planned_again_further_ahead_with_a_longer_lead():
    clock, warnings = FakeClock(T0), []
    make, asked = planner(clock, [0.030, 0.002])  # planning took 30 ms of a 10 ms lead, then 2 ms
    done = plan(clock, motion(), 0.010, make, warn=warnings.append)
    assert len(asked) == 2 and len(warnings) == 1 and 'planning took 30.0 ms' in warnings[0]
    second_lead = (asked[1][1] - asked[1][0]) * 1e-9
    assert second_lead == pytest.approx(max(2 * 0.010, 1.5 * 0.030 + handover.TRANSPORT_MARGIN))  # the lead grew
    assert done.handover_ns == asked[1][1] and clock() < done.handover_ns
    assert done.lead == pytest.approx(second_lead)  # (which a retry of it starts from: HandoverPolicy)


def test_planning_always_longer_than_the_lead_is_refused_after_its_attempts():
    clock = FakeClock(T0)
    make, asked = planner(clock, [1.0, 3.0, 10.0])  # each beyond its lead, the lead growing each time
    with pytest.raises(MoveError, match='3 times .* raise handover_lead') as refusal:
        plan(clock, motion(duration=60.0), 0.010, make)
    assert len(asked) == 3
    last_lead = (asked[2][1] - asked[2][0]) * 1e-9  # the lead of the third attempt, which the refusal names
    assert f'last lead {last_lead:.3f} s' in str(refusal.value)


def test_a_rehearsal_is_planned_once_however_long_it_takes():
    clock = FakeClock(T0)
    make, asked = planner(clock, [1.0])
    assert plan(clock, motion(duration=60.0), 0.010, make, rehearse=True).handover_ns == T0 + 10 * MS
    assert len(asked) == 1


def test_the_slack_keeps_the_transports_share_unless_the_plan_outlasts_the_motion():
    # a short lead (a shaper's 1 ms): 40 % of it is the transport's; a plan done in 0.7 ms is too late
    clock = FakeClock(T0)
    make, asked = planner(clock, [0.0007, 0.0001], duration=1.0)
    plan(clock, motion(duration=3.0), 0.001, make)
    assert len(asked) == 2
    # a plan ending after the running motion may arrive late, up to half the streamer's shift
    clock = FakeClock(T0)
    make, asked = planner(clock, [0.001 + 0.4 * MAX_HANDOVER_SHIFT], duration=5.0)
    plan(clock, motion(duration=3.0), 0.001, make)
    assert len(asked) == 1


def test_no_handover_once_the_motion_would_have_ended():
    clock = FakeClock(T0)
    make, asked = planner(clock, [0.0])
    assert plan(clock, motion(duration=1.01), 0.042, make) is None and asked == []


def test_a_late_arrival_counts_the_lead_from_the_arrival_but_keeps_half_of_it():
    assert handover.arrival_lead(0.042, None, T0) == 0.042
    assert handover.arrival_lead(0.042, T0 - 10 * MS, T0) == pytest.approx(0.032)
    assert handover.arrival_lead(0.042, T0 - 40 * MS, T0) == pytest.approx(0.021)


def test_a_goal_is_held_for_its_lead_and_one_whose_start_passed_streams_from_the_next_tick():
    assert handover.send_at(0, 0.3) == 0  # as soon as possible: at once
    assert handover.send_at(T0, 0.3) == T0 - 300 * MS
    assert handover.streamed_origin(T0, T0 - 1) == T0
    # its origin: stream_state's
    assert handover.streamed_origin(T0, T0) == 0 and handover.streamed_origin(T0, T0 + 5 * MS) == 0


def streamer(clock, execution, takes_at=None, duration=1.0):
    """A fake streamer's stream_state every 20 ms: it takes the motion at ``takes_at`` (ns; None: never)."""
    def tick(now):
        if now % (20 * MS) < 2 * MS:
            started = takes_at is not None and now >= takes_at
            execution.on_stream_state(now, takes_at if started else T0 - 10**9, duration if started else 3.0)
    clock.hooks.append(tick)
    return tick


def test_taken_once_the_streamer_streams_it_and_refused_once_its_clock_passed_the_handover():
    clock = FakeClock(T0)
    execution = Execution(1.0, 1.0, T0 + 10 * MS, 0.6, 0.2)
    streamer(clock, execution, takes_at=T0 + 20 * MS)
    assert handover.taken(execution, T0 + 10 * MS, sleep=clock.sleep, timer=clock.timer) is handover.Verdict.TAKEN
    clock = FakeClock(T0)
    execution = Execution(1.0, 1.0, T0 + 10 * MS, 0.6, 0.2)
    streamer(clock, execution)
    verdict = handover.taken(execution, T0 + 10 * MS, sleep=clock.sleep, timer=clock.timer)
    assert verdict is handover.Verdict.REFUSED
    assert clock() - T0 <= 100 * MS  # its stream_state passed the handover by 50 ms: no longer wait


def test_a_handover_planned_far_ahead_is_judged_by_the_streamers_clock_not_by_a_fixed_wait():
    """A retry's handover lies 0.67 s ahead: the streamer takes it only then, and says so only then."""
    clock = FakeClock(T0)
    at = T0 + 672 * MS
    execution = Execution(1.0, 1.0, at, 0.6, 0.2)
    streamer(clock, execution, takes_at=at)
    assert handover.taken(execution, at, silence=0.5, sleep=clock.sleep, timer=clock.timer) is handover.Verdict.TAKEN
    assert clock() >= at


def test_a_silent_stream_state_leaves_a_handover_unknown_and_the_policy_sends_no_more():
    clock = FakeClock(T0)  # no stream_state at all
    verdict = handover.taken(Execution(1.0, 1.0, T0, 0.6, 0.2), T0, silence=0.5, sleep=clock.sleep, timer=clock.timer)
    assert verdict is handover.Verdict.SILENT and clock() - T0 == pytest.approx(500 * MS, abs=3 * MS)
    calls = []

    def send(lead_scale, first):
        calls.append(lead_scale)
        return handover.Sent(SimpleNamespace(handover_ns=clock() + MS), Execution(1.0, 1.0, clock() + MS, 0.6, 0.2))

    with pytest.raises(ValueError, match='no stream_state for 0.5 s'):
        handover.HandoverPolicy(send, clock.sleep, clock.timer, silence=0.5).run()
    assert calls == [1.0]


class Sender:
    """A goal's handovers sent: the k-th is taken by the fake streamer if ``taken[k]``."""

    def __init__(self, clock, taken, growth=None):
        self.clock, self.taken, self.calls = clock, taken, []
        self.growth = growth or [1.0] * len(taken)  # the k-th one's lead over the one asked for
        self.streamer = None

    def __call__(self, lead_scale, first):
        self.calls.append((lead_scale, first))
        at = self.clock() + round(0.001 * lead_scale * 1e9)
        execution = Execution(1.0, 1.0, at, 0.6, 0.2)
        if self.streamer is not None:
            self.clock.hooks.remove(self.streamer)
        self.streamer = streamer(self.clock, execution, at if self.taken[len(self.calls) - 1] else None)
        return handover.Sent(SimpleNamespace(handover_ns=at, lead_growth=self.growth[len(self.calls) - 1]), execution)


def test_a_handover_the_streamer_did_not_take_is_sent_again_four_times_further_ahead():
    clock, warnings, planned = FakeClock(T0), [], []
    send = Sender(clock, [False, True])
    policy = handover.HandoverPolicy(send, clock.sleep, clock.timer, warn=warnings.append)
    result = policy.run(planned=planned.append)
    assert send.calls == [(1.0, True), (4.0, False)] and len(warnings) == 1 and '4 times further' in warnings[0]
    assert len(planned) == 1 and result is not None


def test_a_handover_whose_planning_needed_a_longer_lead_is_sent_again_half_as_far_again_as_that():
    """Planned 19 times further ahead than asked (planning took that long) and not taken all the same (its
    transport came late): four times the lead asked for would be doomed, half as far again as it needed is
    not."""
    clock, warnings = FakeClock(T0), []
    send = Sender(clock, [False, True], growth=[19.0, 1.0])
    assert handover.HandoverPolicy(send, clock.sleep, clock.timer, warn=warnings.append).run() is not None
    assert send.calls == [(1.0, True), (28.5, False)] and '28.5 times further' in warnings[0]


def test_a_handover_never_taken_gives_up_after_the_attempts():
    clock = FakeClock(T0)
    send = Sender(clock, [False] * 3)
    assert handover.HandoverPolicy(send, clock.sleep, clock.timer).run() is None
    assert [c[0] for c in send.calls] == [1.0, 4.0, 16.0]


def test_the_first_handover_sent_on_arrival_is_not_sent_again():
    clock = FakeClock(T0)
    send = Sender(clock, [True])
    first = send(1.0, True)
    policy = handover.HandoverPolicy(send, clock.sleep, clock.timer)
    assert policy.run(first) is first.result and len(send.calls) == 1


def test_a_cancel_during_a_handover_retry_sends_nothing_more():
    clock = FakeClock(T0)
    send = Sender(clock, [False, True])
    canceled = []
    clock.hooks.append(lambda now: canceled.append(True) if now > T0 + 30 * MS else None)
    policy = handover.HandoverPolicy(send, clock.sleep, clock.timer)
    with pytest.raises(handover.NotSent, match='canceled'):
        policy.run(canceled=lambda: bool(canceled))
    assert send.calls == [(1.0, True)]


def test_the_next_handover_of_a_kind_starts_from_a_lead_its_recent_planning_fits():
    """A kind whose plan took 30 ms of a 10 ms lead: its next handover is planned once, 1.5 times that (and
    the transport's margin) ahead, with no warning; another kind keeps the lead asked for; a lead asked for
    that is longer already is kept."""
    clock, warnings, times = FakeClock(T0), [], handover.PlanningTimes()
    make, asked = planner(clock, [0.030, 0.030, 0.030, 0.002])
    plan(clock, motion(), 0.010, make, warn=warnings.append, times=times, kind='spatial nvf')
    assert len(asked) == 2 and len(warnings) == 1  # the first time: planned again further ahead
    fitted = 1.5 * 0.030 + handover.TRANSPORT_MARGIN
    done = plan(clock, motion(), 0.010, make, warn=warnings.append, times=times, kind='spatial nvf')
    assert len(asked) == 3 and len(warnings) == 1
    assert (asked[2][1] - asked[2][0]) * 1e-9 == pytest.approx(fitted) and done.lead == pytest.approx(fitted)
    other = plan(clock, motion(), 0.010, make, times=times, kind='cart nvf')
    assert (asked[3][1] - asked[3][0]) * 1e-9 == pytest.approx(0.010) and other.lead == pytest.approx(0.010)
    assert times.lead('spatial nvf', 0.5) == 0.5


def test_planning_times_keep_the_latest_few_of_each_kind():
    times = handover.PlanningTimes(kept=2)
    assert times.lead('a', 0.042) == 0.042  # nothing recorded
    for took in (0.2, 0.05, 0.04):
        times.record('a', took)
    assert times.lead('a', 0.042) == pytest.approx(1.5 * 0.05 + handover.TRANSPORT_MARGIN)  # 0.2 forgotten
    times.record('b', 0.001)
    assert times.lead('b', 0.042) == 0.042  # fast plans never shorten the lead asked for
