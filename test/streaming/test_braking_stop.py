"""streaming.braking_stop: the streamer's last resort brakes every axis along its jerk-limited ramp.

Checked on a real ``ReferenceStream`` sampled tick by tick: the acceleration never steps by more than the
jerk limit allows in one tick (a hold would step by the whole acceleration and leave the velocity at once),
and the axis stops where ``braking.stopping_distance`` (checked against ruckig in test_braking) says.
"""
import numpy as np
import pytest

from crane_msgs_py.crane.braking import stopping_distance
from crane_planner.streaming.braking_stop import LEADS, brake, braking_stop
from crane_planner.streaming.reference_stream import ReferenceStream

from .test_reference_stream import EPOCH, MS, PERIOD, Loop, quintic

D, J = 0.5, 5.0


def run(loop, n):
    """(tick, positions..., velocities..., accelerations...) of the next n ticks, one joint or several."""
    rows = []
    for _ in range(n):
        sample = loop.stream.sample(loop.tick)
        rows.append((loop.tick, *np.concatenate([np.atleast_1d(x) for x in sample])))
        loop.tick += 1
    return np.array(rows)


def streaming_quintic(stream, joints=1):
    """A 0.6 m quintic in 4 s (knots every 0.5 s: exact), streamed from tick 2; with two joints the second
    moves 0.47 -> 0.3 m."""
    t = np.linspace(0.0, 4.0, 9)
    cart = np.array(quintic(0.0, 0.6, 4.0, t))
    if joints == 1:
        stream.accept(t, *cart, EPOCH + 2 * MS, EPOCH)
    else:
        hoist = np.array(quintic(0.47, 0.3, 4.0, t))
        stream.accept(t, *(np.column_stack([c, h]) for c, h in zip(cart, hoist)), EPOCH + 2 * MS, EPOCH)


@pytest.mark.parametrize('joints', [1, 2])
def test_a_motion_braked_at_40_percent_never_steps_its_acceleration_and_stops_where_the_ramp_says(joints):
    hold = 0.0 if joints == 1 else (0.0, 0.47)
    stream = ReferenceStream(PERIOD, hold=hold)
    loop = Loop(stream)
    streaming_quintic(stream, joints)
    before = run(loop, 1602)  # to 40 % of the motion
    now = EPOCH + loop.tick * PERIOD
    stop = brake(stream, lambda: now, D, J)
    handover_tick = (stop.handover_ns - EPOCH) // PERIOD
    after = run(loop, round(stop.duration * 1e3) + 200)
    rows = np.vstack([before, after])
    cols = rows.shape[1] - 1
    p, v, a = (rows[:, 1 + k * cols // 3:1 + (k + 1) * cols // 3] for k in range(3))
    assert np.max(np.abs(np.diff(a, axis=0))) <= J * PERIOD * 1e-9 * (1 + 1e-6) + 1e-12  # no step anywhere
    k = int(handover_tick - rows[0, 0])
    assert np.all(np.abs(a[k:]) <= D + 1e-9)
    expected = p[k] + [stopping_distance(v[k, j], a[k, j], D, J) for j in range(p.shape[1])]
    assert p[-1] == pytest.approx(expected, abs=1e-9)
    assert np.all(v[-1] == 0.0) and np.all(a[-1] == 0.0)
    assert p[-1, 0] < 0.6  # braked short of the goal


def test_a_ramp_whose_first_tick_the_loop_streams_meanwhile_is_taken_at_the_next_lead():
    """The ramp starts at the request's time plus the lead, here 0.12 ms before a tick, so its first sample
    is the ramp 0.12 ms in. The loop streams that tick from the motion while the handover is made (a busy
    executor thread): installed anyway, the ramp would take over at the next tick 1.12 ms in, a step of the
    acceleration beyond the jerk limit. The stream refuses it as too late, and the next lead is taken."""
    stream = ReferenceStream(PERIOD, hold=0.0)
    loop = Loop(stream)
    streaming_quintic(stream)
    rows = [run(loop, 1602)]
    now = EPOCH + (loop.tick + 5) * PERIOD - round(LEADS[0] * 1e9) - 120_000
    install, meanwhile = stream._install, []

    def loop_gets_there_first(handover):
        if not meanwhile:  # (once: the next lead's handover is made with the loop left alone)
            meanwhile.append(handover.first_tick)
            rows.append(run(loop, handover.first_tick - loop.tick + 1))
        return install(handover)
    stream._install = loop_gets_there_first
    stop = brake(stream, lambda: now, D, J)
    rows.append(run(loop, round(stop.duration * 1e3) + 200))
    a = np.vstack(rows)[:, 3]
    assert np.max(np.abs(np.diff(a))) <= J * PERIOD * 1e-9 * (1 + 1e-6) + 1e-12
    assert stop.handover_ns == now + round(LEADS[1] * 1e9)  # the first lead's came too late


def test_an_axis_at_rest_holds_and_a_ramp_of_no_time_still_has_two_knots():
    stop = braking_stop(np.array([[0.3], [0.0], [0.0]]), 0, D, J)
    assert stop.duration == 0.0 and len(stop.t) == 2 and stop.end == 0.3 and stop.position[-1, 0] == 0.3


def test_a_motion_ending_before_the_handover_is_left_to_end_at_rest():
    stream = ReferenceStream(PERIOD, hold=0.0)
    loop = Loop(stream)
    streaming_quintic(stream)
    loop.run(4000)
    assert brake(stream, lambda: EPOCH + 4000 * MS, D, J) is None


def test_without_a_motion_there_is_nothing_to_brake():
    stream = ReferenceStream(PERIOD, hold=0.0)
    Loop(stream)
    with pytest.raises(ValueError, match='no motion'):
        brake(stream, lambda: EPOCH, D, J)
