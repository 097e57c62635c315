"""streaming.streamer and streaming.source: the loop's core streams whichever source is active, through the
corrections, takes a request at its next tick and ends a ~/stop at rest; run on explicit ticks, no DDS."""
import numpy as np
import pytest

from crane_msgs_py.crane.axes import AxisLimits
from crane_msgs_py.crane.params import CraneParams
from crane_planner.streaming.operator import OperatorStream
from crane_planner.streaming.reference_stream import ReferenceStream
from crane_planner.streaming.source import Correction, Setpoint, Source, corrected
from crane_planner.streaming.streamer import Inbox, Streamer
from crane_planner.streaming.streamer_state import IllegalTransition, Mode, State

from .test_reference_stream import EPOCH, HOLD, MS, PERIOD, quintic_knots

CART = AxisLimits(0.3, 0.5, 5.0)


def operator_at(position, clock=lambda: 0.0):
    return OperatorStream(PERIOD * 1e-9, (position,), (CART,), 'zv', CraneParams(), clock=clock)


def operator_moving(streamer, loop) -> OperatorStream:
    """An operator stream made active and driven 0.5 s by a stick held at 0.2 m/s."""
    operator = operator_at(HOLD)
    streamer.use(Mode.OPERATOR, operator)
    operator.command(0.2, now=0.0)
    loop.run(500)
    return operator


class Loop:
    """The streamer's loop thread on explicit ticks: ``tick`` is the next one it streams."""

    def __init__(self, streamer: Streamer):
        self.streamer, self.tick = streamer, 0
        assert streamer.start(EPOCH, lambda: self.tick)

    def run(self, n: int) -> list:
        out = []
        for _ in range(n):
            out.append(self.streamer.tick(self.tick, EPOCH + self.tick * PERIOD))
            self.tick += 1
        return out


def streaming(stream=None, **kwargs) -> Streamer:
    streamer = Streamer(ReferenceStream(PERIOD, HOLD, stopped=True) if stream is None else stream, **kwargs)
    streamer.go(Mode.TRAJECTORY, streamer.stream)
    return streamer


class Shift:
    """A correction adding ``dx`` to the position, recording what it was given."""

    def __init__(self, dx):
        self.dx, self.seen = dx, []

    def correct(self, tick, stamp_ns, setpoint):
        self.seen.append((tick, stamp_ns, setpoint))
        return setpoint._replace(position=setpoint.position + self.dx)


def test_the_trajectory_and_the_operator_streams_are_sources_and_a_setpoint_is_a_named_tuple():
    assert isinstance(ReferenceStream(PERIOD, HOLD), Source)
    assert isinstance(operator_at(HOLD), Source)
    assert isinstance(Shift(0.0), Correction)
    setpoint = Setpoint(1.0, 2.0, 3.0)
    assert setpoint == (1.0, 2.0, 3.0)
    p, v, a = setpoint
    assert (p, v, a) == (setpoint.position, setpoint.velocity, setpoint.acceleration)


def test_with_no_corrections_a_tick_is_exactly_the_sources_sample():
    twin = ReferenceStream(PERIOD, HOLD)
    assert twin.start(EPOCH, lambda: 0)
    streamer = streaming()
    loop = Loop(streamer)
    for stream in (twin, streamer.stream):
        stream.accept(*quintic_knots(), EPOCH + 3 * MS, EPOCH)
    ticks = loop.run(1100)
    assert ticks == [twin.sample(k) for k in range(1100)]
    assert all(type(x) is Setpoint for x in ticks)
    assert streamer.stream.at_rest and streamer.stream.position == ticks[-1].position


def test_corrections_apply_after_the_source_in_order_with_the_tick_and_its_stamp():
    first, second = Shift(0.01), Shift(0.1)
    loop = Loop(streaming(corrections=(first, second)))
    out = loop.run(3)
    assert [x.position for x in out] == pytest.approx([HOLD + 0.11] * 3)
    assert [(tick, stamp) for tick, stamp, _ in first.seen] == [(k, EPOCH + k * PERIOD) for k in range(3)]
    assert second.seen[0][2].position == pytest.approx(HOLD + 0.01)  # after the first
    assert corrected((), 7, 0, out[0]) is out[0]
    assert loop.streamer.stream.hold == HOLD  # the source's own position is uncorrected


def test_a_new_source_is_taken_at_the_loops_next_tick_and_the_executor_sees_it_at_once():
    streamer = streaming()
    loop = Loop(streamer)
    loop.run(2)
    operator = operator_at(HOLD)
    streamer.use(Mode.OPERATOR, operator)
    assert streamer.mode is Mode.OPERATOR and streamer.source is operator  # the executor's view
    assert streamer.stream.last_tick == 1  # the loop has not sampled it
    operator.command(0.2, now=0.0)
    p = [x.position for x in loop.run(300)]
    assert streamer.stream.last_tick == 1  # the operator streamed from the next tick on
    assert p[0] == pytest.approx(HOLD) and p[-1] > HOLD + 1e-3 and streamer.moving


def test_an_inbox_gives_the_newest_request_once():
    inbox = Inbox('a')
    assert inbox.take() is None and inbox.latest == 'a'
    inbox.write('b')
    inbox.write('c')
    assert inbox.latest == 'c'
    assert inbox.take() == 'c'
    assert inbox.take() is None


def test_a_stop_of_the_operator_ends_at_rest_with_the_hold_where_it_stopped():
    streamer = streaming()
    loop = Loop(streamer)
    operator = operator_moving(streamer, loop)
    operator.stop()
    streamer.stopping()
    assert streamer.running.is_set() and not streamer.commanded
    ticks = 0
    while streamer.stream.running:
        loop.run(1)
        ticks += 1
        assert ticks < 20_000
    assert streamer.state is State.STOPPED and not streamer.running.is_set()
    assert streamer.stream.hold == operator.position[0] != HOLD
    assert isinstance(streamer.stream.hold, float)


def test_a_stop_during_a_motion_ends_when_the_motion_has_ended():
    streamer = streaming()
    loop = Loop(streamer)
    streamer.stream.accept(*quintic_knots(), EPOCH + 3 * MS, EPOCH)
    loop.run(10)
    streamer.stopping()  # (the stop's trajectory would be accepted as a handover: here the motion runs out)
    rows = loop.run(994)  # to the last sample of the motion, ticks 3 to 1003
    assert streamer.state is State.STOPPING
    rows += loop.run(1)
    assert streamer.state is State.STOPPED and not streamer.stream.running
    assert rows[-1].position == pytest.approx(HOLD + 0.3) and rows[-1].velocity == 0.0


def test_a_halt_stops_the_stream_at_once_and_a_start_streams_from_the_new_hold():
    streamer = streaming()
    loop = Loop(streamer)
    streamer.stream.accept(*quintic_knots(), EPOCH + 3 * MS, EPOCH)
    loop.run(100)
    streamer.halt()
    assert streamer.state is State.STOPPED and not streamer.stream.running and not streamer.stream.streaming
    streamer.stream.hold_at((0.5,))  # a tuple of one joint is that joint's position
    streamer.go(Mode.TRAJECTORY, streamer.stream)
    loop = Loop(streamer)
    assert loop.run(1) == [(0.5, 0.0, 0.0)]


class RestartedWhenAsked:
    """The hold's source, at rest; the first time the loop asks whether it is at rest during a stop, the executor
    halts the streamer and starts it again (a fault reaction's restart) before the loop goes on."""

    def __init__(self, streamer: Streamer):
        self.streamer, self.stream, self.restarted = streamer, streamer.stream, False

    def sample(self, tick):
        return self.stream.sample(tick)

    @property
    def at_rest(self):
        if self.streamer.state is State.STOPPING and not self.restarted:
            self.restarted = True
            self.streamer.halt()
            self.streamer.go(Mode.TRAJECTORY, self)
        return True

    moving = False

    @property
    def position(self):
        return self.stream.position


def test_a_start_between_the_loops_look_at_a_stop_and_its_end_is_not_stopped_by_it():
    """The loop saw a ~/stop at rest; a halt and a new start came before it ended the stop: the stop is over,
    and the new start streams on (its stream not stopped under it)."""
    streamer = streaming()
    loop = Loop(streamer)
    source = RestartedWhenAsked(streamer)
    streamer.use(Mode.TRAJECTORY, source)
    loop.run(1)
    streamer.stopping()
    loop.run(1)
    assert source.restarted
    assert streamer.state is State.STREAMING and streamer.running.is_set()
    assert streamer.start(EPOCH, lambda: loop.tick)  # the new start's stream runs: not stopped by the old stop


def test_a_start_refused_by_the_state_changes_nothing():
    streamer = streaming()
    streamer.stopping()
    with pytest.raises(IllegalTransition):
        streamer.go(Mode.OPERATOR, operator_at(HOLD))
    assert streamer.mode is Mode.TRAJECTORY and streamer.source is streamer.stream


def test_two_joints_stream_a_tuple_per_field():
    streamer = streaming(ReferenceStream(PERIOD, (HOLD, 1.0), stopped=True))
    (setpoint,) = Loop(streamer).run(1)
    assert setpoint == ((HOLD, 1.0), (0.0, 0.0), (0.0, 0.0))
    assert np.allclose(streamer.stream.position, (HOLD, 1.0))
