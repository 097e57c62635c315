"""Motion from any state as the planner serves it (serving.transitions), on the knots the streamer streams:
every handover is checked against the streamer's own rules (ReferenceStream) and on crane_sim's crane."""
import numpy as np
import pytest

from crane_msgs_py.crane.params import CraneParams
from crane_msgs_py.messages.names import CART_JOINT, HOIST_JOINT
from crane_planner.planning.dispatch import PlanOptions, SolverCache, plan
from crane_planner.planning.plan import AxesPlan, PlanError
from crane_planner.planning.signals import Swing
from crane_planner.serving.moves import axis_samples
from crane_planner.serving.transitions import (
    JointReading,
    Measurement,
    Running,
    handover_state,
    joint_starts,
    retarget,
    settle,
    stop,
    taken_over,
)
from crane_planner.streaming.knots import knot_times
from crane_sim.simulator import simulate

PARAMS = CraneParams()
ORIGIN = 5_000_000_000  # ns: the running motion's first knot
START = 0.2  # m: where it starts
DT = 1e-3


@pytest.fixture(scope='module')
def variational():
    return SolverCache()


def running_of(p, start=START, hoist=None):
    """The Running motion of plan ``p`` as the node sends it: knots, absolute positions."""
    t = knot_times(p)
    samples = axis_samples(p, t)
    starts = [start] + ([hoist] if hoist is not None else [])
    joints = ('cart', 'hoist')[:len(starts)]
    pos = np.column_stack([s.position + x for s, x in zip(samples, starts)])
    vel = np.column_stack([s.velocity for s in samples])
    acc = np.column_stack([s.acceleration for s in samples])
    return Running(joints, t, pos, vel, acc, ORIGIN, p)


def simulated(running, new, handover_ns, new_start, settle_s=4.0, initial=None):
    """crane_sim run through the running motion until the handover, then the new plan: (t, result)."""
    t_h = (handover_ns - ORIGIN) * 1e-9
    t1 = np.arange(0.0, t_h + 1e-9, DT)
    t2 = np.arange(0.0, new.duration + settle_s, DT)
    a1 = running.at(ORIGIN + np.round(t1 * 1e9).astype(np.int64))[0][2]
    a2 = new.evaluate(t2).acceleration
    t = np.concatenate([t1, t_h + t2[1:]])
    return t, simulate(t, np.concatenate([a1, a2[1:]]), PARAMS, initial_state=initial)


def measure(running, stamp_ns):
    """The measurement the sim would publish at ``stamp_ns`` (crane_sim, independent of the planner)."""
    t = np.arange(0.0, (stamp_ns - ORIGIN) * 1e-9 + 1e-9, DT)
    a = running.at(ORIGIN + np.round(t * 1e9).astype(np.int64))[0][2]
    r = simulate(t, a, PARAMS)
    return Measurement(stamp_ns, {CART_JOINT: JointReading(START + r.y[0, -1], r.v[0, -1])},
                       Swing(r.theta1[0, -1], r.theta2[0, -1], r.dtheta1[0, -1], r.dtheta2[0, -1]))


def handover_is_continuous(running, new, handover_ns, start):
    """What the streamer checks: the new plan's first sample is the knots' state at the handover."""
    ref = running.at(handover_ns)[0]
    s = new.evaluate(0.0)
    assert start + s.position[0] == pytest.approx(ref[0][0], abs=1e-9)
    assert s.velocity[0] == pytest.approx(ref[1][0], abs=1e-7)
    assert s.acceleration[0] == pytest.approx(ref[2][0], abs=1e-6)


@pytest.mark.parametrize('method', ['nvf', 'rvf', 'zv'])
def test_a_new_goal_at_40_percent_ends_at_it_without_swing(variational, method):
    old = running_of(plan(method, 0.3, 3.0, PARAMS, variational=variational))
    handover = ORIGIN + 1_200_000_000
    state = handover_state(old, handover, measure(old, handover - 30_000_000), PARAMS)
    new = retarget(variational, old, handover, state, method, {'cart': START + 0.5}, 3.0, PARAMS, PlanOptions())
    handover_is_continuous(old, new, handover, state.axis(CART_JOINT).position)
    assert state.axis(CART_JOINT).position + new.displacement == pytest.approx(START + 0.5, abs=1e-9)
    t, r = simulated(old, new, handover, state.axis(CART_JOINT).position)
    assert np.abs(r.load_excursion[0, t > 1.2 + new.duration]).max() < 0.1e-3


@pytest.mark.parametrize('method', ['zv', 'nvf'])
def test_a_new_goal_taken_over_late_with_its_change_delayed_still_leaves_no_swing(variational, method):
    """What the streamer streams when the handover reaches it 7.3 ms after its stamp (taken_over, the
    streamer's own rule), played on crane_sim: continuous at the late tick, no swing left at the goal."""
    old = running_of(plan(method, 0.3, 3.0, PARAMS, variational=variational))
    handover = ORIGIN + 1_200_000_000
    state = handover_state(old, handover, measure(old, handover - 30_000_000), PARAMS)
    new = retarget(variational, old, handover, state, method, {'cart': START + 0.5}, 3.0, PARAMS, PlanOptions())
    sent = running_of(new, start=state.axis(CART_JOINT).position)
    sent.origin_ns = handover
    at = handover + 7_300_000
    joined = taken_over(old, sent, at)
    assert joined.origin_ns == at and joined.duration == pytest.approx(new.duration, abs=1e-12)
    for x, y in zip(old.at(at)[0][:3], joined.at(at)[0][:3]):  # no step where it takes over
        assert y[0] == pytest.approx(x[0], abs=1e-9)
    tt = np.arange(0.0, (at - ORIGIN) * 1e-9 + new.duration + 4.0, DT)
    stamps = ORIGIN + np.round(tt * 1e9).astype(np.int64)
    acc = np.where(stamps < at, old.at(stamps)[0][2], joined.at(stamps)[0][2])
    r = simulate(tt, acc, PARAMS)
    assert START + r.y[0, -1] == pytest.approx(START + 0.5, abs=1e-5)  # (NVF: 1.4 um without a delay too)
    assert np.abs(r.load_excursion[0, stamps > joined.end_ns]).max() < 0.1e-3


def test_the_swing_is_predicted_from_the_measurement_or_else_the_model(variational):
    old = running_of(plan('nvf', 0.3, 3.0, PARAMS, variational=variational))
    handover = ORIGIN + 1_500_000_000
    truth = measure(old, handover)
    measured = handover_state(old, handover, measure(old, handover - 40_000_000), PARAMS)
    modelled = handover_state(old, handover, None, PARAMS)
    for state in (measured, modelled):
        assert state.swing.values() == pytest.approx(truth.swing.values(), abs=1e-4)
        assert state.axis(CART_JOINT).position == pytest.approx(old.at(handover)[0][0][0])
    # one measured 1 s before (a handover planned again further ahead) is predicted as far
    earlier = handover_state(old, handover, measure(old, handover - 1_000_000_000), PARAMS)
    assert earlier.swing.values() == pytest.approx(truth.swing.values(), abs=1e-4)
    # one after the handover is not used: the model's swing then
    late = handover_state(old, handover, measure(old, handover + 100_000_000), PARAMS)
    assert late.swing.values() == pytest.approx(modelled.swing.values(), abs=1e-12)


def test_cancel_at_half_way_stops_without_swing_ten_times_better_than_a_hard_stop(variational):
    old = running_of(plan('rvf', 0.3, 3.0, PARAMS, variational=variational))
    handover = ORIGIN + 1_500_000_000
    state = handover_state(old, handover, measure(old, handover - 20_000_000), PARAMS)
    new = stop(variational, old, handover, state, 'rvf', PARAMS, PlanOptions())
    handover_is_continuous(old, new, handover, state.axis(CART_JOINT).position)
    assert new.method == 'nvf'  # every variational stop is NVF's
    t, r = simulated(old, new, handover, state.axis(CART_JOINT).position)
    residual = np.abs(r.load_excursion[0, t > 1.5 + new.duration]).max()
    assert residual < 0.5e-3
    assert np.abs(r.v[0, t > 1.5 + new.duration]).max() < 1e-4  # at rest within the stop's duration
    # a hard stop: the reference held where it is at the handover
    tt = np.arange(0.0, 7.0, DT)
    held = old.at(ORIGIN + np.round(np.minimum(tt, 1.5) * 1e9).astype(np.int64))[0][0]
    hard = simulate(tt, held, PARAMS, source='position')
    assert np.abs(hard.load_excursion[0, tt > 3.5]).max() > 10 * residual


def test_a_shaped_motion_stops_by_braking_its_base_within_the_limits(variational):
    old = running_of(plan('zvd', 0.3, 3.0, PARAMS))
    handover = ORIGIN + 1_200_000_000
    state = handover_state(old, handover, None, PARAMS)
    new = stop(variational, old, handover, state, 'zvd', PARAMS, PlanOptions(max_acceleration=1.0, max_jerk=10.0))
    handover_is_continuous(old, new, handover, state.axis(CART_JOINT).position)
    assert new.info.get('stop') == 'shaped'
    assert new.peaks()[1] <= 1.0 + 1e-9
    t, r = simulated(old, new, handover, state.axis(CART_JOINT).position)
    assert np.abs(r.load_excursion[0, t > 1.2 + new.duration]).max() < 0.1e-3


def test_settle_damps_30_mm_below_1_mm_within_3_s(variational):
    # a first-mode swing of 30 mm at the load, the cart at rest at START
    from crane_planner.planning.model import linearized_matrices  # noqa: F401  (the model the sim does not use)
    theta = 0.03 / (PARAMS.L1 + PARAMS.L2)
    x0 = np.array([0.0, 0.0, 0.0, theta, 0.0, 0.0, 0.0])
    free = simulate(np.arange(0.0, 0.5, DT), np.zeros(500), PARAMS, initial_state=x0)
    swing = Swing(free.theta1[0, -1], free.theta2[0, -1], free.dtheta1[0, -1], free.dtheta2[0, -1])
    from crane_planner.planning.continuation import AxisState, MotionState
    state = MotionState({CART_JOINT: AxisState(START, lag=0.0)}, swing)
    new = settle(variational, state, PARAMS, PlanOptions())
    assert new.duration < 2.5 and new.displacement == pytest.approx(0.0, abs=1e-9)
    t = np.arange(0.0, new.duration + 3.0, DT)
    x1 = np.array([0.0, 0.0, 0.0, *swing.values()])
    r = simulate(t, new.evaluate(t).acceleration, PARAMS, initial_state=x1)
    assert np.abs(r.load_excursion[0, t > new.duration]).max() < 1e-3 * 0.1
    with pytest.raises(PlanError, match='cannot damp a swing it did not cause'):
        settle(variational, state, PARAMS, PlanOptions(), method='zv')


def test_shapers_refuse_a_new_goal_while_hoisting_and_nvf_serves_it(variational):
    hoisting = plan('nvf', 0.3, 3.0, PARAMS, variational=variational, hoist=(0.47, 0.35))
    old = running_of(hoisting, hoist=0.47)
    handover = ORIGIN + 1_200_000_000
    state = handover_state(old, handover, None, PARAMS)
    rope = state.axis(HOIST_JOINT)
    assert rope.velocity < 0.0  # lifting
    with pytest.raises(PlanError, match='cannot retarget a motion while the rope length changes'):
        retarget(variational, old, handover, state, 'zv', {'cart': START + 0.5, 'hoist': 0.35}, 3.0, PARAMS,
                 PlanOptions())
    new = retarget(variational, old, handover, state, 'nvf', {'cart': START + 0.5, 'hoist': 0.3}, 3.0, PARAMS,
                   PlanOptions())
    assert isinstance(new, AxesPlan)
    h = new.evaluate_axis('hoist', [0.0, new.duration])
    assert h.position[0] == pytest.approx(rope.position, abs=1e-12) and h.position[1] == pytest.approx(0.3)
    assert joint_starts(new, state) == [state.axis(CART_JOINT).position, new.starts['hoist']]


def test_a_new_goal_needs_a_duration(variational):
    old = running_of(plan('nvf', 0.3, 3.0, PARAMS, variational=variational))
    state = handover_state(old, ORIGIN + 1_000_000_000, None, PARAMS)
    for method in ('nvf', 'zv'):
        with pytest.raises(PlanError, match='needs a duration'):
            retarget(variational, old, ORIGIN + 1_000_000_000, state, method, {'cart': 0.6}, 0.0, PARAMS,
                     PlanOptions())


def test_a_stop_brakes_no_harder_than_twice_the_motion_and_stops_short_of_its_goal(variational):
    old = running_of(plan('nvf', 0.3, 3.0, PARAMS, variational=variational))
    handover = ORIGIN + 1_500_000_000
    state = handover_state(old, handover, None, PARAMS)
    new = stop(variational, old, handover, state, 'nvf', PARAMS, PlanOptions())
    own = plan('nvf', 0.3, 3.0, PARAMS, variational=variational).peaks()[1]
    assert new.peaks()[1] <= 2.0 * own * (1 + 1e-6)
    assert state.axis(CART_JOINT).position + new.displacement < START + 0.3  # short of the goal it was heading to
    limited = stop(variational, old, handover, state, 'nvf', PARAMS, PlanOptions(max_acceleration=0.1))
    assert limited.peaks()[1] <= 0.1 + 1e-6 and limited.duration > new.duration
