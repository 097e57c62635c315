"""ROS: the runway over real nodes, two cranes each its own process group (separate DDS participants) in its own
namespace of one private graph (contract "Cranes sharing a runway"; docs/runway.md): crane a (planner, streamer and
sim in /crane_a) at runway_offset [0, 0], crane b (streamer and sim in /crane_b: no planner, so nothing of b's is
published on /runway/occupancy and a's planner plans as if b were not there) at [0, 2.0], both with the bridge
(joints [cart, bridge]), runway on, runway_min_distance 0.2 m, runway_timeout 0.5 s.

Here: an unusable occupancy published by the test is ignored and counted; a planner whose runway_offset puts its
girder on another's exits at start-up naming both; ``refuse`` names the crane in the way and ``wait`` says the
delay; the guard stops a goal of a towards b (its result says so) and stops a when b, within reach, is killed,
until b is heard again. Where the cranes are is measured from both sims' joint_states, placed in the runway frame
(crane_sim's own cable directions for the masses), never from what the streamers say. (Two cranes' goals sent
together, one waiting, and an operator stopped by the guard: the demo's runway case, test_demo.py.)
"""
import math
import os
import signal
import threading
from types import SimpleNamespace

import numpy as np
import pytest

from crane_msgs_py.crane.params import CraneParams

A, B = 'crane_a', 'crane_b'
NS_A, NS_B = f'/{A}', f'/{B}'
JOINTS = ['cart', 'bridge']
MIN, TIMEOUT, HALF = 0.2, 0.5, 0.05  # runway_min_distance (m), runway_timeout (s), girder and load half sizes (m)
B_Y = 2.0  # crane b's runway_offset y: its girder stands there
RUNWAY = {'runway': True, 'runway_min_distance': MIN, 'runway_timeout': TIMEOUT}
PLANNER_A = {**RUNWAY, 'runway_offset': [0.0, 0.0], 'solver_processes': 1}
STREAMER_A = {**RUNWAY, 'runway_offset': [0.0, 0.0]}
STREAMER_B = {**RUNWAY, 'runway_offset': [0.0, B_Y], 'joints': JOINTS}
P = CraneParams()
S = 1_000_000_000


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
    """Both cranes up; a's harness, b's node group, a stick on a's cmd_vel, the recorder, and what the test hears
    on /runway/occupancy (``heard``: (received ns, message)) and publishes there (``publish``); everything
    stopped after."""
    from crane_interfaces.msg import Occupancy

    from crane_msgs_py.runtime.qos import RUNWAY_OCCUPANCY_QOS
    from crane_planner.runway.config import OCCUPANCY_TOPIC
    from crane_planner.tools.harness import CraneHarness, start_crane_nodes
    from crane_planner.tools.processes import NodeGroup
    from crane_planner.tools.runway_demo import Stick
    a = NodeGroup(ros_domain, tmp_path_factory.mktemp('crane_a-node-logs'))
    b = NodeGroup(ros_domain, tmp_path_factory.mktemp('crane_b-node-logs'))
    driver = stick = None
    try:
        start_b(b)
        start_crane_nodes(a, NS_A, streamer_params=STREAMER_A, joints=JOINTS, planner_params=PLANNER_A)
        driver = CraneHarness(NS_A, a)
        recorder = Recorder(driver)
        heard, lock = [], threading.Lock()

        def on_occupancy(msg):
            with lock:
                heard.append((driver.now_ns(), msg))

        driver.node.create_subscription(Occupancy, OCCUPANCY_TOPIC, on_occupancy, RUNWAY_OCCUPANCY_QOS)
        publisher = driver.node.create_publisher(Occupancy, OCCUPANCY_TOPIC, RUNWAY_OCCUPANCY_QOS)
        driver.wait_until_up(120.0)
        driver.wait_until(lambda: recorder.heard(B) and recorder.heard(A), 30.0,
                          'the cranes never said where they are on /runway/state')
        stick = Stick(driver.node, NS_A)
        yield SimpleNamespace(a=driver, b=b, stick=stick, recorder=recorder, heard=heard, lock=lock,
                              publish=publisher.publish, tmp=tmp_path_factory)
        driver.nodes.check_alive()
    finally:
        if stick is not None:
            stick.close()
        if driver is not None:
            driver.close()
        a.stop(timeout=10.0)
        b.stop(timeout=10.0)


def heard_occupancies(cranes, crane: str) -> list:
    with cranes.lock:
        return [msg for _, msg in cranes.heard if msg.crane == crane]


def runway_footprints(rows: np.ndarray, offset_y: float):
    """A crane's footprint (``runway.occupancy.Footprint``) at each joint_states row, in the runway frame."""
    from crane_planner.runway.occupancy import Footprint
    from crane_planner.tools.harness import measured_masses, state_columns
    rec = state_columns(rows)
    m1, m2 = measured_masses(rec, P.L1, P.L2)
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
    return 1e3 * load_swing(rec['theta1'], rec['theta2'], P.L1, P.L2, rec['phi1'], rec['phi2'])


def bridge(driver) -> float:
    return driver.last_state()[4]  # (STATE_COLUMNS: stamp, theta1, theta2, cart, bridge, ...)


def test_unusable_occupancies_are_ignored_and_counted_on_diagnostics(cranes):
    """Unordered times, a NaN, arrays of different lengths and another frame: the planner ignores them and counts
    them on /diagnostics. (The last, used, would hold crane x across both cranes' girders: every goal of a
    towards b would be refused.)"""
    from crane_interfaces.msg import Occupancy

    from crane_msgs_py.runtime.diagnostics import WARN, level_of, status_values

    def occupancy(**fields):
        msg = Occupancy(crane='crane_x', t=[0.0, 0.5], girder=[1.0, 1.0], hook_x=[0.0, 0.0], hook_y=[0.0, 2.0],
                        load_x=[0.0, 0.0], load_y=[0.0, 2.0], girder_half_width=0.05, load_half_size=0.05)
        msg.header.frame_id = 'runway'
        for key, value in fields.items():
            setattr(msg, key, value)
        return msg

    bad = [occupancy(t=[0.0, -0.5]), occupancy(load_y=[0.0, math.nan]), occupancy(girder=[1.0]), occupancy()]
    bad[-1].header.frame_id = 'crane_base'
    for msg in bad:
        cranes.publish(msg)
    status = cranes.a.planner.diagnostics.wait_for(
        lambda s: int(status_values(s).get('ignored', 0)) >= 4, 10.0, name='crane_planner: runway',
        hardware_id=f'{NS_A}/crane_planner')
    assert status is not None, 'the planner did not count 4 ignored occupancies'
    assert level_of(status) == WARN and status_values(status)['ignored'] == '4'
    assert "occupancy of 'crane_x': header.frame_id 'crane_base' is not 'runway'" in status.message
    reasons = [s.message for s in cranes.a.planner.diagnostics.statuses(name='crane_planner: runway',
                                                                        hardware_id=f'{NS_A}/crane_planner')]
    assert any('t must start at 0 and increase' in r for r in reasons)
    assert any('load_y has a value that is not finite' in r for r in reasons)
    assert any('must have one equal, non-zero length, got t 2, girder 1' in r for r in reasons)


def test_a_runway_offset_on_another_crane_s_girder_is_refused_at_start_up_naming_both(cranes):
    from crane_planner.tools.processes import PLANNER as PLANNER_EXE
    from crane_planner.tools.processes import NodeGroup
    cranes.a.wait_until(lambda: any(len(m.t) == 1 and m.girder[0] == 0.0 for m in heard_occupancies(cranes, A)),
                        5.0, 'crane a\'s hold at y 0 never heard')
    nodes = NodeGroup(cranes.a.nodes.env, cranes.tmp.mktemp('crane_c-node-logs'))
    try:
        proc = nodes.start(*PLANNER_EXE, namespace='/crane_c', params={**PLANNER_A, 'runway_offset': [0.0, 0.25]})
        assert proc.popen.wait(timeout=60.0) == 2
        lines = proc.log_path.read_text().strip().splitlines()
    finally:
        nodes.stop()
    [line] = [line for line in lines if line.startswith('PlannerNode: ')]
    assert line.startswith("PlannerNode: runway_offset [0.0, 0.25]: crane 'crane_c''s girder at y 0.25 m would "
                           'be 0.150 m from crane \'crane_a\'\'s at y 0 m, closer than runway_min_distance 0.2 m')


def test_refuse_names_the_crane_in_the_way_and_wait_says_the_delay_and_the_crane(cranes):
    """A third crane, z, made up by the test (its occupancy published on /runway/occupancy), standing 0.25 m
    beyond a's goal and leaving 1 s after a's start (0.6 m in 4 s): a preview of that goal is refused naming z
    with runway_policy refuse (also on /diagnostics), and with wait starts later by the delay it says (offline
    0.65 s), behind z. (z then says it went far away: a newer occupancy replaces the older.)"""
    from crane_msgs_py.messages.conversions import move_message, stamp_ns
    from crane_msgs_py.runtime.diagnostics import ERROR, level_of
    from crane_planner.nodes.occupancy_messages import to_message
    from crane_planner.planning.dispatch import plan
    from crane_planner.runway.occupancy import Footprint, Shape, holding
    from crane_planner.runway.prediction import plan_occupancy
    a = cranes.a
    assert abs(bridge(a)) < 1e-3  # (a at home: the numbers below are from there)
    start = a.now_ns() + round(2.0e9)
    z = plan_occupancy('crane_z', plan('zv', 0.0, 4.0, P, bridge=0.6), P, {'cart': 0.0, 'bridge': 0.0},
                       (0.0, 0.85), start + round(1e9), a.now_ns(), Shape(), settle=1.0)
    cranes.publish(to_message(z))
    a.wait_until(lambda: heard_occupancies(cranes, 'crane_z'), 5.0, 'crane z never heard')
    move = move_message([0.6], 2.0, [], 'zv', ['bridge'], start)
    mark = a.planner.diagnostics.mark()
    try:
        a.set_parameters('planner', {'runway_policy': 'refuse'})
        refused = a.planner.call('zv', None, 0.6, 2.0, move=move)
    finally:
        a.set_parameters('planner', {'runway_policy': 'wait'})
    assert not refused.success and refused.message.startswith('runway: the move would come within 0.'), refused.message
    assert refused.message.endswith("m of crane 'crane_z' (runway_min_distance 0.2 m and a margin of 0.02 m): "
                                    'refused'), refused.message
    status = a.planner.diagnostics.wait_for(name='crane_planner: plan', after=mark, timeout=5.0,
                                            hardware_id=f'{NS_A}/crane_planner')
    assert status is not None and level_of(status) == ERROR and "crane 'crane_z'" in status.message
    preview = a.planner.call('zv', None, 0.6, 2.0, move=move)
    assert preview.success and preview.info.runway_waited_for == 'crane_z' and preview.info.runway_delay > 0.3
    assert stamp_ns(preview.trajectory.header.stamp) == start + round(preview.info.runway_delay * 1e9)
    # z goes far away (behind a), so that it is in nobody's way in the tests below
    cranes.publish(to_message(holding('crane_z', a.now_ns(), Footprint.at_rest(-10.0, 0.0), Shape())))
    a.wait_until(lambda: heard_occupancies(cranes, 'crane_z')[-1].girder[0] == -10.0, 5.0, 'z never heard gone')


def test_a_goal_towards_the_other_crane_is_stopped_short_of_it_and_its_result_says_which_crane_and_why(cranes):
    """A ZV goal into b's way (b publishes no plan: a's planner does not know b), stopped by a's guard short of the
    minimum; the goal's result names b and says how it stopped: the planned stop (NVF, in the stop worker),
    without swing, or, when the stop worker cannot have it within the guard's lead (its planning time is the
    host's: 0.04-0.07 s idle for this one, ``bench/guard_stops.py``), the braking ramp, which swings."""
    driver, recorder = cranes.a, cranes.recorder
    cart, y0 = driver.held('cart'), driver.held('bridge')
    begin = driver.now_ns()
    # onto b's girder (1 s ahead: a's planner, on the runway, starts no goal sooner than its claim window allows)
    start, _, _ = driver.move('zv', cart, cart, 5.0, bridge=(y0, B_Y - 0.1), start_ns=driver.now_ns() + S)
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
    driver.reset_sim()  # (the next test from rest: the braking ramp leaves a swing)


def test_the_other_crane_killed_within_reach_stops_this_one_until_it_is_heard_again(cranes):
    """Crane a's operator creeping towards b (0.05 m/s) when b's streamer and sim are SIGKILLed: a stops within
    runway_timeout and its stop, stays though pushed on, and moves on once b, started again, is heard."""
    driver, b, stick, recorder = cranes.a, cranes.b, cranes.stick, cranes.recorder
    driver.sleep(0.5)  # (the goal's settle played out: a mode changes only at rest)
    driver.set_parameters('streamer', {'mode': 'operator'})
    creep = 0.05  # m/s towards b
    start_y = bridge(driver)
    stick.velocity = creep
    driver.wait_until(lambda: bridge(driver) > start_y + 0.005, 10.0, 'the stick never moved a')
    assert not recorder.heard(A, driver.now_ns() - S // 2, 'lost')
    for proc in list(b.processes):  # b's streamer and sim, their whole process groups
        os.killpg(proc.popen.pid, signal.SIGKILL)
        proc.popen.wait()
    killed = driver.now_ns()
    b.processes.clear()
    driver.wait_until(lambda: recorder.heard(A, killed, 'lost'), 10.0, 'a never said b was lost')
    driver.sleep(2.5)  # its stop: braked and shaped from 0.05 m/s
    rested = driver.now_ns()
    rows = driver.states_between(killed - S // 2, rested, timeout=5.0)
    y_kill = float(np.interp(killed, rows[:, 0], rows[:, 4]))
    y_rest = rows[-1, 4]
    # at rest though the stick still pushes towards b, after going on for the timeout from b's last state and
    # then its stop: 0.05 m/s x 0.5 s and the shaped stop's 0.03 m (its lag 0.5 s and the braking), with 0.1 s of
    # the middleware's and the loop's slack
    assert np.ptp(rows[rows[:, 0] >= rested - S // 2, 4]) < 1e-5  # (10 um: the servo settling, not a creep)
    reach = creep * (TIMEOUT + 0.1) + 0.031
    print(f'\nb killed with a at y {y_kill:.4f} m: a at rest at {y_rest:.4f} m ({1e3 * (y_rest - y_kill):.1f} mm on; '
          f'at most {1e3 * reach:.1f} mm)')
    assert creep * TIMEOUT * 0.8 < y_rest - y_kill <= reach
    # b started again: a moves on once b is heard, not before
    restarted = driver.now_ns()
    start_b(b)
    driver.wait_until(lambda: recorder.heard(B, restarted), 30.0, 'b never said where it is again')
    driver.wait_until(lambda: bridge(driver) > y_rest + 0.01, 10.0, 'a never moved on once b was heard again')
    stick.velocity = 0.0
    # a's own word (its CraneState): lost from the kill until after b was started again (b's first states may
    # reach a sooner than this test: each participant discovers a new one on its own)
    resumed = min(s[2] for s in recorder.heard(A, rested) if s[4] != 'lost')
    assert not [s for s in recorder.heard(A, rested) if s[4] != 'lost' and s[2] < restarted]
    assert resumed > restarted
    still = driver.states_between(rested, resumed - 20_000_000, timeout=5.0)  # (a's state before: still lost)
    assert len(still) > 25 and np.ptp(still[:, 4]) < 1e-5  # at rest while b was silent, pushed towards it
    driver.wait_until_still(joints=('bridge',))
