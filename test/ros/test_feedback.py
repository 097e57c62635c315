"""ROS: closed-loop sway control through the real executables (the streamer's ``feedback`` on).

The perturbed crane (the sim's upper cable 0.42 m, the planner's and the streamer's model 0.47 m) leaves the load
quiet where open loop leaves 8.6-8.9 mm; a push at rest is damped within one slow period and the cart comes back
to its hold. Judged from what the nodes publish: the goals' results and ``joint_states``."""
import math
import re
import threading

import numpy as np
import pytest

from crane_msgs_py.crane.params import CraneParams

NS = '/crane_feedback'
NOMINAL = CraneParams()
PERIOD = 1.73  # s, the first mode's period of Table 1's crane
T = 2.5


@pytest.fixture(scope='module')
def crane(start_crane):
    with start_crane(NS, planner_params={'solver_processes': 1}, streamer_params={'feedback': True}) as driver:
        yield driver


@pytest.fixture
def perturbed(crane):
    crane.set_parameters('sim', {'L1': 0.42})
    try:
        yield crane
    finally:
        crane.set_parameters('sim', {'L1': NOMINAL.L1})


def quiet(crane, timeout: float = 20.0):
    """Wait until the feedback has the load quiet and its correction back to nothing, the cart where the
    streamer holds it (``CraneHarness.wait_until_quiet``: not the sim's ~/reset under a correction moving the cart)."""
    crane.wait_until_quiet(NOMINAL.L1, NOMINAL.L2, timeout)


def corrected_mm(message: str) -> float:
    """How far the sway feedback moved the axes (mm), as the goal's result says."""
    found = re.search(r'the sway feedback having moved the axes up to ([0-9.]+) mm', message)
    assert found, message
    return float(found.group(1))


@pytest.mark.parametrize('method, bound', [('nvf', 1e-3), ('zv', 1e-3)])
def test_the_perturbed_crane_with_feedback_ends_quiet_at_its_goal(perturbed, method, bound):
    """0.3 m in 2.5 s with the sim's L1 0.42 m: open loop leaves 8.6 mm (NVF) and 8.9 mm (ZV); with the feedback
    the goal succeeds once the corrected reference is back at its goal, with its residual under the bound. (RVF,
    insensitive to L1 by design, leaves the feedback little to correct; the correction does not depend on the
    method.)"""
    crane = perturbed
    quiet(crane)
    here = crane.held()
    goal = 0.3 if here < 0.15 else 0.0
    start, _, _ = crane.move(method, None, goal, T, settle=1.0)
    result = crane.move_result(start, timeout=40.0)
    assert result.success, result.message
    assert result.residual_swing <= bound, result.message
    assert 0.1 < corrected_mm(result.message) < 30.0  # it corrected: centimetres at most
    assert crane.stream_hold() == pytest.approx(goal, abs=1e-3)
    last = crane.last_state()
    assert last[3] == pytest.approx(goal, abs=1e-3)


def test_a_push_at_rest_is_damped_within_one_period_and_the_cart_returns_to_its_hold(crane):
    from crane_planner.tools.harness import state_columns
    from crane_sim.metrics import residual_load_mm
    quiet(crane)
    held = crane.held()
    pushed = crane.now_ns() - 100_000_000  # (plant time runs the playout delay behind)
    crane.push_sim()
    crane.sleep(6.0)
    rows = state_columns(crane.states_between(pushed, pushed + 5_500_000_000, timeout=10.0))
    t = (rows['stamp'] - pushed) * 1e-9
    push = 0.03
    peak = residual_load_mm(t, rows['theta1'], rows['theta2'], NOMINAL.L1, NOMINAL.L2, after=t[0], until=1.0)
    assert peak == pytest.approx(1e3 * push, rel=0.1)  # the push, seen
    later = residual_load_mm(t, rows['theta1'], rows['theta2'], NOMINAL.L1, NOMINAL.L2, after=PERIOD + 0.3)
    assert later < 0.05 * 1e3 * push, later
    assert np.abs(rows['cart'] - held).max() < 0.05  # a correction of centimetres, not a run
    quiet(crane)  # the correction back to nothing: the cart where it was held
    assert crane.last_state()[3] == pytest.approx(held, abs=1e-3)
    assert math.isfinite(later)


def test_a_push_during_a_move_with_a_late_camera_leaves_the_load_quiet_and_the_cart_at_its_goal(crane):
    """The load pushed 30 mm at 40 % of a 3 s move, the camera 50 ms late (the sim's sensor_latency): the goal
    succeeds with a residual under 1.5 mm once settled, the cart at its goal."""
    quiet(crane)
    crane.set_parameters('sim', {'sensor_latency': 0.05})
    try:
        here = crane.held()
        goal = 0.3 if here < 0.15 else 0.0
        start, _, _ = crane.move('nvf', None, goal, 3.0, settle=1.0)
        crane.sleep(max(0.0, (start + 1_200_000_000 - crane.now_ns()) * 1e-9))
        crane.push_sim()
        result = crane.move_result(start, timeout=40.0)
        assert result.success and result.residual_swing <= 1.5e-3, result.message
        assert corrected_mm(result.message) > 1.0  # it had a push to correct
        assert crane.last_state()[3] == pytest.approx(goal, abs=1e-3)
    finally:
        crane.set_parameters('sim', {'sensor_latency': 0.0})


def one_second_into_a_move(crane) -> tuple[int, float]:
    """NVF 0.3 m in 2.5 s (out to 0.3 m, or back to 0), the references kept: (its motion's start, its goal), once
    it has run for 1 s."""
    crane.keep_references(True)
    here = crane.held()
    goal = 0.3 if here < 0.15 else 0.0
    start, _, _ = crane.move('nvf', None, goal, T, settle=1.0)
    crane.sleep(max(0.0, (start + 1_000_000_000 - crane.now_ns()) * 1e-9))
    return start, goal


def test_joint_states_lost_during_a_move_fade_the_correction_without_a_jump_and_the_motion_ends_open_loop(crane):
    """Every camera sample lost (the sim's sensor_dropout 1) from 1 s into a move on the perturbed crane: the
    streamer's feedback goes 'lost' on /diagnostics, the correction fades without a jump in the reference, and the
    goal ends as open loop would (no joint_states in its window: the residual not measured); samples back, the
    feedback is active again."""
    from crane_msgs_py.runtime.diagnostics import status_values
    quiet(crane)
    crane.set_parameters('sim', {'L1': 0.42})
    try:
        start, goal = one_second_into_a_move(crane)
        mark = crane.planner.diagnostics.mark()
        crane.set_parameters('sim', {'sensor_dropout': 1.0})
        result = crane.move_result(start, timeout=40.0)
        references = crane.keep_references(False)
        lost = crane.planner.diagnostics.wait_for(lambda s: status_values(s).get('feedback') == 'lost', 5.0,
                                                  after=mark, name='crane_streamer: stream')
        assert lost is not None, 'the streamer never said its feedback was lost'
        assert 'residual not measured' in result.message, result.message
        rows = references[references[:, 0] >= start]
        steps = np.abs(np.diff(rows[:, 1]))
        assert steps.max() < 0.35 * 1e-3 + 1e-6  # each tick's step within the velocity limit (0.3 m/s): no jump
    finally:
        crane.keep_references(False)
        crane.set_parameters('sim', {'sensor_dropout': 0.0, 'L1': NOMINAL.L1})
    mark = crane.planner.diagnostics.mark()
    active = crane.planner.diagnostics.wait_for(lambda s: status_values(s).get('feedback') == 'active', 5.0,
                                                after=mark, name='crane_streamer: stream')
    assert active is not None, 'the feedback did not resume with the samples back'
    # and the cart ends where the stream holds it: the sim's parameters changed mid-motion lost no reference
    quiet(crane)
    assert crane.last_state()[3] == pytest.approx(goal, abs=1e-3)


class NanCamera:
    """joint_states of a camera that has lost the load, published by the test at 50 Hz: the angles NaN, the cart's
    position finite (its drive's, where the streamer streams it), each stamped as the sim stamps its samples (plant
    time: the clock less the sim's playout delay), on a thread of its own until ``stop()``; how many it sent."""

    def __init__(self, crane, delay: float = 0.1):
        from sensor_msgs.msg import JointState

        from crane_msgs_py.messages.names import JOINT_STATES_TOPIC
        from crane_msgs_py.runtime.qos import JOINT_STATES_QOS
        self.crane, self.delay, self.sent = crane, delay, 0
        self._message = JointState(name=['cart', 'theta1', 'theta2'])
        self._publisher = crane.node.create_publisher(JointState, JOINT_STATES_TOPIC, JOINT_STATES_QOS)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self):
        from crane_msgs_py.messages.conversions import set_stamp
        while not self._stop.wait(0.02):
            cart = self.crane.stream_hold()
            msg = self._message
            set_stamp(msg.header.stamp, self.crane.now_ns() - round(self.delay * 1e9))
            msg.position = [math.nan if cart is None else cart, math.nan, math.nan]
            msg.velocity = [0.0, math.nan, math.nan]
            self._publisher.publish(msg)
            self.sent += 1

    def stop(self) -> int:
        self._stop.set()
        self._thread.join(5.0)
        self.crane.node.destroy_publisher(self._publisher)
        return self.sent


def test_joint_states_with_non_finite_angles_during_a_move_are_no_measurement_and_the_motion_ends_open_loop(crane):
    """From 1 s into a move on the perturbed crane the camera has lost the load: the sim's samples stop (its
    sensor_dropout 1) and joint_states with NaN angles come instead (the test's, stamped as the sim stamps its own,
    50 Hz). They arrive but measure nothing (the planner drops them; its executor once died of the first): the
    streamer counts them as unused, its feedback goes 'lost', the
    correction fades with no jump in the reference (every value finite, each tick's step within the velocity
    limit) to a micrometre, the reference the plan's hold at the goal (open loop); the goal ends as open loop's would
    with that camera (the motion to its end, the residual not measured); finite samples back, it is active again."""
    from crane_msgs_py.runtime.diagnostics import status_values
    quiet(crane)
    name = 'crane_streamer: stream'

    def unused(status) -> int:
        return int(status_values(status).get('feedback_measurements_unused', -1))

    crane.set_parameters('sim', {'L1': 0.42})
    camera = None
    try:
        start, goal = one_second_into_a_move(crane)
        corrected = abs(crane.correction()['cart'])  # what is left to fade
        before = crane.planner.diagnostics.wait_for(timeout=5.0, name=name, after=crane.planner.diagnostics.mark())
        crane.set_parameters('sim', {'sensor_dropout': 1.0})
        camera = NanCamera(crane)
        result = crane.move_result(start, timeout=40.0)
        lost = crane.planner.diagnostics.wait_for(lambda s: status_values(s).get('feedback') == 'lost', 5.0,
                                                  after=crane.planner.diagnostics.mark(), name=name)
        assert lost is not None, 'the streamer never said its feedback was lost'
        # open loop: the correction faded to a micrometre, the published reference the plan's hold at the goal
        crane.wait_until(lambda: abs(crane.correction()['cart']) < 1e-6, 10.0, 'the correction never faded')
        references = crane.keep_references(False)
        sent = camera.stop()
        camera = None
    finally:
        if camera is not None:
            camera.stop()
        crane.keep_references(False)
        crane.set_parameters('sim', {'sensor_dropout': 0.0, 'L1': NOMINAL.L1})
    assert corrected > 1e-4, corrected  # the feedback was correcting when the camera lost the load
    assert sent >= 50 and unused(lost) - unused(before) >= 10, (sent, unused(before), unused(lost))
    assert result.success and 'residual not measured' in result.message, result.message
    rows = references[references[:, 0] >= start]
    assert np.all(np.isfinite(rows[:, 1:4]))
    assert np.abs(np.diff(rows[:, 1])).max() < 0.35 * 1e-3 + 1e-6  # each tick within the velocity limit: no jump
    assert rows[-1, 1] == pytest.approx(goal, abs=1e-6) and abs(rows[-1, 2]) < 1e-5 and abs(rows[-1, 3]) < 1e-4
    mark = crane.planner.diagnostics.mark()
    active = crane.planner.diagnostics.wait_for(lambda s: status_values(s).get('feedback') == 'active', 5.0,
                                                after=mark, name=name)
    assert active is not None, 'the feedback did not resume with finite samples back'
    quiet(crane)
    assert crane.last_state()[3] == pytest.approx(goal, abs=1e-3)


#: The wind test's disturbance (the sim's wind, gust and gust_time) and how long it blows open and closed loop.
WIND, GUST, GUST_TIME = 0.3, 0.2, 1.0
OPEN, CLOSED, DAMPED = 2.0, 12.0, 2.5  # s: open loop, then closed loop, of which the first DAMPED s are not judged
STEP_NS = 1_000_000  # the sim's step


def open_loop_replay(steps: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """The load's excursion (m) after each of ``steps`` 1 ms steps of crane_sim's own plant from rest under a held
    cart, with the wind and the gusts the sim blows from the moment they are first set: the same stream of its
    ``seed`` (``crane_sim.disturbances.Gust``: drawn stationary then, one draw per step, held over it); and the
    gust (m/s^2) over each step."""
    from crane_msgs_py.crane.geometry import load_excursion
    from crane_sim.disturbances import Gust
    from crane_sim.simulator import CraneSimulator
    gusts = Gust(GUST, GUST_TIME, 1, seed).path(steps, STEP_NS * 1e-9)[0]
    sim = CraneSimulator(NOMINAL, dt=STEP_NS * 1e-9)
    out = np.empty(steps)
    for k in range(steps):
        sim.disturbance = (WIND + gusts[k + 1], 0.0)
        sim.step(0.0)
        swing = sim.swing
        out[k] = load_excursion(swing.theta1, swing.theta2, NOMINAL.L1, NOMINAL.L2)
    return out, gusts[1:]


def onset_fit(stamps: np.ndarray, measured: np.ndarray, replay: np.ndarray, earliest: int, latest: int):
    """(the plant time (ns) at which the wind began, on the sim's step grid within [earliest, latest], the largest
    misfit (m) of ``measured`` against ``replay`` begun then): at rest before it, the replay's step ending at each
    stamp after."""
    best = (0, math.inf)
    first = int(stamps[0] + (earliest - stamps[0]) // STEP_NS * STEP_NS)
    for onset in range(first, latest + STEP_NS, STEP_NS):
        k = (stamps - onset) // STEP_NS - 1
        model = np.where(k >= 0, replay[np.clip(k, 0, len(replay) - 1)], 0.0)
        misfit = float(np.max(np.abs(measured - model)))
        if misfit < best[1]:
            best = (onset, misfit)
    return best


def test_wind_and_gusts_at_rest_the_feedback_keeps_the_swing_about_its_mean_well_below_open_loops(crane):
    """Wind 0.3 m/s^2 with gusts of 0.2 m/s^2 (1 s) on the load at rest: 2 s open loop, then the feedback switched
    on for 12 s. The open loop is replayed on crane_sim's own plant with the sim's gust stream (its seed 0, drawn
    from the moment the gusts are first set, the wind and the gusts set together): the first 2 s match what
    joint_states measured to 1 um, so the replay is this run's open loop, gust for gust. Over the closed loop's last
    9.5 s (its first 2.5 s damp the swing the open loop built) the swing about its mean is at most half the
    replay's over the same stamps and within 1.6 times the lean into the same gusts ((L1 + L2) w / g, the floor no
    damping passes: the offline bound), and the streamed reference keeps within the cart's limits (0.3 m/s,
    0.5 m/s^2, 5 m/s^3), decimetres from its hold.

    Why half: the ratio depends on the gusts' path. Offline (20 s, the sim's gusts of seeds 0-3) it is 0.17 with
    seed 0 and up to 0.58 where open loop stayed quiet: what is left is mostly the lean, which damping cannot
    remove. Measured against the same path it is a property of the run, not a draw: on this seed's path the open
    loop swings 87 mm RMS, the closed loop 18.7 mm (0.22; the lean 14.1 mm); 0.5 leaves room for the real-time
    run's timing, and fails at once with the feedback left off (1.00)."""
    from crane_msgs_py.crane.geometry import load_excursion
    from crane_planner.tools.harness import state_columns
    quiet(crane)
    held = crane.held()
    crane.set_parameters('streamer', {'feedback': False})
    try:
        crane.wait_until(lambda: crane.correction()['cart'] == 0.0, 10.0, 'the correction never faded')
        crane.reset_sim()  # the plant exactly at rest under the hold, as the replay starts
        rested = crane.now_ns()  # (its reply comes with the first sample after it)
        crane.sleep(0.1)  # samples at rest before the wind: they pin its onset
        crane.keep_references(True)
        asked = crane.now_ns()
        crane.set_parameters('sim', {'wind': [WIND, 0.0], 'gust': GUST, 'gust_time': GUST_TIME},
                             atomically=True)  # (the wind and the gusts from the same step, as replayed)
        applied = crane.now_ns()
        crane.sleep(OPEN)
        switched = crane.now_ns()
        crane.set_parameters('streamer', {'feedback': True})
        crane.sleep(CLOSED)
        references = crane.keep_references(False)
        end = crane.now_ns() - 200_000_000  # (plant time runs the playout delay behind)
    finally:
        crane.keep_references(False)
        crane.set_parameters('sim', {'wind': [0.0, 0.0], 'gust': 0.0})
        crane.set_parameters('streamer', {'feedback': True})
    delay = 100_000_000  # the sim's playout delay: plant time is the clock less it
    rows = state_columns(crane.states_between(rested - delay, end, timeout=10.0))
    stamps = rows['stamp'].astype(np.int64)
    measured = load_excursion(rows['theta1'], rows['theta2'], NOMINAL.L1, NOMINAL.L2)
    earliest, latest = asked - delay - 50_000_000, applied - delay + 50_000_000  # (the wind's onset, plant time)
    replay, gusts = open_loop_replay(int((stamps[-1] - earliest) // STEP_NS) + 2)
    opened = stamps < switched - delay
    onset, misfit = onset_fit(stamps[opened], measured[opened], replay, earliest, latest)
    assert misfit < 1e-6, f'open loop is not the replay of the sim\'s gusts: {1e3 * misfit:.3f} mm off'
    assert np.count_nonzero(stamps < onset) >= 2  # (at rest before it: the onset is pinned to the step)
    judged = stamps >= switched - delay + round(DAMPED * 1e9)
    assert judged.sum() > 40 * (CLOSED - DAMPED - 0.5), judged.sum()
    steps = (stamps[judged] - onset) // STEP_NS - 1
    closed, open_loop = float(np.std(measured[judged])), float(np.std(replay[steps]))
    lean = float(np.std((NOMINAL.L1 + NOMINAL.L2) / NOMINAL.g * gusts[steps]))  # the floor: leaning into the gusts
    print(f'\nwind {WIND} m/s^2, gusts {GUST} m/s^2: the swing about its mean {1e3 * closed:.1f} mm RMS with the '
          f'feedback, {1e3 * open_loop:.1f} mm open loop on the same gusts ({closed / open_loop:.2f}), the lean into '
          f'them {1e3 * lean:.1f} mm ({closed / lean:.2f})')
    assert closed <= 0.5 * open_loop and closed <= 1.6 * lean, (closed, open_loop, lean)
    # within the cart's limits, every tick of the run (a sample the recording missed spans two)
    ticks = np.maximum(np.round(np.diff(references[:, 0]) * 1e-6), 1.0)
    assert np.abs(references[:, 2]).max() <= 0.3 + 1e-9 and np.abs(references[:, 3]).max() <= 0.5 + 1e-9
    assert (np.abs(np.diff(references[:, 3])) / ticks).max() <= 5.0 * 1e-3 * (1 + 1e-6) + 1e-9
    assert np.abs(references[:, 1] - held).max() < 0.2
    # (the load is left swinging after the gusts: each test here begins by waiting for the feedback to quiet it)
