"""ROS: motion from any state through the real executables: a new goal mid-move, a cancel that
stops the crane, ~/settle after a push. The swing is measured by the test from ``joint_states``; the
streamed reference from the 1 kHz ``reference`` topic."""
import numpy as np
import pytest

from crane_msgs_py.crane.params import CraneParams

T = 3.0
T_PREEMPTED = 5.0  # s, the motion a new goal takes over at 40 %
SETTLE = 1.0  # s of residual window: more than half the slow mode's 1.73 s period, so its peak shows
NOMINAL = CraneParams()
STATUS_ABORTED, STATUS_CANCELED = 6, 5  # action_msgs/GoalStatus


@pytest.fixture
def crane(cart_crane):
    """The nodes (conftest's ``cart_crane``), the crane at rest after the test (whatever its outcome): the tests
    move from wherever the streamer holds the cart (``hold``), so none needs a move home."""
    yield cart_crane
    cart_crane.keep_references(False)
    at_rest(cart_crane)


def residual_mm(driver, begin_ns: int, end_ns: int) -> tuple[float, np.ndarray]:
    """Peak load excursion (mm) from joint_states stamped in [begin, end], and the record."""
    from crane_sim.metrics import residual_load_mm
    driver.sleep(max(0.0, (end_ns - driver.now_ns()) * 1e-9))
    rec = driver.states_between(begin_ns, end_ns, timeout=10.0)
    assert len(rec) > 40 * (end_ns - begin_ns) * 1e-9, f'only {len(rec)} joint_states'
    t = (rec[:, 0] - begin_ns) * 1e-9
    return float(residual_load_mm(t, rec[:, 1], rec[:, 2], NOMINAL.L1, NOMINAL.L2, after=t[0])), rec


def at_rest(driver):
    """Once a motion a failed test left running or queued has ended and the streamer holds, the sim reset: the
    plant at rest where the cart is, no swing left from a test."""
    driver.sleep(max(0.0, (driver.trajectories_end_ns() - driver.now_ns()) * 1e-9))
    driver.wait_until_holding()
    driver.reset_sim()


def hold(driver) -> tuple[float, float]:
    """Where the streamer holds the cart (m), from its stream_state: where the test's motion starts; and the
    direction (+1 or -1) of the test's moves, towards 0 m and past it, so that the cart stays near 0 whatever
    ran before."""
    driver.wait_until(lambda: driver.stream_hold() is not None, 10.0, 'no stream_state from the streamer')
    here = driver.held()
    return here, (1.0 if here <= 0.0 else -1.0)


def steps_at(references: np.ndarray, stamp_ns: int) -> tuple:
    """The tick-to-tick changes of position, velocity and acceleration into the tick taking over at
    ``stamp_ns``, and their largest values over the 20 ticks before and the 20 after it (the old and the new
    motion's own rates: a tick's worth)."""
    k = int(np.searchsorted(references[:, 0], stamp_ns))
    d = np.abs(np.diff(references[:, 1:], axis=0))
    return d[k - 1], np.vstack([d[k - 21:k - 1], d[k:k + 20]]).max(axis=0)


@pytest.mark.parametrize('method', ['rvf', 'nvf', 'zv'])
def test_a_new_goal_at_40_percent_takes_over_without_a_step_and_leaves_no_swing(crane, method):
    """The running motion lasts 5 s, so at 40 % 3 s are left: on a loaded host a handover planned again further
    ahead twice (a solve 20 times slower than alone) still falls within it."""
    driver = crane
    here, way = hold(driver)
    driver.keep_references()
    start, _, _ = driver.move(method, None, here + way * 0.3, T_PREEMPTED, settle=SETTLE)
    driver.sleep(max(0.0, (start + round(0.4 * T_PREEMPTED * 1e9) - driver.now_ns()) * 1e-9))
    sent = driver.now_ns()
    handover = driver.retarget(method, here + way * 0.5, T, settle=SETTLE)
    # the handover lies in the motion, after the goal was sent (how long after: bench/any_state.py)
    assert start + round(0.4 * T_PREEMPTED * 1e9) <= sent < handover < start + round(T_PREEMPTED * 1e9)
    end = handover + round(T * 1e9)
    residual, rec = residual_mm(driver, end, end + round(SETTLE * 1e9))
    references = driver.keep_references(False)
    assert residual <= 0.5, residual
    assert rec[-1, 3] == pytest.approx(here + way * 0.5, abs=1e-4)  # the cart at the new goal
    step, own = steps_at(references, handover)
    # no step: the change over the handover tick is what the motion's own rates give over a tick
    assert step[0] <= own[0] * 1.1 + 1e-9 and step[1] <= own[1] * 1.1 + 1e-9, (step, own)
    assert step[2] <= own[2] * 1.1 + 1e-6, (step, own)
    status, result = driver.outcome(start)
    assert status == STATUS_ABORTED and 'preempted by a newer goal' in result.message, result.message
    new = driver.move_result(handover)
    assert new.success and abs(1e3 * new.residual_swing - residual) < 0.05


def test_the_handover_warm_up_rehearses_during_a_motion_and_sends_nothing(crane):
    """While a motion streams, the planner's goals' thread plans a shaper's handover of it (back to its start)
    every ``handover_warmup`` (0.02 s) and serializes its trajectory, sending nothing: the goal's status on
    /diagnostics counts the rehearsals from its trajectory sent to its end, each shorter than the period; the
    topic carried the goal's own trajectory only, and the crane ends at its goal, not where the rehearsals
    went. 0 turns it off."""
    from crane_msgs_py.runtime.diagnostics import status_float
    driver = crane
    here, way = hold(driver)
    mark = driver.planner.diagnostics.mark()
    before = driver.sent_trajectories()
    start, _, _ = driver.move('zv', None, here + way * 0.3, T, settle=0.2)
    assert driver.move_result(start).success
    assert driver.sent_trajectories()[len(before):] == [start]
    status = driver.planner.diagnostics.wait_for(after=mark, name='crane_planner: execute', timeout=3.0)
    assert status is not None
    count, each = status_float(status, 'handover_warmups'), status_float(status, 'handover_warmup_ms')
    motion = T + 0.3  # from its trajectory sent (publish_lead, 0.3 s before its start) to its end
    # rehearsed during the motion, at most once a period (how often the host lets it, and how long each
    # takes: bench/any_state.py)
    assert 1 <= count <= motion / 0.02 + 1, count
    assert each > 0.0, each
    driver.wait_for_state_after(start + round((T + 0.3) * 1e9))
    assert driver.last_state()[3] == pytest.approx(here + way * 0.3, abs=1e-4)
    # 0 turns it off (at once: the next motion, of 1.5 s, has none of its 90 periods)
    driver.set_parameters('planner', {'handover_warmup': 0.0})
    try:
        mark = driver.planner.diagnostics.mark()
        start, _, _ = driver.move('zv', None, here, 1.5, settle=0.2)
        assert driver.move_result(start).success
        status = driver.planner.diagnostics.wait_for(after=mark, name='crane_planner: execute', timeout=3.0)
        assert status_float(status, 'handover_warmups') == 0.0
    finally:
        driver.set_parameters('planner', {'handover_warmup': 0.02})


def test_cancel_at_half_way_stops_the_crane_without_swing(crane):
    from crane_sim.simulator import simulate
    driver = crane
    here, way = hold(driver)
    start, _, traj = driver.move('rvf', None, here + way * 0.3, T, settle=SETTLE)
    driver.sleep(max(0.0, (start + round(0.5 * T * 1e9) - driver.now_ns()) * 1e-9))
    status, result = driver.cancel(start)
    assert status == STATUS_CANCELED, result.message
    assert 'stopped at' in result.message, result.message
    where = float(result.message.split('stopped at ')[1].split(' m')[0])
    stop = [s for s in driver.sent_trajectories() if s > start][-1]
    stop_duration = driver.trajectory(stop).points[-1].time_from_start
    stop_end = stop + stop_duration.sec * 1_000_000_000 + stop_duration.nanosec
    residual, rec = residual_mm(driver, stop_end, stop_end + round(SETTLE * 1e9))
    assert residual <= 0.5, residual
    assert abs(1e3 * result.residual_swing - residual) < 0.05
    # at rest within the stop's duration, where the result says
    assert np.ptp(rec[:, 3]) < 1e-5 and rec[-1, 3] == pytest.approx(where, abs=1e-4)
    # the stop took over during the motion and braked forward from where the motion was then (how far into
    # the motion depends on how long the stop took to plan: a loaded host plans it further ahead)
    from crane_msgs_py.messages.conversions import joint_trajectory_to_arrays
    from crane_planner.streaming.hermite import QuinticHermite
    t_k, p, v, a = joint_trajectory_to_arrays(traj, 'cart')
    assert start < stop < start + round(T * 1e9)
    assert way * (where - QuinticHermite(t_k, p, v, a)(np.array([(stop - start) * 1e-9]))[0][0]) > 0.0
    # an unshaped hard stop of the same move at the same time (the reference held), on the same plant
    t = np.arange(0.0, 8.0, 1e-3)
    held = QuinticHermite(t_k, p, v, a)(np.minimum(t, (stop - start) * 1e-9))[0]
    hard = simulate(t, held - here, NOMINAL, source='position')  # (from the plant's rest at 0)
    assert np.abs(hard.load_excursion[0, t > 4.0]).max() * 1e3 > 10 * residual


def test_settle_damps_a_push_below_1_mm_within_3_s(crane):
    driver = crane
    driver.push_sim()
    driver.sleep(1.0)
    called = driver.now_ns()
    stamp, message = driver.settle()
    swing = float(message.split('settling a swing of about ')[1].split(' mm')[0])
    assert 20.0 < swing < 45.0, message  # the push's 30 mm, both modes' share estimated as the first's
    before, _ = residual_mm(driver, called - round(0.6e9), called - round(0.1e9))
    assert before > 20.0  # it swung
    # the settle starts after the call (how long after: bench/any_state.py); 3 s from its start on, the
    # swing is gone (the window as the call's 3 s when the settle starts 0.2 s after it)
    assert stamp > called
    residual, rec = residual_mm(driver, stamp + round(2.8e9), stamp + round(3.8e9))
    assert residual < 1.0, residual
    assert abs(rec[-1, 3] - rec[0, 3]) < 1e-4  # it ends where it started


def test_settle_is_refused_during_a_motion_and_a_goal_with_a_start_mid_move(crane):
    from crane_msgs_py.crane.errors import PlanError
    from crane_planner.tools.harness import HarnessError
    driver = crane
    here, way = hold(driver)
    start, _, _ = driver.move('zv', None, here + way * 0.2, T, settle=0.5)
    driver.sleep(max(0.0, (start + round(0.5e9) - driver.now_ns()) * 1e-9))
    with pytest.raises(HarnessError, match='a motion is streaming: settle once it has ended'):
        driver.settle()
    with pytest.raises(PlanError, match='a goal during a motion needs a duration'):
        driver.retarget('nvf', here + way * 0.4, 0.0)
    assert driver.move_result(start).success  # the motion went on to its goal
