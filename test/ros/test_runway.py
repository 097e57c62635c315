"""ROS: two cranes sharing a runway, each its own process group (planner, streamer, sim: separate DDS
participants) in its own namespace of one private graph, their planners on the runway (contract "Cranes sharing a
runway"; docs/runway.md).

Crane a's ``crane_base`` is at [0, 0] of the runway, crane b's at [0, 2] (bridges 2 m apart), both with the
joints [cart, bridge] and loads on the default 0.47 + 0.391 m cables, runway_min_distance 0.2 m. Both goals sent
at the same moment bring the cranes closer, one into the space the other leaves, their goals far enough apart
but not where the follower would be while the other is still there, its load leading as it brakes (numbers
found offline with runway.prediction and runway.schedule, checked on crane_sim): the follower waits, names the
other, neither stops. (Anti-sway moves towards each other whose goals clear the minimum never conflict on the
way: each load stays between its start and its goal; docs/runway.md.) The test measures both loads (hook and
load, from each sim's joint_states, placed in the runway by crane_sim's own cable geometry) and both girders
itself, and the residual swing after each motion. Also: an unusable occupancy published by the test is ignored
and counted, ``refuse`` names the crane, and a planner whose runway_offset puts its girder on another's exits at
start-up naming both.
"""
import math
import threading
from types import SimpleNamespace

import numpy as np
import pytest

from crane_msgs_py.crane.params import CraneParams

A, B = 'crane_a', 'crane_b'
OFFSETS = {A: (0.0, 0.0), B: (0.0, 2.0)}
JOINTS = ['cart', 'bridge']
MIN_DISTANCE = 0.2
PLANNER = {'runway': True, 'runway_min_distance': MIN_DISTANCE, 'solver_processes': 1}
P = CraneParams()
SETTLE = 1.0  # s of residual window: more than half the slow mode's period (1.73 s)
#: ZV: crane a's bridge 1.87 m towards b in 3 s, b's 0.3 m away in 5.5 s (offline: together they would come
#: within 0.15 m; a waits 0.45 s, then 0.206 m at the closest).
ZV_FOLLOW, ZV_LEAVE = 1.87, 0.3
STATUS_SUCCEEDED = 4  # action_msgs/GoalStatus


@pytest.fixture(scope='module')
def cranes(ros_domain, tmp_path_factory):
    """Both cranes' nodes, started together (two NodeGroups: two process groups), a harness each, and what the
    test hears on /runway/occupancy (``heard``: (received ns, message)) and publishes there (``publish``)."""
    from crane_interfaces.msg import Occupancy

    from crane_msgs_py.runtime.qos import RUNWAY_OCCUPANCY_QOS
    from crane_planner.runway.config import OCCUPANCY_TOPIC
    from crane_planner.tools.harness import CraneHarness, start_crane_nodes
    from crane_planner.tools.processes import NodeGroup
    groups = {name: NodeGroup(ros_domain, tmp_path_factory.mktemp(f'{name}-node-logs')) for name in (A, B)}
    drivers = {}
    try:
        for name, nodes in groups.items():
            start_crane_nodes(nodes, f'/{name}', joints=JOINTS,
                              planner_params={**PLANNER, 'runway_offset': list(OFFSETS[name])})
        for name, nodes in groups.items():
            drivers[name] = CraneHarness(f'/{name}', nodes)
        for driver in drivers.values():
            driver.wait_until_up(240.0)
        heard, lock = [], threading.Lock()
        node = drivers[A].node

        def on_occupancy(msg):
            with lock:
                heard.append((node.get_clock().now().nanoseconds, msg))

        node.create_subscription(Occupancy, OCCUPANCY_TOPIC, on_occupancy, RUNWAY_OCCUPANCY_QOS)
        publisher = node.create_publisher(Occupancy, OCCUPANCY_TOPIC, RUNWAY_OCCUPANCY_QOS)
        yield SimpleNamespace(a=drivers[A], b=drivers[B], groups=groups, heard=heard, lock=lock,
                              publish=publisher.publish, tmp=tmp_path_factory)
        for nodes in groups.values():
            nodes.check_alive()  # every node survived the whole module
    finally:
        for driver in reversed(list(drivers.values())):  # (a's harness owns the rclpy context: last)
            driver.close()
        for nodes in groups.values():
            nodes.stop(timeout=10.0)


def heard_occupancies(cranes, crane: str, after_ns: int = 0) -> list:
    with cranes.lock:
        return [msg for received, msg in cranes.heard if msg.crane == crane and received >= after_ns]


def bridge_move(method: str, goal: float, duration: float, start_ns: int):
    from crane_msgs_py.messages.conversions import move_message
    return move_message([goal], duration, [], method, ['bridge'], start_ns)


def send(driver, method: str, goal: float, duration: float, start_ns: int, settle: float = SETTLE):
    """An ExecuteMove goal of the bridge alone (its handle, once accepted)."""
    return driver.planner.send_execute(method, None, goal, duration, start_ns, settle, timeout=30.0,
                                       move=bridge_move(method, goal, duration, start_ns))


def result(driver, handle, timeout: float = 60.0):
    """(status, result) of a goal, whatever its outcome."""
    future = handle.get_result_async()
    driver.wait_until(future.done, timeout, f'no result within {timeout:g} s')
    return future.result().status, future.result().result


def send_together(cranes, goals: dict, start_ns: int, settle: float = SETTLE) -> dict:
    """Each crane's goal (method, bridge goal, duration) sent at once, from a thread each: crane -> handle."""
    handles, threads = {}, []
    for name, (method, goal, duration) in goals.items():
        driver = getattr(cranes, name[-1])
        threads.append(threading.Thread(target=lambda n=name, d=driver, m=(method, goal, duration): handles.__setitem__(
            n, send(d, *m, start_ns, settle))))
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(30.0)
    assert set(handles) == set(goals), 'a goal was not accepted'
    return handles


def footprints(cranes, begin_ns: int, end_ns: int) -> dict:
    """Each crane's measured girder and masses in the runway (``Footprint``) at its joint_states in [begin, end],
    each placed by its runway_offset: crane -> (stamps ns, Footprint)."""
    from crane_planner.runway.occupancy import Footprint
    from crane_planner.tools.harness import measured_masses, state_columns
    found = {}
    for name in (A, B):
        driver = getattr(cranes, name[-1])
        driver.sleep(max(0.0, (end_ns - driver.now_ns()) * 1e-9))
        rec = state_columns(driver.states_between(begin_ns, end_ns, timeout=30.0))
        assert len(rec['stamp']) > 40 * (end_ns - begin_ns) * 1e-9, f'{name}: only {len(rec["stamp"])} joint_states'
        m1, m2 = measured_masses(rec, P.L1, P.L2)
        offset = np.array(OFFSETS[name])
        masses = np.stack([m1[:, :2], m2[:, :2]], axis=1) + offset
        found[name] = (rec['stamp'], Footprint(rec['bridge'] + offset[1], masses), rec)
    return found


def closest_measured(found: dict) -> tuple[float, int]:
    """The least distance (m) between the two cranes as measured, and when (ns): b's joint_states interpolated to
    a's stamps (both sims stamp with the reference's time)."""
    from crane_planner.runway.occupancy import Footprint, Shape, separation
    (ta, fa, _), (tb, fb, _) = found[A], found[B]
    inside = (ta >= tb[0]) & (ta <= tb[-1])
    t = ta[inside]
    fa = Footprint(fa.girder[inside], fa.masses[inside])
    at = Footprint(np.interp(t, tb, fb.girder), np.stack([np.stack([np.interp(t, tb, fb.masses[:, m, c])
                                                                    for c in range(2)], axis=-1) for m in range(2)],
                                                          axis=1))
    d = separation(fa, Shape(), at, Shape())
    k = int(np.argmin(d))
    return float(d[k]), int(t[k])


def residual_mm(rec: dict, begin_ns: int) -> float:
    """The load's largest horizontal offset from below its suspension point (mm) after ``begin_ns``."""
    from crane_msgs_py.crane.geometry import load_offset
    after = rec['stamp'] >= begin_ns
    dx, dy = load_offset(rec['theta1'][after], rec['theta2'][after], rec['phi1'][after], rec['phi2'][after], P.L1,
                         P.L2)
    return 1e3 * float(np.hypot(dx, dy).max())


def occupancy_of(msg):
    from crane_planner.nodes.occupancy_messages import from_message
    return from_message(msg)


def dense_min_distance(a, b) -> float:
    from crane_planner.runway.occupancy import separation
    stamps = np.arange(min(a.start_ns, b.start_ns), max(a.end_ns, b.end_ns) + 1, 1_000_000)
    return float(separation(a.at(stamps), a.shape, b.at(stamps), b.shape).min())


def ignored_count(driver, name: str, at_least: int, timeout: float = 10.0):
    from crane_msgs_py.runtime.diagnostics import status_values
    status = driver.planner.diagnostics.wait_for(
        lambda s: int(status_values(s).get('ignored', 0)) >= at_least, timeout, name='crane_planner: runway',
        hardware_id=f'/{name}/crane_planner')
    return status


def test_unusable_occupancies_are_ignored_and_counted_on_diagnostics(cranes):
    """Unordered times, a NaN, arrays of different lengths and another frame: each planner ignores them and counts
    them on /diagnostics. (The last, used, would hold crane x across both cranes' girders: the goals of the next
    test would be refused.)"""
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
    for name in (A, B):
        status = ignored_count(getattr(cranes, name[-1]), name, 4)
        assert status is not None, f'{name} did not count 4 ignored occupancies'
        assert level_of(status) == WARN and status_values(status)['ignored'] == '4'
        assert "occupancy of 'crane_x': header.frame_id 'crane_base' is not 'runway'" in status.message
    reasons = [s.message for s in cranes.a.planner.diagnostics.statuses(name='crane_planner: runway',
                                                                        hardware_id=f'/{A}/crane_planner')]
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
        proc = nodes.start(*PLANNER_EXE, namespace='/crane_c', params={**PLANNER, 'runway_offset': [0.0, 0.25]})
        assert proc.popen.wait(timeout=60.0) == 2
        lines = proc.log_path.read_text().strip().splitlines()
    finally:
        nodes.stop()
    [line] = [line for line in lines if line.startswith('PlannerNode: ')]
    assert line.startswith("PlannerNode: runway_offset [0.0, 0.25]: crane 'crane_c''s girder at y 0.25 m would "
                                'be 0.150 m from crane \'crane_a\'\'s at y 0 m, closer than runway_min_distance 0.2 m')


def convoy(cranes, method: str, leader: str, follower: str, goals: dict, residual_limit: float):
    """Both cranes' goals (crane -> (bridge goal, duration)) sent together: the follower moves into the space the
    leader leaves, which it could not reach before the leader has gone: it waits, names the leader, and neither
    stops. Measured: the least distance between both cranes (never under the minimum), each at its goal and its
    residual swing within ``residual_limit`` (mm). Returns the measured figures."""
    start = cranes.a.now_ns() + round(1.5e9)
    mark = cranes.a.now_ns()
    handles = send_together(cranes, {name: (method, *goal) for name, goal in goals.items()}, start)
    results = {name: result(getattr(cranes, name[-1]), handle) for name, handle in handles.items()}
    for name, (status, res) in results.items():
        assert status == STATUS_SUCCEEDED and res.success, f'{name}: {res.message}'
    delays = {name: (res.info.runway_delay, res.info.runway_waited_for) for name, (_, res) in results.items()}
    assert delays[leader] == (0.0, '') and delays[follower][1] == leader, delays
    delay = delays[follower][0]
    assert 0.1 <= delay <= 2.0, delays
    # as published: the follower's motion, started when asked, would have come within the minimum of the leader's
    claims = {name: [occupancy_of(m) for m in heard_occupancies(cranes, name, mark) if len(m.t) > 1] for name in (A, B)}
    mine, theirs = claims[follower][-1], claims[leader][-1]
    assert dense_min_distance(mine, theirs) >= MIN_DISTANCE
    assert dense_min_distance(mine.delayed(-delay), theirs) < MIN_DISTANCE - 0.02
    ends = {name: start + round((delays[name][0] + goals[name][1]) * 1e9) for name in (A, B)}
    found = footprints(cranes, start - round(0.2e9), max(ends.values()) + round(SETTLE * 1e9))
    distance, when = closest_measured(found)
    residuals = {name: residual_mm(found[name][2], ends[name]) for name in (A, B)}
    print(f'{method}: {follower} waited {delay:.2f} s for {leader}; closest measured {distance:.4f} m at '
          f'{(when - start) * 1e-9:.2f} s; residual {A} {residuals[A]:.4f} mm, {B} {residuals[B]:.4f} mm '
          f'(the planners: {", ".join(f"{1e3 * res.residual_swing:.4f}" for _, res in results.values())} mm)')
    assert distance >= MIN_DISTANCE, (distance, (when - start) * 1e-9)
    for name, (_, res) in results.items():
        rec = found[name][2]
        assert rec['bridge'][-1] == pytest.approx(goals[name][0], abs=2e-3), name
        assert residuals[name] <= residual_limit and abs(1e3 * res.residual_swing - residuals[name]) < 0.05, name
    return delay, distance, residuals


def test_zv_a_crane_following_another_into_the_space_it_leaves_sent_together_waits_neither_stops(cranes):
    """Crane b leaves slowly (0.3 m in 5.5 s) while crane a, sent at the same moment, comes 1.87 m towards it in
    3 s, to 0.43 m from b's goal but 0.13 m from where b stands: a's load, leading as it brakes, would come within
    0.15 m of b's girder; a waits."""
    convoy(cranes, 'zv', B, A, {A: (ZV_FOLLOW, 3.0), B: (ZV_LEAVE, 5.5)}, residual_limit=1.0)


def test_nvf_the_other_way_b_follows_a_home_sent_together_waits_neither_stops_no_residual(cranes):
    """Home: a goes back 1.87 m in 6 s, b, sent at the same moment, 0.3 m in 1.3 s into the space a leaves (its
    girder within 0.03 m of a's were a still there): b waits; NVF leaves no swing (0.1 mm). (The sims reset first:
    the ZV moves before left a quarter of a millimetre, which a goal from rest would carry to its end.)"""
    for driver in (cranes.a, cranes.b):
        driver.reset_sim()
    convoy(cranes, 'nvf', A, B, {A: (0.0, 6.0), B: (0.0, 1.3)}, residual_limit=0.1)


def test_refuse_names_the_crane_in_the_way_and_wait_says_the_delay_and_the_crane(cranes):
    """A third crane, z, made up by the test (its occupancy published on /runway/occupancy), standing 0.25 m
    beyond a's goal and leaving 1 s after a's start (0.6 m in 4 s): a preview of that goal is refused naming z
    with runway_policy refuse (also on /diagnostics), and with wait starts later by the delay it says (offline
    0.65 s), behind z."""
    from crane_msgs_py.messages.conversions import stamp_ns
    from crane_msgs_py.runtime.diagnostics import ERROR, level_of
    from crane_planner.nodes.occupancy_messages import to_message
    from crane_planner.planning.dispatch import plan
    from crane_planner.runway.occupancy import Shape
    from crane_planner.runway.prediction import plan_occupancy
    a = cranes.a
    start = a.now_ns() + round(2.0e9)
    z = plan_occupancy('crane_z', plan('zv', 0.0, 4.0, P, bridge=0.6), P, {'cart': 0.0, 'bridge': 0.0},
                       (0.0, 0.85), start + round(1e9), a.now_ns(), Shape(), settle=1.0)
    cranes.publish(to_message(z))
    a.wait_until(lambda: heard_occupancies(cranes, 'crane_z'), 5.0, 'crane z never heard')
    move = bridge_move('zv', 0.6, 2.0, start)
    mark = a.planner.diagnostics.mark()
    try:
        a.set_parameters('planner', {'runway_policy': 'refuse'})
        refused = a.planner.call('zv', None, 0.6, 2.0, move=move)
    finally:
        a.set_parameters('planner', {'runway_policy': 'wait'})
    assert not refused.success and refused.message.startswith('runway: the move would come within 0.'), refused.message
    assert refused.message.endswith("m of crane 'crane_z' (runway_min_distance 0.2 m): refused"), refused.message
    status = a.planner.diagnostics.wait_for(name='crane_planner: plan', after=mark, timeout=5.0,
                                            hardware_id=f'/{A}/crane_planner')
    assert status is not None and level_of(status) == ERROR and "crane 'crane_z'" in status.message
    preview = a.planner.call('zv', None, 0.6, 2.0, move=move)
    assert preview.success and preview.info.runway_waited_for == 'crane_z' and preview.info.runway_delay > 0.3
    assert stamp_ns(preview.trajectory.header.stamp) == start + round(preview.info.runway_delay * 1e9)
