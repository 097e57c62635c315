"""ROS: the streamer's runway guard with two cranes on one runway, each its own process group (separate DDS
participants) in its own namespace: crane a (planner, streamer, sim in /crane_a, operator mode) at runway_offset
[0, 0] and crane b (streamer and sim in /crane_b: its planner has nothing to do here) at [0, 2.0], both with the
bridge (joints [cart, bridge]), runway on, runway_min_distance 0.2 m.

Where the cranes are is measured from both sims' joint_states, placed in the runway frame (crane_sim's own cable
directions for the masses), never from what the streamers say: an operator driving a at full speed towards b
stops short of the minimum without swing, is refused further and goes away; b killed (SIGKILL) while within
reach stops a within runway_timeout and its stop, and a moves on once b, started again, is heard."""
import math
import os
import signal
import threading

import numpy as np
import pytest

from crane_msgs_py.crane.params import CraneParams

NS_A, NS_B = '/crane_a', '/crane_b'
JOINTS = ['cart', 'bridge']
MIN, TIMEOUT, HALF = 0.2, 0.5, 0.05  # runway_min_distance (m), runway_timeout (s), girder and load half sizes (m)
B_Y = 2.0  # crane b's runway_offset y: its girder stands there
RUNWAY = {'runway': True, 'runway_min_distance': MIN, 'runway_timeout': TIMEOUT}
STREAMER_A = {**RUNWAY, 'runway_offset': [0.0, 0.0], 'mode': 'operator'}
STREAMER_B = {**RUNWAY, 'runway_offset': [0.0, B_Y], 'joints': JOINTS}
NOMINAL = CraneParams()
FULL_SPEED = 0.3  # m/s: the bridge's operator limit
S = 1_000_000_000


class Stick:
    """A joystick on crane a's cmd_vel: the bridge's velocity (m/s) held, published at 20 Hz from a thread."""

    def __init__(self, node):
        from geometry_msgs.msg import Twist
        self._twist, self._pub = Twist, node.create_publisher(Twist, f'{NS_A}/cmd_vel', 10)
        self.velocity, self._stop = 0.0, threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self):
        while not self._stop.wait(0.05):
            msg = self._twist()
            msg.linear.y = float(self.velocity)
            self._pub.publish(msg)

    def close(self):
        self.velocity = 0.0
        self._stop.set()
        self._thread.join()


class Recorder:
    """Crane b's joint_states (rows of the harness's STATE_COLUMNS) and every crane's /runway/state as received
    (received ns, crane, stamp ns, girder, guard, guard crane)."""

    def __init__(self, driver):
        from crane_interfaces.msg import CraneState
        from sensor_msgs.msg import JointState

        from crane_msgs_py.messages.conversions import stamp_ns
        from crane_msgs_py.runtime.qos import JOINT_STATES_QOS, RUNWAY_STATE_QOS, recording
        from crane_planner.tools.harness import STATE_COLUMNS
        self._lock, self.b_rows, self.states = threading.Lock(), [], []

        def on_joint_state(msg):
            names = list(msg.name)
            row = (stamp_ns(msg.header.stamp), *(msg.position[names.index(j)] if j in names else math.nan
                                                 for j in STATE_COLUMNS[1:]))
            with self._lock:
                self.b_rows.append(row)

        def on_crane_state(msg):
            with self._lock:
                self.states.append((driver.now_ns(), msg.crane, stamp_ns(msg.header.stamp), msg.girder, msg.guard,
                                    msg.guard_crane))

        driver.node.create_subscription(JointState, f'{NS_B}/joint_states', on_joint_state,
                                        recording(JOINT_STATES_QOS, 10.0, 50.0))
        driver.node.create_subscription(CraneState, '/runway/state', on_crane_state,
                                        recording(RUNWAY_STATE_QOS, 10.0, 100.0))

    def heard(self, crane: str, after_ns: int = 0, guard: str | None = None) -> list:
        """The states of ``crane`` received after ``after_ns`` (with its guard at ``guard``)."""
        with self._lock:
            return [s for s in self.states if s[1] == crane and s[0] > after_ns and guard in (None, s[4])]

    def b_between(self, begin_ns: int, end_ns: int) -> np.ndarray:
        with self._lock:
            return np.array([r for r in self.b_rows if begin_ns <= r[0] <= end_ns])


def start_b(nodes):
    from crane_planner.tools.processes import SIM, STREAMER
    nodes.start(*STREAMER, namespace=NS_B, params=STREAMER_B)
    nodes.start(*SIM, namespace=NS_B, params={'joints': JOINTS})


@pytest.fixture(scope='module')
def cranes(ros_domain, tmp_path_factory):
    """Both cranes up, a's harness, b's node group, the stick and the recorder; everything stopped after."""
    from crane_planner.tools.harness import CraneHarness, start_crane_nodes
    from crane_planner.tools.processes import NodeGroup
    a = NodeGroup(ros_domain, tmp_path_factory.mktemp('crane_a-node-logs'))
    b = NodeGroup(ros_domain, tmp_path_factory.mktemp('crane_b-node-logs'))
    driver = stick = None
    try:
        start_b(b)
        start_crane_nodes(a, NS_A, streamer_params=STREAMER_A, joints=JOINTS, planner_params={'solver_processes': 1})
        driver = CraneHarness(NS_A, a)
        recorder = Recorder(driver)
        driver.wait_until_up(90.0)
        driver.wait_until(lambda: recorder.heard('crane_b') and recorder.heard('crane_a'), 30.0,
                          'the cranes never said where they are on /runway/state')
        stick = Stick(driver.node)
        yield driver, b, stick, recorder
        driver.nodes.check_alive()
    finally:
        if stick is not None:
            stick.close()
        if driver is not None:
            driver.close()
        a.stop(timeout=10.0)
        b.stop(timeout=10.0)


def runway_footprints(rows: np.ndarray, offset_y: float):
    """A crane's footprint (``runway.occupancy.Footprint``) at each joint_states row, in the runway frame."""
    from crane_planner.runway.occupancy import Footprint
    from crane_planner.tools.harness import measured_masses, state_columns
    rec = state_columns(rows)
    m1, m2 = measured_masses(rec, NOMINAL.L1, NOMINAL.L2)
    masses = np.stack([m1[:, :2], m2[:, :2]], axis=1) + np.array([0.0, offset_y])
    return Footprint(rec['bridge'] + offset_y, masses)


def distance(a_rows: np.ndarray, b_rows: np.ndarray) -> np.ndarray:
    """The least distance (m) between the two cranes (girders, masses, their half sizes) at each of a's rows, b
    where its nearest row before says."""
    from crane_planner.runway.occupancy import Footprint, Shape, separation
    fa, fb = runway_footprints(a_rows, 0.0), runway_footprints(b_rows, B_Y)
    k = np.clip(np.searchsorted(b_rows[:, 0], a_rows[:, 0]) - 1, 0, len(b_rows) - 1)
    shape = Shape(HALF, HALF)
    return separation(fa, shape, Footprint(fb.girder[k], fb.masses[k]), shape)


def swing_mm(rows: np.ndarray) -> np.ndarray:
    """The load's swing (mm) at each row: the norm of its horizontal offset from below the trolley."""
    from crane_msgs_py.crane.geometry import load_swing
    from crane_planner.tools.harness import state_columns
    rec = state_columns(rows)
    return 1e3 * load_swing(rec['theta1'], rec['theta2'], NOMINAL.L1, NOMINAL.L2, rec['phi1'], rec['phi2'])


def bridge(driver) -> float:
    return driver.last_state()[4]  # (STATE_COLUMNS: stamp, theta1, theta2, cart, bridge, ...)


def guard_status(driver, after: int):
    """The newest status of a's guard on /diagnostics after the mark ``after`` (None if none)."""
    statuses = driver.planner.diagnostics.statuses(name='crane_streamer: runway guard',
                                                   hardware_id=f'{NS_A}/crane_streamer', after=after)
    return statuses[-1] if statuses else None


def test_an_operator_at_full_speed_towards_the_other_crane_stops_short_of_the_minimum_without_swing_and_goes_only_away(
        cranes):
    from crane_msgs_py.runtime.diagnostics import ERROR, level_of
    driver, _, stick, recorder = cranes
    begin, mark = driver.now_ns(), driver.planner.diagnostics.mark()
    stick.velocity = FULL_SPEED  # towards b, held
    driver.wait_until(lambda: recorder.heard('crane_a', begin, 'stop'), 20.0, 'a never stopped for b')
    driver.sleep(3.0)  # the stop (braked and shaped: 1.5 s at most) and then a second pushing on against it
    end = driver.now_ns()
    rows = driver.states_between(begin, end, timeout=5.0)
    y, gap = rows[:, 4], distance(rows, recorder.b_between(begin - S, end))
    pushed = rows[:, 0] >= end - S  # the last second: the stick still pushing towards b
    print(f'\na stopped at y {y[-1]:.4f} m, {gap.min():.4f} m from b at the closest (minimum {MIN} m); '
          f'swing then {swing_mm(rows[pushed]).max():.3f} mm')
    assert y[-1] > 1.0  # (it drove up to b)
    assert gap.min() >= MIN  # never closer than the minimum, girders and loads measured
    assert gap.min() <= MIN + 0.01  # and stopped where it had to, not a braking distance early
    assert np.ptp(y[pushed]) < 1e-6  # refused: at rest though pushed towards b
    assert swing_mm(rows[pushed]).max() <= 1.0  # stopped without swing
    status = guard_status(driver, mark)
    assert level_of(status) == ERROR and status.message.startswith('stop: crane_b, '), status.message
    # away is taken at once
    stick.velocity = -FULL_SPEED
    driver.wait_until(lambda: bridge(driver) < y[-1] - 0.3, 10.0, 'a never went away from b')
    stick.velocity = 0.0
    driver.wait_until_still(joints=('bridge',))


def test_the_other_crane_killed_within_reach_stops_this_one_until_it_is_heard_again(cranes):
    driver, b, stick, recorder = cranes
    creep = 0.05  # m/s towards b
    start_y = bridge(driver)
    stick.velocity = creep
    driver.wait_until(lambda: bridge(driver) > start_y + 0.005, 10.0, 'the stick never moved a')
    assert not recorder.heard('crane_a', driver.now_ns() - S // 2, 'lost')
    for proc in list(b.processes):  # b's streamer and sim, their whole process groups
        os.killpg(proc.popen.pid, signal.SIGKILL)
        proc.popen.wait()
    killed = driver.now_ns()
    b.processes.clear()
    driver.wait_until(lambda: recorder.heard('crane_a', killed, 'lost'), 10.0, 'a never said b was lost')
    driver.sleep(2.5)  # its stop: braked and shaped from 0.05 m/s
    rested = driver.now_ns()
    rows = driver.states_between(killed - S // 2, rested, timeout=5.0)
    y_kill = float(np.interp(killed, rows[:, 0], rows[:, 4]))
    y_rest = rows[-1, 4]
    # at rest though the stick still pushes towards b, after going on for the timeout from b's last state and
    # then its stop: 0.05 m/s x 0.5 s and the shaped stop's 0.03 m (its lag 0.5 s and the braking), with 0.1 s of
    # the middleware's and the loop's slack
    assert np.ptp(rows[rows[:, 0] >= rested - S // 2, 4]) < 1e-6
    reach = creep * (TIMEOUT + 0.1) + 0.031
    print(f'\nb killed with a at y {y_kill:.4f} m: a at rest at {y_rest:.4f} m ({1e3 * (y_rest - y_kill):.1f} mm on; '
          f'at most {1e3 * reach:.1f} mm)')
    assert creep * TIMEOUT * 0.8 < y_rest - y_kill <= reach
    # b started again: a moves on once b is heard, not before
    restarted = driver.now_ns()
    start_b(b)
    driver.wait_until(lambda: recorder.heard('crane_b', restarted), 30.0, 'b never said where it is again')
    driver.wait_until(lambda: bridge(driver) > y_rest + 0.01, 10.0, 'a never moved on once b was heard again')
    stick.velocity = 0.0
    # a's own word (its CraneState): lost from the kill until after b was started again (b's first states may
    # reach a sooner than this test: each participant discovers a new one on its own)
    resumed = min(s[2] for s in recorder.heard('crane_a', rested) if s[4] != 'lost')
    assert not [s for s in recorder.heard('crane_a', rested) if s[4] != 'lost' and s[2] < restarted]
    assert resumed > restarted
    still = driver.states_between(rested, resumed - 20_000_000, timeout=5.0)  # (a's state before: still lost)
    assert len(still) > 25 and np.ptp(still[:, 4]) < 1e-6  # at rest while b was silent, pushed towards it
    driver.wait_until_still(joints=('bridge',))


def test_a_goal_towards_the_other_crane_is_stopped_short_of_it_and_its_result_says_which_crane_and_why(cranes):
    """Trajectory mode (this planner plans no runway of its own here): a ZV goal into b's way, stopped by the
    guard short of the minimum; the goal's result names b and says how it stopped: the planned stop (NVF, in the
    stop worker), without swing, or, when the stop worker cannot have it within the guard's lead (a busy host:
    the spatial crane's first stops took seconds on this one), the braking ramp, which swings."""
    driver, _, stick, recorder = cranes
    stick.velocity = 0.0
    driver.wait_until_still(joints=('bridge',))
    driver.sleep(1.5)  # (the operator's shaper played out: a mode changes only at rest)
    driver.set_parameters('streamer', {'mode': 'trajectory'})
    driver.sleep(0.5)  # (the planner hears the mode on stream_state as the harness does; a busy host delays it)
    cart, y0 = driver.stream_hold('cart'), driver.stream_hold('bridge')
    begin = driver.now_ns()
    start, _, _ = driver.move('zv', cart, cart, 3.0, bridge=(y0, B_Y - 0.1))  # onto b's girder
    _, result = driver.outcome(start, timeout=30.0)
    assert not result.success
    assert 'it holds (the runway guard stopped it: crane_b, ' in result.message, result.message
    driver.wait_until_still(joints=('bridge',))
    end = driver.now_ns()
    rows = driver.states_between(begin, end, timeout=5.0)
    gap = distance(rows, recorder.b_between(begin - S, end))
    after = rows[:, 0] >= end - S // 2
    print(f'\nthe goal from y {y0:.3f} m towards b stopped at y {rows[-1, 4]:.4f} m, {gap.min():.4f} m from b at '
          f'the closest; swing then {swing_mm(rows[after]).max():.3f} mm; {result.message}')
    assert gap.min() >= MIN and rows[-1, 4] > y0 + 0.05  # it went towards b, and stopped short of the minimum
    assert ': stopping without swing at ' in result.message or ': stopping along the axes\' braking ramp (' in \
        result.message
    if ': stopping without swing at ' in result.message:
        assert swing_mm(rows[after]).max() <= 1.0
