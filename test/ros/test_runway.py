"""ROS: two cranes sharing a runway, each its own process group (planner, streamer, sim: separate DDS
participants) in its own namespace of one private graph, their planners on the runway (contract "Cranes sharing a
runway"; docs/runway.md).

Crane a's ``crane_base`` is at [0, 0] of the runway, crane b's at [0, 2] (bridges 2 m apart), both with the
joints [cart, bridge] and loads on the default 0.47 + 0.391 m cables, runway_min_distance 0.2 m. Goals that bring
them towards each other end 0.28-0.38 m apart (beyond the minimum and the girders' half-widths), but the loads
lead by over 0.1 m as they brake (offline: runway.prediction and runway.schedule): sent together, one waits and
neither stops. The test measures both loads (hook and load, from each sim's joint_states, placed in the runway
by crane_sim's own cable geometry) and both girders itself, and the residual swing over each settle window.
Also: an unusable occupancy published by the test is ignored and counted, ``refuse`` names the crane, and a
planner whose runway_offset puts its girder on another's exits at start-up naming both.
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
#: ZV, each bridge 0.76 m towards the other in 1.3 s: 0.38 m apart at the end (0.28 m between the girders'
#: strips), the loads 0.12 m ahead of their girders as they brake: together they would come within 0.15 m.
ZV_GOAL, ZV_T = 0.76, 1.3
#: NVF, crane a 0.86 m towards b (ZV as above) in 1.8 s: 0.28 m between the girders at the end; before b's load
#: has swung back, a's would come within 0.17 m of it.
NVF_GOAL, NVF_T = 0.86, 1.8
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


def test_zv_goals_towards_each_other_sent_together_one_waits_neither_stops_the_loads_keep_apart(cranes):
    start = cranes.a.now_ns() + round(1.5e9)
    mark = cranes.a.now_ns()
    handles = send_together(cranes, {A: ('zv', ZV_GOAL, ZV_T), B: ('zv', -ZV_GOAL, ZV_T)}, start)
    results = {name: result(getattr(cranes, name[-1]), handle) for name, handle in handles.items()}
    for name, (status, res) in results.items():
        assert status == STATUS_SUCCEEDED and res.success, f'{name}: {res.message}'
    delays = {name: (res.info.runway_delay, res.info.runway_waited_for) for name, (_, res) in results.items()}
    waiting = [name for name, (delay, _) in delays.items() if delay > 0.0]
    assert len(waiting) == 1, delays
    waiter, other = waiting[0], ({A, B} - set(waiting)).pop()
    assert delays[waiter][1] == other and delays[other] == (0.0, ''), delays
    assert 0.3 <= delays[waiter][0] <= 1.5, delays
    # as published: the waiter's motion, started when asked, would have come within the minimum of the other's
    claims = {name: [occupancy_of(m) for m in heard_occupancies(cranes, name, mark) if len(m.t) > 1] for name in (A, B)}
    mine, theirs = claims[waiter][-1], claims[other][-1]
    assert dense_min_distance(mine, theirs) >= MIN_DISTANCE
    assert dense_min_distance(mine.delayed(-delays[waiter][0]), theirs) < MIN_DISTANCE - 0.02
    # measured: both loads and girders, never closer than the minimum; at rest at the goals, quiet
    end = start + round((delays[waiter][0] + ZV_T + SETTLE) * 1e9)
    found = footprints(cranes, start - round(0.2e9), end)
    distance, when = closest_measured(found)
    print(f'zv: {waiter} waited {delays[waiter][0]:.2f} s for {other}; closest measured {distance:.4f} m at '
          f'{(when - start) * 1e-9:.2f} s')
    assert distance >= MIN_DISTANCE, (distance, (when - start) * 1e-9)
    for name, (_, res) in results.items():
        rec = found[name][2]
        assert rec['bridge'][-1] == pytest.approx(ZV_GOAL if name == A else -ZV_GOAL, abs=2e-3)
        motion_end = start + round(((delays[name][0]) + ZV_T) * 1e9)
        residual = residual_mm(rec, motion_end)
        print(f'zv: {name} residual {residual:.3f} mm (planner: {1e3 * res.residual_swing:.3f} mm)')
        assert residual <= 1.0 and abs(1e3 * res.residual_swing - residual) < 0.05


def test_nvf_towards_a_zv_motion_published_first_waits_for_it_refuse_names_it_the_loads_keep_apart(cranes):
    """Home again (apart: no conflict, neither waits), then b's ZV goal towards a; once its motion is published,
    a's NVF goal towards b starting at the same time: refused naming b with runway_policy refuse (a preview),
    with wait previewed and executed later by the same delay."""
    home = cranes.a.now_ns() + round(1.0e9)
    handles = send_together(cranes, {A: ('zv', 0.0, 1.5), B: ('zv', 0.0, 1.5)}, home, settle=0.3)
    for name, handle in handles.items():
        status, res = result(getattr(cranes, name[-1]), handle)
        assert status == STATUS_SUCCEEDED and res.info.runway_delay == 0.0, (name, res.message, res.info.runway_delay)
    cranes.a.reset_sim()
    cranes.b.reset_sim()
    mark = cranes.a.now_ns()
    start = mark + round(2.5e9)
    handle_b = send(cranes.b, 'zv', -ZV_GOAL, ZV_T, start)
    cranes.a.wait_until(lambda: any(len(m.t) > 1 for m in heard_occupancies(cranes, B, mark)), 5.0,
                        'crane b\'s motion never published')
    a, move = cranes.a, bridge_move('nvf', NVF_GOAL, NVF_T, start)
    try:
        a.set_parameters('planner', {'runway_policy': 'refuse'})
        refused = a.planner.call('nvf', None, NVF_GOAL, NVF_T, move=move)
    finally:
        a.set_parameters('planner', {'runway_policy': 'wait'})
    assert not refused.success
    assert refused.message.startswith("runway: the move would come within 0.") and \
        "m of crane 'crane_b' (runway_min_distance 0.2 m): refused" in refused.message, refused.message
    preview = a.planner.call('nvf', None, NVF_GOAL, NVF_T, move=move)
    assert preview.success and preview.info.runway_waited_for == B and preview.info.runway_delay > 0.2
    status, res = result(a, send(a, 'nvf', NVF_GOAL, NVF_T, start))
    assert status == STATUS_SUCCEEDED and res.success, res.message
    assert (res.info.runway_delay, res.info.runway_waited_for) == (pytest.approx(preview.info.runway_delay), B)
    status_b, res_b = result(cranes.b, handle_b)
    assert status_b == STATUS_SUCCEEDED and res_b.success and res_b.info.runway_delay == 0.0, res_b.message
    delay = res.info.runway_delay
    end = start + round((delay + NVF_T + SETTLE) * 1e9)
    found = footprints(cranes, start - round(0.2e9), end)
    distance, when = closest_measured(found)
    print(f'nvf: a waited {delay:.2f} s for b; closest measured {distance:.4f} m at {(when - start) * 1e-9:.2f} s')
    assert distance >= MIN_DISTANCE, (distance, (when - start) * 1e-9)
    residual_a = residual_mm(found[A][2], start + round((delay + NVF_T) * 1e9))
    residual_b = residual_mm(found[B][2], start + round(ZV_T * 1e9))
    print(f'nvf: a residual {residual_a:.4f} mm, b (zv) {residual_b:.3f} mm')
    assert residual_a <= 0.1 and residual_b <= 1.0
    assert found[A][2]['bridge'][-1] == pytest.approx(NVF_GOAL, abs=2e-3)
