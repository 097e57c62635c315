"""serving.execution: an executed move followed by the streamer's clock and the measured angles.

The swing is checked against the load excursion computed here from Fig. 1
(x_cart - x_m2 = L1 sin th1 + L2 sin(th1 + th2)), not against the module's own helper.
"""
import math

import numpy as np
import pytest

from crane_planner.serving.execution import DONE, FAILED, MOVING, SETTLING, WAITING, Execution

L1, L2 = 0.47, 0.391
S = 1_000_000_000  # ns per s
START = 100 * S


def excursion(th1, th2):
    return L1 * math.sin(th1) + L2 * math.sin(th1 + th2)


def execution(**kw):
    return Execution(duration=3.0, settle=2.0, start_ns=START, L1=L1, L2=L2, **kw)


def test_progress_follows_the_streamers_clock_from_the_motions_first_tick():
    ex = execution()
    assert ex.phase(START) == WAITING and ex.progress == 0.0
    late = START + 2_000_000  # the streamer shifted the start by 2 ms (it came late)
    for k in range(0, 3001, 20):
        ex.on_stream_state(late + k * 1_000_000, late, 3.0)
        assert ex.progress == pytest.approx(k / 3000, abs=1e-12)
        assert ex.time_remaining == pytest.approx(3.0 - k * 1e-3, abs=1e-9)
    assert ex.motion_start_ns == late and ex.end_ns == late + 3 * S
    assert ex.phase(0) == SETTLING


def test_the_streamers_origin_of_the_motion_is_kept_with_its_start():
    on_time, late = execution(), execution()
    on_time.on_stream_state(START + 400_000, START + 400_000, 3.0, START)  # first tick 0.4 ms after the stamp
    late.on_stream_state(START + 8 * 1_000_000, START + 8 * 1_000_000, 3.0, START + 8 * 1_000_000)
    assert (on_time.motion_start_ns, on_time.motion_origin_ns) == (START + 400_000, START)
    assert late.motion_origin_ns == START + 8 * 1_000_000  # it came late: its time counts from its first tick
    unsaid = execution()
    unsaid.on_stream_state(START, START, 3.0)
    assert unsaid.motion_origin_ns == START


def test_another_motion_on_the_stream_is_not_taken_for_this_one():
    ex = execution()
    ex.on_stream_state(START - S, START - 5 * S, 3.0)  # an earlier motion, still the last one
    ex.on_stream_state(START + S, START + 10_000_000, 2.5)  # someone else's, of another duration
    assert ex.motion_start_ns is None and ex.phase(START) == WAITING


def test_the_residual_is_the_peak_excursion_stamped_within_the_settle_window():
    ex = execution()
    ex.on_stream_state(START + 3 * S, START, 3.0)  # the motion has ended
    rng = np.random.default_rng(1)
    window = []
    for k in range(0, 301):  # joint_states every 20 ms from t = 0 to 6 s
        t = k * 0.02
        th1, th2 = rng.normal(0.0, 0.01, 2)
        ex.on_joint_state(START + round(t * S), th1, th2)
        assert ex.swing == pytest.approx(excursion(th1, th2), abs=1e-15)
        if 3.0 <= t <= 5.0 + 1e-9:
            window.append(abs(excursion(th1, th2)))
        if t < 5.0 - 1e-9:
            assert ex.phase(START + round(t * S)) in (MOVING, SETTLING)
    assert ex.phase(0) == DONE
    assert ex.residual == pytest.approx(max(window), abs=1e-15) and len(window) == 101


def test_without_joint_states_swing_and_residual_are_nan_and_the_stream_clock_closes_the_window():
    ex = execution()
    ex.on_stream_state(START + 4 * S, START, 3.0)
    assert ex.phase(START + 4 * S) == SETTLING and math.isnan(ex.swing)
    ex.on_stream_state(START + 5 * S, START, 3.0)
    assert ex.phase(START + 5 * S) == DONE and math.isnan(ex.residual)


def test_a_motion_the_streamer_never_streams_fails_naming_the_likely_cause():
    ex = execution()
    assert ex.phase(START + S // 2) == WAITING
    assert ex.phase(START + 2 * S) == FAILED and 'no stream_state' in ex.failure
    heard = execution()
    heard.on_stream_state(START + 2 * S, START - 5 * S, 1.0)  # heard, but not streaming ours
    assert heard.phase(START + 2 * S) == FAILED and 'refused' in heard.failure


def test_a_next_motion_ends_the_settle_window_at_its_start():
    ex = execution()
    ex.on_stream_state(START + 3 * S, START, 3.0)
    ex.cut(START + 4 * S)  # the next motion starts 1 s after this one's end
    ex.on_joint_state(START + 3 * S + S // 2, 0.0, 0.01)
    ex.on_joint_state(START + 4 * S + S // 2, 0.2, 0.0)  # after the cut: the next motion's swing
    assert ex.window_end_ns == START + 4 * S and ex.phase(0) == DONE
    assert ex.residual == pytest.approx(excursion(0.0, 0.01), abs=1e-15)


def streamed_to(ex, ms: int):
    """stream_state every 20 ms from the motion's start to ``ms``, the planner checking at each: its time (ns)."""
    for k in range(0, ms + 1, 20):
        ex.on_stream_state(START + k * 1_000_000, START, 3.0)
        assert ex.phase(START + k * 1_000_000) == MOVING
    return START + ms * 1_000_000


def looks(ex, since: int, step_ms: int, count: int) -> list:
    """The phases of ``count`` checks every ``step_ms`` after ``since``."""
    return [ex.phase(since + k * step_ms * 1_000_000) for k in range(1, count + 1)]


def test_a_stream_silent_during_the_motion_fails_it_naming_the_lost_stream():
    ex = execution(stream_timeout=1.0)
    last = streamed_to(ex, 1200)  # 40 % of the 3 s motion streamed, then nothing
    assert looks(ex, last, 50, 20) == [MOVING] * 20  # silent for exactly the timeout: not yet lost
    assert ex.phase(last + S + 1) == FAILED
    assert 'lost the reference stream at 40 %' in ex.failure and 'stream_state for 1.0 s' in ex.failure


def test_the_silence_counts_only_while_the_planner_looks():
    """A planner paused itself (its checks, every 50 ms, resume 1.5 s after the last) finds the newest
    stream_state old: what the streamer sent meanwhile may still wait in its queue, so of the pause only
    LOOK_GAP_NS (0.25 s) counts as silence."""
    ex = execution(stream_timeout=1.0)
    last = streamed_to(ex, 1200)
    resumed = last + 3 * S // 2
    assert ex.phase(resumed) == MOVING  # 1.5 s since the newest stream_state, the planner not looking
    # looking again every 50 ms and hearing nothing: lost once 0.75 s more are silent
    assert looks(ex, resumed, 50, 16) == [MOVING] * 15 + [FAILED]
    assert 'no stream_state for 2.3 s' in ex.failure  # the silence named is the stream's own
    queued = execution(stream_timeout=1.0)  # the same pause, then the queue delivers: the motion goes on
    last = streamed_to(queued, 1200)
    assert queued.phase(resumed) == MOVING
    queued.on_stream_state(last + 20_000_000, START, 3.0)  # sent during the pause, taken only now
    assert looks(queued, resumed, 50, 20) == [MOVING] * 20 and not queued.failure
    # then silent for the timeout, counted from the first check after that stream_state
    assert looks(queued, resumed + S, 50, 2) == [MOVING, FAILED]


def test_a_dead_stream_is_found_however_seldom_the_planner_looks():
    """Checks a second apart (a planner starved of CPU): each adds LOOK_GAP_NS of silence, so the goal still
    fails, after stream_timeout / 0.25 s of them."""
    ex = execution(stream_timeout=1.0)
    last = streamed_to(ex, 1200)
    assert looks(ex, last, 1000, 5) == [MOVING] * 4 + [FAILED]


def test_by_default_a_stall_the_streamer_catches_up_on_is_no_loss():
    """The streamer sends the ticks it missed, up to CATCH_UP (1 s) of them, after a stall: the default
    timeout waits longer than that, as the sim does."""
    from crane_planner.streaming.reference_stream import CATCH_UP
    ex = execution()
    assert ex.stream_timeout == 2.0 > CATCH_UP
    last = streamed_to(ex, 1200)
    assert looks(ex, last, 50, 20) == [MOVING] * 20  # a 1 s stall of the streamer
    ex.on_stream_state(last + 20_000_000, START, 3.0)  # then what it missed, at once
    assert ex.phase(last + S) == MOVING
    # and if it never comes back: lost 2 s after its last word
    assert looks(ex, last + S, 50, 41) == [MOVING] * 40 + [FAILED]


def test_a_silent_stream_after_the_motion_only_closes_the_settle_window():
    ex = execution(stream_timeout=0.5)
    ex.on_stream_state(START + 3 * S, START, 3.0)  # the motion's last tick, then the streamer is gone
    assert ex.phase(START + 4 * S) == SETTLING  # the settle window is timed, not failed
    assert ex.phase(START + 5 * S) == DONE and not ex.failure


def test_a_streamer_holding_before_the_motions_end_has_dropped_it():
    ex = execution()
    for k in range(0, 1201, 20):
        ex.on_stream_state(START + k * 1_000_000, START, 3.0)
    ex.on_stream_state(START + 1220 * 1_000_000, START, 3.0, streaming=False)  # a ~/stop, say
    assert ex.phase(START + 1221 * 1_000_000) == FAILED and 'stopped streaming the motion at 41 %' in ex.failure
    done = execution()
    done.on_stream_state(START + 2996 * 1_000_000, START, 3.0)
    done.on_stream_state(START + 2998 * 1_000_000, START, 3.0, streaming=False)  # its last tick: not dropped
    assert not done.failure


def test_a_motion_the_streamers_runway_guard_stopped_or_refused_fails_saying_which_crane_and_why():
    why = 'the runway guard stopped it: crane_b, 0.190 m between the stopping envelopes'
    ex = execution()
    ex.on_stream_state(START + 1200 * 1_000_000, START, 3.0)
    ex.on_stream_state(START + 1220 * 1_000_000, START, 3.0, streaming=False, reason=why)
    assert ex.phase(START + 1221 * 1_000_000) == FAILED
    assert ex.failure == f'the streamer stopped streaming the motion at 41 %: it holds ({why})'
    refused = execution()
    refused.on_stream_state(START + 2 * S, START - 5 * S, 1.0, reason='the runway guard refuses motions towards b')
    assert refused.phase(START + 2 * S) == FAILED
    assert refused.failure.endswith('(refused: the runway guard refuses motions towards b)')


def test_the_axes_fault_reaction_in_the_motion_fails_it_once_the_motion_has_streamed():
    """The sim braked at a gap mid-motion (axis_status fault_stopping stamped then) while the streamer streamed
    on to the motion's end, holding only after it: nothing was dropped, yet the crane stands elsewhere than the
    goal. The goal keeps moving until the motion has streamed, then fails naming the fault reaction."""
    ex = execution()
    ex.on_stream_state(START + S, START, 3.0)
    ex.on_axis_status(START + 2 * S, 'fault_stopping', 'reference stream lost at 102 s (samples missing for 1300 ms'
                                                      ' mid-motion)')
    assert ex.phase(START + 2 * S) == MOVING  # while it streams, the streamer's drop (or silence) says more
    ex.on_stream_state(START + 3 * S, START, 3.0)  # streamed to its end: holding
    assert ex.phase(START + 3 * S) == FAILED
    assert 'fault reaction (reference stream lost' in ex.failure and 'samples missing for 1300 ms' in ex.failure


@pytest.mark.parametrize('stamp', [START - S, START + 6 * S])
def test_a_fault_reaction_before_the_motion_or_after_its_settle_window_is_not_its_own(stamp):
    """axis_status is latched (transient local): a fault from before the motion, or after its window, is ignored."""
    ex = execution()
    ex.on_axis_status(stamp - S, 'fault_hold', 'an older fault')  # before the motion is known at all: ignored
    ex.on_stream_state(START + S, START, 3.0)
    ex.on_axis_status(stamp, 'fault_hold', 'an older fault')
    ex.on_axis_status(START + S, 'tracking', 'tracking the reference stream')
    ex.on_stream_state(START + 5 * S, START, 3.0)
    assert ex.phase(START + 5 * S + S) == DONE and not ex.failure
