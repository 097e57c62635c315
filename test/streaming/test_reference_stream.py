"""The streamer's motion rules (crane_planner.streaming.reference_stream), without ROS.

The loop is played by the test: ``Loop`` samples tick after tick and is the
``tick()`` the stream aligns new motions to.
"""
import numpy as np
import pytest

from crane_planner.streaming.hermite import QuinticHermite
from crane_planner.streaming.reference_stream import FIRST_SAMPLES, MAX_HANDOVER_SHIFT, ReferenceStream

PERIOD = 1_000_000                   # ns: 1 kHz
EPOCH = 1_700_000_000_000_000_000    # ns of ROS time at tick 0
MS = 1_000_000                       # ns
HOLD = 0.2                           # m


class Loop:
    """The streamer's loop thread: samples ticks in order; ``tick`` is the next one it samples."""

    def __init__(self, stream: ReferenceStream, epoch: int = EPOCH):
        self.stream, self.tick = stream, 0
        assert stream.start(epoch, lambda: self.tick)

    def run(self, n: int) -> np.ndarray:
        """(tick, position, velocity, acceleration) of the next n ticks."""
        rows = []
        for _ in range(n):
            rows.append((self.tick, *self.stream.sample(self.tick)))
            self.tick += 1
        return np.array(rows)

    def run_to(self, tick: int) -> np.ndarray:
        return self.run(tick - self.tick)


def quintic(p0, p1, duration, t):
    """Rest-to-rest quintic from p0 to p1 (m) in ``duration`` (s): position, velocity, acceleration at t."""
    s, d = np.asarray(t) / duration, p1 - p0
    return (p0 + d * s**3 * (10 - 15 * s + 6 * s * s),
            d / duration * 30 * s**2 * (1 - s)**2,
            d / duration**2 * 60 * s * (1 - 3 * s + 2 * s * s))


def quintic_knots(p0=HOLD, p1=HOLD + 0.3, duration=1.0, t=(0.0, 0.2, 0.45, 0.7, 1.0)):
    t = np.array(t)
    return (t, *quintic(p0, p1, duration, t))


def wavy_knots(p0=HOLD, t=(0.1, 0.35, 0.6, 1.1)):
    """Knots of p0 + 0.1 sin(3 (t - t0)): not a polynomial, so the Hermite interpolant is not exact."""
    t = np.array(t)
    u = 3.0 * (t - t[0])
    return t, p0 + 0.1 * np.sin(u), 0.3 * np.cos(u), -0.9 * np.sin(u)


@pytest.fixture
def stream():
    return ReferenceStream(PERIOD, hold=HOLD, start_tolerance=1e-6)


# -- refusals -------------------------------------------------------------------------


def test_a_trajectory_off_the_hold_position_is_refused_naming_the_jump(stream):
    Loop(stream)
    with pytest.raises(ValueError, match=r'it starts at 0\.7 m, not at the hold position 0\.2 m '
                                         r'\(a jump of 0\.5 m\)'):
        stream.accept(*quintic_knots(HOLD + 0.5, HOLD + 0.6), 0, EPOCH)
    # within start_tolerance (1 um) is no jump; the tolerance may change at any time
    assert stream.accept(*quintic_knots(HOLD + 0.9e-6, HOLD + 0.3), 0, EPOCH).position[0] == HOLD + 0.9e-6


def test_the_start_tolerance_can_be_changed_live(stream):
    Loop(stream)
    stream.start_tolerance = 0.01
    assert stream.accept(*quintic_knots(HOLD + 0.005, HOLD + 0.3), 0, EPOCH).first_tick == 2


def test_a_trajectory_arriving_while_a_motion_streams_needs_a_handover_time(stream):
    loop = Loop(stream)
    motion = stream.accept(*quintic_knots(), 0, EPOCH)
    loop.run_to(motion.first_tick + 10)
    assert stream.streaming
    with pytest.raises(ValueError, match='a motion is streaming: a trajectory during it must start at a time '
                                         'within it'):
        stream.accept(*quintic_knots(), 0, EPOCH + 12 * MS)


def test_a_second_trajectory_starting_after_a_queued_one_is_refused(stream):
    Loop(stream)
    stream.accept(*quintic_knots(), EPOCH + 500 * MS, EPOCH)
    assert not stream.streaming  # queued, not taken over yet
    with pytest.raises(ValueError, match='its start is outside the streaming motion'):
        stream.accept(*quintic_knots(), EPOCH + 3000 * MS, EPOCH)


# -- handovers (a new goal or a stop mid-move) ------------------------------------------------


def continuation_knots(t_h, goal, duration=1.0):
    """Knots from the quintic_knots motion's state at t_h (s into it) to rest at ``goal`` in ``duration``:
    the interpolant the streamer uses gives the state, as the planner computes it."""
    p, v, a = (x[0] for x in QuinticHermite(*quintic_knots())(t_h))
    return np.array([0.0, duration]), np.array([p, goal]), np.array([v, 0.0]), np.array([a, 0.0])


def test_a_handover_replaces_the_rest_of_the_motion_without_a_jump(stream):
    loop = Loop(stream)
    motion = stream.accept(*quintic_knots(), EPOCH + 100 * MS, EPOCH)
    before = loop.run_to(motion.first_tick + 300)
    t_h = 0.4005  # between two ticks: the first tick at or after it takes over
    handover = stream.accept(*continuation_knots(t_h, HOLD + 0.5), EPOCH + 100 * MS + round(t_h * 1e9),
                             EPOCH + 400 * MS)
    assert handover.handover and handover.first_tick == motion.first_tick + 401
    rows = np.vstack([before, loop.run(1200)])
    assert stream.last_motion is handover and not stream.streaming
    assert rows[-1, 1] == pytest.approx(HOLD + 0.5, abs=1e-12)  # ends at the new goal
    # no step at the handover: consecutive ticks differ by what the motion's own rates give over a tick
    dp, dv, da = (np.abs(np.diff(rows[:, k])) for k in (1, 2, 3))
    i = np.searchsorted(rows[:, 0], handover.first_tick) - 1  # the step into the handover tick
    assert dp[i] < 1e-3 * 0.6 and dv[i] < 1e-3 * 3.0 and da[i] < 1e-3 * 30.0
    assert dv[i] < 2 * np.median(dv[i - 5:i]) + 1e-6 and da[i] < 2 * np.median(da[i - 5:i]) + 1e-4


def assert_streamed_as_spliced(rows, motion, handover, knots, t_h):
    """The streamed positions are the closed form of a handover at t_h (s into ``motion``) taken over at
    ``handover.first_tick``: the old motion until then, old + (continuation - old) delayed to it after."""
    old, change = QuinticHermite(*quintic_knots()), QuinticHermite(*knots)
    tau = (rows[:, 0] - handover.first_tick) * 1e-3
    t_old = (rows[:, 0] - motion.first_tick) * 1e-3
    expected = np.where(tau < 0, old(t_old)[0], old(t_old)[0] + change(tau)[0] - old(t_h + tau)[0])
    assert np.abs(rows[:, 1] - expected).max() < 1e-12


def test_a_late_handover_is_taken_at_the_next_tick_with_its_change_delayed(stream):
    loop = Loop(stream)
    motion = stream.accept(*quintic_knots(), EPOCH + 100 * MS, EPOCH)
    before = loop.run_to(motion.first_tick + 407)  # the loop is 7 ms past the handover's stamp
    t_h = 0.4
    knots = continuation_knots(t_h, HOLD + 0.5)
    handover = stream.accept(*knots, EPOCH + 100 * MS + round(t_h * 1e9), EPOCH + 507 * MS)
    assert handover.handover and handover.first_tick == loop.tick  # the next tick the loop samples
    assert handover.late == pytest.approx(0.007, abs=1e-12) and handover.duration == pytest.approx(1.0)
    rows = np.vstack([before, loop.run(1100)])
    # the old motion until the handover tick, then old + (continuation - old) 7 ms later: closed forms
    assert_streamed_as_spliced(rows, motion, handover, knots, t_h)
    assert rows[-1, 1] == pytest.approx(HOLD + 0.5, abs=1e-12)
    dp, dv, da = (np.abs(np.diff(rows[:, k])) for k in (1, 2, 3))
    i = np.searchsorted(rows[:, 0], handover.first_tick) - 1  # the step into the handover tick
    assert dv[i] < 2 * np.median(dv[i - 5:i]) + 1e-6 and da[i] < 2 * np.median(da[i - 5:i]) + 1e-4


def test_a_handover_the_loop_samples_past_while_it_is_made_is_made_again_at_the_next_tick(stream, monkeypatch):
    """The loop goes on while a handover is made: should it sample past the handover's first tick (the
    machine stalled the maker), that handover is not handed over (its change would start a tick late, a
    step) but made again from the loop's next tick; streamed, it is the closed form from there."""
    import crane_planner.streaming.reference_stream as module
    loop = Loop(stream)
    motion = stream.accept(*quintic_knots(), EPOCH + 100 * MS, EPOCH)
    before = loop.run_to(motion.first_tick + 407)
    stalled = []
    real_splice = module.splice

    def stalling_splice(*args):
        if not stalled:  # the first attempt: the loop samples three ticks meanwhile
            stalled.append(loop.run(3))
        return real_splice(*args)

    monkeypatch.setattr(module, 'splice', stalling_splice)
    t_h = 0.4
    knots = continuation_knots(t_h, HOLD + 0.5)
    handover = stream.accept(*knots, EPOCH + 100 * MS + round(t_h * 1e9), EPOCH + 507 * MS)
    assert handover.first_tick == motion.first_tick + 410 == loop.tick  # not 407: the loop sampled 407-409
    assert handover.late == pytest.approx(0.010, abs=1e-12)
    rows = np.vstack([before, stalled[0], loop.run(1100)])
    assert_streamed_as_spliced(rows, motion, handover, knots, t_h)


def test_a_handover_takes_over_at_the_tick_after_the_one_sampled_when_it_arrived(stream):
    """Arrived after tick 506 was sampled, made after 507 was (sampled from the old motion, which the
    handover continues there): it takes over at 507, the change from rest there, the stream the closed form."""
    loop = Loop(stream)
    motion = stream.accept(*quintic_knots(), EPOCH + 100 * MS, EPOCH)
    before = loop.run_to(motion.first_tick + 407)
    arrived = stream.last_tick
    assert arrived == motion.first_tick + 406
    before = np.vstack([before, loop.run(1)])  # the loop samples 507 meanwhile
    t_h = 0.4
    knots = continuation_knots(t_h, HOLD + 0.5)
    handover = stream.accept(*knots, EPOCH + 100 * MS + round(t_h * 1e9), EPOCH + 508 * MS, arrived)
    assert handover.first_tick == arrived + 1 == loop.tick - 1
    rows = np.vstack([before, loop.run(1100)])
    assert_streamed_as_spliced(rows, motion, handover, knots, t_h)


def test_a_handover_later_than_the_shift_allowed_or_a_late_stop_is_refused(stream):
    loop = Loop(stream)
    motion = stream.accept(*quintic_knots(), EPOCH + 100 * MS, EPOCH)
    late = round(MAX_HANDOVER_SHIFT * 1e3) + 1  # ms
    loop.run_to(motion.first_tick + 400 + late)
    with pytest.raises(ValueError, match=f'too late for its handover .*at most {MAX_HANDOVER_SHIFT:g} s'):
        stream.accept(*continuation_knots(0.4, HOLD + 0.5), EPOCH + 500 * MS, EPOCH + (500 + late) * MS)
    # a stop (ending before the motion would have) is never delayed: it would creep on until the old end
    with pytest.raises(ValueError, match=r'ends before the motion it replaces would have \(a stop\)'):
        stream.accept(*continuation_knots(0.4, HOLD + 0.25, duration=0.3), EPOCH + 500 * MS,
                      EPOCH + (500 + late) * MS)
    assert stream.last_motion is motion and stream.streaming  # nothing changed


def test_a_motion_is_queued_with_its_first_samples_and_the_loop_never_misses_the_rest(monkeypatch):
    """accept queues a motion with FIRST_SAMPLES samples (the loop may start it at once) and samples the
    rest outside the lock; a loop getting past them first evaluates its ticks itself, the same values."""
    whole = ReferenceStream(PERIOD, hold=HOLD)
    loop = Loop(whole)
    motion = whole.accept(*quintic_knots(), 0, EPOCH)
    assert len(motion.position) == motion.ticks == 1001 > FIRST_SAMPLES
    expected = loop.run(1010)
    monkeypatch.setattr(ReferenceStream, '_filled', lambda self, motion: motion)  # the rest never comes
    cut = ReferenceStream(PERIOD, hold=HOLD)
    loop = Loop(cut)
    motion = cut.accept(*quintic_knots(), 0, EPOCH)
    assert len(motion.position) == FIRST_SAMPLES
    rows = loop.run(1010)
    assert np.array_equal(rows, expected) and cut.hold == HOLD + 0.3 and not cut.streaming


def test_a_handover_that_does_not_continue_the_motion_is_refused_naming_the_gap(stream):
    loop = Loop(stream)
    motion = stream.accept(*quintic_knots(), EPOCH + 100 * MS, EPOCH)
    loop.run_to(motion.first_tick + 300)
    t, p, v, a = continuation_knots(0.5, HOLD + 0.5)
    v = v + np.array([1e-3, 0.0])
    with pytest.raises(ValueError, match=r'the velocity differs by 0\.001 m/s'):
        stream.accept(t, p, v, a, EPOCH + 600 * MS, EPOCH + 400 * MS)
    with pytest.raises(ValueError, match='too late for its handover'):
        stream.accept(*continuation_knots(0.2, HOLD + 0.5), EPOCH + 300 * MS, EPOCH + 400 * MS)
    with pytest.raises(ValueError, match='outside the streaming motion'):
        stream.accept(*continuation_knots(1.0, HOLD + 0.5), EPOCH + 1200 * MS, EPOCH + 400 * MS)
    assert stream.last_motion is motion and stream.streaming  # nothing changed


def test_refused_before_the_loop_starts_and_while_stopped():
    fresh = ReferenceStream(PERIOD, hold=HOLD)
    with pytest.raises(ValueError, match='^the stream has not started yet$'):
        fresh.accept(*quintic_knots(), 0, EPOCH)
    stopped = ReferenceStream(PERIOD, hold=HOLD, stopped=True)
    with pytest.raises(ValueError, match=r'^the streamer is stopped \(call ~/start\)$'):
        stopped.accept(*quintic_knots(), 0, EPOCH)
    assert not stopped.start(EPOCH, lambda: 0) and not stopped.running  # a stopped stream does not start
    stopped.resume()
    with pytest.raises(ValueError, match='^the stream has not started yet$'):
        stopped.accept(*quintic_knots(), 0, EPOCH)
    Loop(stopped)
    assert stopped.running and stopped.accept(*quintic_knots(), 0, EPOCH).first_tick == 2


def test_a_trajectory_that_ended_already_is_refused(stream):
    Loop(stream).run(1000)
    # knots from 0.1 s to 1.1 s after the stamp: it ended 1.6 - 1.1 = 0.5 s ago
    with pytest.raises(ValueError, match=r'^it ended 0\.500 s ago$'):
        stream.accept(*wavy_knots(), EPOCH, EPOCH + 1600 * MS)
    # one that has not ended is streamed (late), and a zero stamp never ends
    assert stream.accept(*wavy_knots(), EPOCH, EPOCH + 1000 * MS).late > 0


def test_bad_knots_are_refused_by_the_interpolant(stream):
    Loop(stream)
    with pytest.raises(ValueError, match='increase strictly'):
        stream.accept([0.0, 0.0], [HOLD, HOLD], [0.0, 0.0], [0.0, 0.0], 0, EPOCH)
    with pytest.raises(ValueError, match='finite'):
        stream.accept([0.0, 1.0], [HOLD, np.nan], [0.0, 0.0], [0.0, 0.0], 0, EPOCH)


# -- where a motion starts, what it samples -----------------------------------------------


@pytest.mark.parametrize('past_tick, first', [(0, 110), (1, 111), (250_000, 111), (999_999, 111)])
def test_the_start_is_aligned_to_the_first_tick_at_or_after_it(stream, past_tick, first):
    """Knot t0 = 0.1 s after a stamp 10 ms + past_tick ns after the epoch: due at 110 ms + past_tick."""
    loop = Loop(stream)
    start_ns = EPOCH + 10 * MS + past_tick
    motion = stream.accept(*wavy_knots(), start_ns, EPOCH)
    assert motion.first_tick == first and motion.late == 0.0
    rows = loop.run_to(first + 1200)
    ticks = rows[:, 0].astype(int)
    # each tick publishes the interpolant at its own time: t0 + (epoch + k period - start)
    interp = QuinticHermite(*wavy_knots())
    k = np.arange(first, first + len(motion.position))
    p, v, a = interp(0.1 + (EPOCH + k * PERIOD - start_ns - 100 * MS) * 1e-9)
    on = (ticks >= first) & (ticks < first + len(motion.position))
    np.testing.assert_allclose(rows[on, 1], p, rtol=0, atol=1e-12)
    np.testing.assert_allclose(rows[on, 2], v, rtol=0, atol=1e-12)
    np.testing.assert_allclose(rows[on, 3], a, rtol=0, atol=1e-12)
    # the motion (1 s) ends at 1110 ms + past_tick: its last sample is the first tick at or past that
    last = first + len(motion.position) - 1
    assert last == -(-(1110 * MS + past_tick) // PERIOD)
    assert rows[ticks == last, 1:].tolist() == [[interp.position[-1], interp.velocity[-1], interp.acceleration[-1]]]
    assert motion.duration == pytest.approx(1.0) and motion.end_position == interp.position[-1]


def test_the_sampled_values_are_the_hermite_interpolation_at_the_tick_times(stream):
    """Quintic knots: Hermite reproduces the quintic, so every tick carries the planned motion exactly."""
    loop = Loop(stream)
    loop.run(7)
    motion = stream.accept(*quintic_knots(), 0, EPOCH)  # a zero stamp: at the first tick the loop cannot reach
    assert motion.first_tick == 7 + 2 and len(motion.position) == 1001
    rows = loop.run_to(motion.first_tick + 1001)[2:]
    t = np.arange(1001) * PERIOD * 1e-9
    for column, exact in zip(rows[:, 1:].T, quintic(HOLD, HOLD + 0.3, 1.0, t)):
        np.testing.assert_allclose(column, exact, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(rows[:, 1:].T, QuinticHermite(*quintic_knots())(t))


def test_a_late_start_is_shifted_to_the_next_free_tick_and_streamed_whole(stream):
    loop = Loop(stream)
    loop.run(500)  # the loop is at tick 500 (500 ms) ...
    start_ns = EPOCH + 300 * MS - 100 * MS  # ... and the motion (knots from 0.1 s) was due at 300 ms
    motion = stream.accept(*wavy_knots(), start_ns, EPOCH + 500 * MS)
    assert motion.first_tick == 502 and motion.late == pytest.approx(0.202, abs=1e-12)
    assert motion.summary.endswith('1001 ticks, started 0.202 s late')
    rows = loop.run_to(1600)
    ticks = rows[:, 0].astype(int)
    # every sample of the motion, from its start, 202 ms late: no jump into its middle
    p, v, a = QuinticHermite(*wavy_knots())(0.1 + np.arange(1001) * PERIOD * 1e-9)
    on = (ticks >= 502) & (ticks <= 1502)
    np.testing.assert_array_equal(rows[on, 1:].T, [p, v, a])
    assert rows[ticks == 502, 1] == HOLD and np.all(rows[ticks < 502, 1:] == [HOLD, 0.0, 0.0])


# -- the hold -------------------------------------------------------------------------


def test_the_stream_holds_at_rest_before_between_and_after_motions(stream):
    loop = Loop(stream)
    first = stream.accept(*quintic_knots(), EPOCH + 100 * MS, EPOCH)   # ticks 100..1100
    rows = loop.run_to(1500)
    end = HOLD + 0.3
    assert np.all(rows[:100, 1:] == [HOLD, 0.0, 0.0])
    assert first.first_tick == 100 and rows[1100, 1:].tolist() == [end, 0.0, 0.0]  # the last sample: the end state
    assert np.all(rows[1101:, 1:] == [end, 0.0, 0.0]) and stream.hold == end and not stream.streaming
    # the next motion starts at the new hold position, the old one is a jump now
    with pytest.raises(ValueError, match='a jump of -0.3 m'):
        stream.accept(*quintic_knots(), EPOCH + 2000 * MS, EPOCH + 1500 * MS)
    second = stream.accept(*quintic_knots(end, HOLD), EPOCH + 2000 * MS, EPOCH + 1500 * MS)
    rows = loop.run_to(2500)
    assert second.first_tick == 2000 and np.all(rows[:500, 1:] == [end, 0.0, 0.0])  # ticks 1500..1999: held
    assert rows[-1, 2] < 0.0 and stream.streaming  # moving back
    rows = loop.run_to(3100)[-10:]
    assert np.all(rows[:, 1:] == [HOLD, 0.0, 0.0]) and stream.hold == HOLD


def test_stop_drops_the_motion_where_it_was_and_resumes_from_there(stream):
    loop = Loop(stream)
    motion = stream.accept(*quintic_knots(), 0, EPOCH)
    rows = loop.run(400)
    assert stream.stop() is motion and not stream.running and not stream.streaming
    where = rows[-1, 1]
    assert HOLD < where < HOLD + 0.3 and stream.hold == where
    # a tick the loop runs before it sees the stop publishes the hold, at rest
    assert stream.sample(loop.tick) == (where, 0.0, 0.0)
    with pytest.raises(ValueError, match='stopped'):
        stream.accept(*quintic_knots(where, HOLD), 0, EPOCH)
    stream.resume()
    loop = Loop(stream, epoch=EPOCH + 5000 * MS)  # a fresh epoch, ticks from 0
    with pytest.raises(ValueError, match='not at the hold position'):
        stream.accept(*quintic_knots(), 0, EPOCH + 5000 * MS)
    again = stream.accept(*quintic_knots(where, HOLD), 0, EPOCH + 5000 * MS)
    assert again.first_tick == 2 and loop.run(3)[2, 1] == where


def test_stop_drops_a_queued_motion_before_its_first_tick(stream):
    loop = Loop(stream)
    motion = stream.accept(*quintic_knots(), EPOCH + 50 * MS, EPOCH)
    loop.run(10)
    assert stream.stop() is None  # nothing was streaming
    assert np.all(loop.run_to(motion.first_tick + 20)[:, 1:] == [HOLD, 0.0, 0.0]) and stream.hold == HOLD


def test_a_period_must_be_positive():
    with pytest.raises(ValueError, match='> 0'):
        ReferenceStream(0)


def test_the_last_motion_is_reported_from_its_first_tick_until_the_next_one_starts(stream):
    """What the streamer's stream_state says: the streaming (else last) motion, started at its first tick."""
    loop = Loop(stream)
    assert stream.last_motion is None
    first = stream.accept(*quintic_knots(), EPOCH + 100 * MS + 300_000, EPOCH)
    loop.run_to(first.first_tick)
    assert stream.last_motion is None  # queued, not started
    loop.run(1)
    assert stream.last_motion is first and stream.streaming
    assert first.start_ns == EPOCH + first.first_tick * PERIOD == EPOCH + 101 * MS  # the tick at or after it
    loop.run_to(first.first_tick + len(first.position) + 5)
    assert stream.last_motion is first and not stream.streaming  # ended: still the last one
    second = stream.accept(*quintic_knots(first.end_position, HOLD, 0.5, (0.0, 0.5)), 0, EPOCH)
    loop.run_to(second.first_tick + 1)
    assert stream.last_motion is second and second.start_ns == EPOCH + second.first_tick * PERIOD


def test_two_joints_stream_together_each_from_its_own_hold():
    """The cart and the hoist: one motion, a column each, aligned on the same ticks; a hold per joint; a jump
    of either refused naming both positions."""
    stream = ReferenceStream(PERIOD, (HOLD, 0.47))
    loop = Loop(stream)
    assert loop.stream.sample(0) == ((HOLD, 0.47), (0.0, 0.0), (0.0, 0.0))
    t = np.linspace(0.0, 2.0, 41)
    cart, hoist = quintic(HOLD, HOLD + 0.3, 2.0, t), quintic(0.47, 0.27, 2.0, t)
    knots = [np.column_stack([c, h]) for c, h in zip(cart, hoist)]
    motion = stream.accept(t, *knots, start_ns=EPOCH + 100 * MS, now_ns=EPOCH)
    assert motion.first_tick == 100 and len(motion.position) == 2001
    rows = [stream.sample(tick) for tick in range(0, 2102)][100:2101]  # tuples: not Loop.run
    loop.tick = 2102
    positions = np.array([r[0] for r in rows])
    exact = np.column_stack([quintic(HOLD, HOLD + 0.3, 2.0, np.arange(2001) * 1e-3)[0],
                             quintic(0.47, 0.27, 2.0, np.arange(2001) * 1e-3)[0]])
    assert np.max(np.abs(positions - exact)) < 1e-6  # quintic Hermite through the knots
    assert stream.hold == pytest.approx((HOLD + 0.3, 0.27), abs=1e-12)
    with pytest.raises(ValueError, match=r'not at the hold position \(0.5, 0.27\)'):
        stream.accept(t, *[np.column_stack([c, c]) for c in quintic(HOLD + 0.3, HOLD, 2.0, t)], start_ns=0,
                      now_ns=EPOCH + 3000 * MS)
    with pytest.raises(ValueError, match='every knot needs 2 positions'):
        stream.accept(t, *quintic(HOLD + 0.3, HOLD, 2.0, t), start_ns=0, now_ns=EPOCH + 3000 * MS)
