"""ROS integration: the real planner, streamer and sim executables in one namespace of a private graph.

One set of nodes serves the whole module (``crane`` fixture: the set the cart-only modules share, conftest's
``cart_crane``); it is always stopped (SIGINT, then kill) however the tests end. The test process talks to
the nodes over their ROS surface only: services, topics, parameters and /diagnostics (contract: ROS 2 nodes).
"""
import math
import time
from contextlib import contextmanager
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from shared_crane import CART_NAMESPACE

from crane_msgs_py.crane.params import CraneParams
from crane_planner.planning import METHODS, SHAPER_METHODS
from crane_planner.planning.model import modal_frequencies
from crane_planner.planning.plan import PlanError
from crane_planner.planning.shapers import design

NS = CART_NAMESPACE
D = 0.3              # m, the paper's displacement
SETTLE = 1.0         # s observed after each motion: more than half the slow mode's 1.73 s period, so its peak shows
LEAD = 1.0           # s between the example client's request and its motion start
NOMINAL = CraneParams()


def duration_for(method: str) -> float:
    """2.5 s (the paper's §5, the demo's), longer where the shaper alone is close to that (ZVD, ZVDD).

    EI tolerates 5 % of the unshaped swing at its design frequency by design,
    and its quintic gets only T minus two periods: at 3 s that leaves 11 mm
    (crane-plan agrees), at 6 s 0.4 mm.
    """
    if method == 'ei':
        return 6.0
    if method not in SHAPER_METHODS:
        return 2.5
    shaper = design(method, modal_frequencies(NOMINAL), 0.0)
    return max(2.5, math.ceil(2.0 * (shaper.duration + 0.5)) / 2.0)


_OFFLINE = {}


def offline_plan(method: str, displacement: float, duration: float):
    """The same request planned in this process by the planning core (crane-plan's planner)."""
    from crane_planner.serving import Planner
    planner = _OFFLINE.setdefault('planner', Planner())
    return planner.plan(method, displacement, duration, NOMINAL)


def offline_residual(method: str, duration: float) -> float:
    """Residual load swing (mm) of the same plan simulated offline (crane-plan's evaluation)."""
    from crane_planner.tools.evaluate import simulate_plan
    ev = simulate_plan(offline_plan(method, D, duration), NOMINAL, settle=SETTLE)
    return ev.metrics[0]['residual']['load_mm']


class Crane:
    """The test's handle on the running nodes (rclpy node of a CraneHarness plus extras)."""

    def __init__(self, driver):
        from rclpy.parameter_client import AsyncParameterClient

        from crane_msgs_py.messages.names import PLANNER_NODE

        self.driver, self.nodes = driver, driver.nodes  # the driver records joint_states and the plans
        self.node = driver.node
        self.planner = driver.planner
        self.diagnostics = driver.planner.diagnostics
        self.hold = 0.0
        # the raw client: a refused parameter's result (successful, reason) is under test
        self.planner_params = AsyncParameterClient(self.node, PLANNER_NODE)
        assert self.planner_params.wait_for_services(10.0), 'planner parameter services not up'

    def next_goal(self) -> float:
        """D from near 0, else 0: each move starts where the last one ended."""
        return D if self.hold < D / 2 else 0.0

    def now(self) -> int:
        return self.driver.now_ns()

    def sleep_until(self, ns: int):
        self.driver.sleep(max(0.0, (ns - self.now()) * 1e-9))

    def status(self, node: str, task: str, after: int = 0, timeout: float = 3.0, predicate=None, level=None):
        """The first ``<node>: <task>`` status of our namespace after mark ``after``."""
        status = self.diagnostics.wait_for(predicate, timeout, after=after, name=f'{node}: {task}',
                                           hardware_id=f'{NS}/{node}', level=level)
        assert status is not None, f'no {node}: {task} status within {timeout} s'
        return status

    def values(self, node: str, task: str, after: int = 0, predicate=None) -> dict:
        from crane_msgs_py.runtime.diagnostics import status_values
        return status_values(self.status(node, task, after, predicate=predicate))

    @contextmanager
    def references(self, arrival: bool = False):
        """Record the reference stream: rows (stamp ns, position, velocity, acceleration) in arrival order.

        The stream gets a node and an executor of its own and a queue of 1 s,
        so nothing is lost when this process lags. The EventsExecutor costs a
        fifth of the CPU of the Python executors at 1 kHz, but only these pass
        the middleware's message info: with ``arrival`` each row ends with the
        time (ns, system clock) the DDS reader received the sample, a time
        this process's own lag does not shift.
        """
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.experimental import EventsExecutor
        from trajectory_msgs.msg import JointTrajectory

        from crane_msgs_py.messages.conversions import read_reference
        from crane_msgs_py.messages.names import REFERENCE_TOPIC
        from crane_msgs_py.runtime.qos import REFERENCE_EVERY_SAMPLE_QOS, recording
        from crane_msgs_py.runtime.runner import spinning
        rows = []
        node = rclpy.create_node('crane_it_recorder', namespace=NS)
        if arrival:
            node.create_subscription(JointTrajectory, REFERENCE_TOPIC,
                                     lambda m, info: rows.append((*read_reference(m), info['received_timestamp'])),
                                     recording(REFERENCE_EVERY_SAMPLE_QOS, 10.0, 1000.0))
        else:
            node.create_subscription(JointTrajectory, REFERENCE_TOPIC, lambda m: rows.append(read_reference(m)),
                                     REFERENCE_EVERY_SAMPLE_QOS)
        executor = SingleThreadedExecutor() if arrival else EventsExecutor()
        executor.add_node(node)
        try:
            with spinning(executor):
                deadline = time.monotonic() + 5.0
                while not rows:  # matched and flowing
                    assert time.monotonic() < deadline, 'no reference received'
                    time.sleep(0.01)
                yield rows
        finally:
            node.destroy_node()

    def publisher(self, msg_type, topic, qos):
        pub = self.node.create_publisher(msg_type, topic, qos)
        deadline = time.monotonic() + 5.0
        while pub.get_subscription_count() == 0:
            assert time.monotonic() < deadline, f'nobody subscribes to {topic}'
            time.sleep(0.01)
        return pub

    def move(self, method: str, goal: float, duration: float):
        """Execute hold -> goal through ~/execute_move starting the harness's ``lead()`` from now, watched for
        SETTLE s after its end; the served plan (its knots) and the stamps the motion starts and ends.

        A trajectory reaching the streamer after its start stamp (a busy
        machine) is streamed whole from the next tick: the stamps follow that.
        The goal's result is ``self.driver.move_result(start)``.
        """
        from crane_msgs_py.messages.conversions import joint_trajectory_to_arrays, stamp_ns
        start_ns, _, traj = self.driver.move(method, self.hold, goal, duration, settle=SETTLE)
        t, p, v, a = joint_trajectory_to_arrays(traj)
        plan = SimpleNamespace(t=t, position=p, velocity=v, acceleration=a, start_ns=stamp_ns(traj.header.stamp),
                               trajectory=traj)
        self.hold = float(p[-1])  # the goal up to rounding: what the streamer holds next
        return plan, start_ns, start_ns + round(duration * 1e9)

    def swing_after(self, start_ns: int, duration: float, L1: float):
        """Residual load swing (mm) over SETTLE s after the motion, and the cart's travel, from joint_states."""
        from crane_sim.metrics import residual_load_mm
        end_ns = start_ns + round((duration + SETTLE) * 1e9)
        self.sleep_until(end_ns)
        # (stamp, theta1, theta2, cart), one 50 Hz sample past the window
        rec = self.driver.states_between(start_ns - 50_000_000, end_ns + 20_000_000, timeout=10.0)
        assert len(rec) > 40 * (duration + SETTLE), f'only {len(rec)} joint_states'
        t = (rec[:, 0] - start_ns) * 1e-9
        residual = residual_load_mm(t, rec[:, 1], rec[:, 2], L1, NOMINAL.L2, after=duration,
                                    until=duration + SETTLE)
        return residual, rec[-1, 3] - rec[0, 3]


@pytest.fixture(scope='module')
def crane(cart_crane):
    """The nodes (warm: the harness waited for the planner's solvers), the cart at 0 m: the tests' moves
    alternate between 0 and ``D``."""
    driver = cart_crane
    driver.home(lambda: driver.move('nvf', None, 0.0, 1.5, settle=0.05)[0], lambda last: abs(last[3]) <= 1e-6)
    yield Crane(driver)


def quintic_trajectory(start: float, goal: float, duration: float, stamp_ns: int = 0):
    """A rest-to-rest quintic as the planner would publish it (independent of the planner)."""
    from crane_msgs_py.messages.conversions import samples_to_joint_trajectory
    t = np.append(np.arange(0.0, duration, 0.01), duration)
    s = t / duration
    d = goal - start
    samples = SimpleNamespace(t=t, position=d * (10 * s**3 - 15 * s**4 + 6 * s**5),
                              velocity=d * (30 * s**2 - 60 * s**3 + 30 * s**4) / duration,
                              acceleration=d * (60 * s - 180 * s**2 + 120 * s**3) / duration**2)
    return samples_to_joint_trajectory(samples, start, stamp_ns)


# --------------------------------------------------------------------------- every method


@pytest.mark.parametrize('method', METHODS)
def test_method_is_planned_published_streamed_and_leaves_no_swing(crane, method):
    from crane_msgs_py.messages.conversions import joint_trajectory_to_arrays
    T = duration_for(method)
    start, goal = crane.hold, crane.next_goal()
    crane.driver.reset_sim()  # the simulated crane has no damping: start each motion at rest
    with crane.references() as refs:
        plan, start_ns, end_ns = crane.move(method, goal, T)
        residual, travel = crane.swing_after(start_ns, T, NOMINAL.L1)
    result = crane.driver.move_result(start_ns)
    # the served trajectory: a knot per breakpoint and few more, ending at the goal exactly at the
    # requested time, in crane_base, stamped with the requested start
    traj = plan.trajectory
    assert traj.header.frame_id == 'crane_base' and list(traj.joint_names) == ['cart']
    offline = offline_plan(method, goal - start, T)
    assert set(np.round(offline.breakpoints(), 6)) <= set(np.round(plan.t, 6))
    assert len(traj.points) <= 2 * len(offline.breakpoints()) + 20  # lean: not one per 10 ms (301 at 3 s)
    assert plan.t[-1] == pytest.approx(T, abs=1e-9)
    assert plan.position[0] == pytest.approx(start, abs=1e-9)
    assert plan.position[-1] == pytest.approx(goal, abs=1e-9)
    assert abs(plan.velocity[0]) < 1e-6 and abs(plan.velocity[-1]) < 1e-6
    # a preview of the same move (PlanMove) gives the same knots: preview and execution plan alike
    preview = crane.planner.plan(method, start, goal, T, start_ns=plan.start_ns)
    t, p, v, a = joint_trajectory_to_arrays(preview.trajectory)
    assert np.allclose(t, plan.t, atol=1e-9) and np.allclose(p, plan.position, atol=1e-9)
    assert preview.info.method == method and preview.info.duration == pytest.approx(T, abs=1e-9)
    assert preview.info.peak_velocity[0] >= np.max(np.abs(v)) * (1 - 1e-6)
    # the action's result: success, and the residual it measured agrees with this test's own
    assert result.success and result.info.method == method
    assert abs(1e3 * result.residual_swing - residual) < 0.1, (result.residual_swing, residual)
    # the stream: the plan itself at every tick of the motion (the planning core's exact evaluation
    # of the same request, made here), the goal held afterwards
    rows = np.array(refs, dtype=object)
    stamps = rows[:, 0].astype(np.int64)
    during = (stamps >= start_ns) & (stamps <= end_ns)
    assert during.sum() > 0.3 * T * 1000, f'only {during.sum()} references during the motion'
    exact = offline.evaluate((stamps[during] - start_ns) * 1e-9)
    assert np.max(np.abs(rows[during, 1].astype(float) - start - exact.position)) < 2e-6
    assert np.max(np.abs(rows[during, 3].astype(float) - exact.acceleration)) < 2e-3 * np.max(np.abs(a))
    after = rows[stamps > end_ns, 1].astype(float)
    assert after.size > 0 and np.all(after == p[-1])  # the last knot, held exactly
    # the plant: no residual swing on the nominal plant, and the cart travelled the displacement
    assert residual < 1.0, f'{method}: residual load swing {residual:.3f} mm'
    assert travel == pytest.approx(goal - start, abs=1e-3)
    if method in SHAPER_METHODS:  # cheap to plan here: the same swing as the offline simulation
        assert residual == pytest.approx(offline_residual(method, T), rel=0.1, abs=0.05)


# --------------------------------------------------------------------------- preview vs execution


def test_plan_calls_move_nothing_and_one_execute_moves_the_cart(crane):
    """10 ~/plan_move calls of every method (and of the default method) from the hold position,
    starting soon, while the sim runs: the cart stays put and no trajectory is sent; one ~/execute_move
    then moves it."""
    hold, goal = crane.hold, crane.next_goal()
    rng = np.random.default_rng(9)
    crane.driver.reset_sim()  # at rest where it is (the last motion may have left it swinging)
    crane.driver.sleep(0.5)  # past the sim's playout delay
    begin = crane.now()
    sent_before = set(crane.driver.sent_trajectories())
    for method in (None, *METHODS):
        for k in range(10):
            T = max(duration_for(method or 'rvf'), 3.0) + rng.uniform(0.0, 2.0)
            plan = crane.planner.plan(method, hold, hold + rng.uniform(-1.0, 1.0), T,
                                      start_ns=crane.now() + 200_000_000)
            assert plan.position[0] == pytest.approx(hold, abs=1e-9)
    crane.driver.sleep(0.5)  # anything sent would have started by now
    states = crane.driver.states_between(begin, crane.now() - 100_000_000, timeout=5.0)
    assert len(states) > 40 * (crane.now() - begin) * 1e-9 * 0.8 - 50
    assert np.ptp(states[:, 3]) < 1e-6 and states[0, 3] == pytest.approx(hold, abs=1e-4), \
        'a preview moved the cart'
    assert set(crane.driver.sent_trajectories()) == sent_before, 'a preview was sent to the streamer'
    # the explicit path moves it
    plan, start_ns, end_ns = crane.move('zv', goal, 3.0)
    assert plan.start_ns in crane.driver.sent_trajectories()
    crane.sleep_until(end_ns + 500_000_000)
    states = crane.driver.states_between(end_ns + 300_000_000, end_ns + 500_000_000)
    assert states[:, 3] == pytest.approx(goal, abs=1e-4)


# --------------------------------------------------------------------------- the action


def test_execute_move_is_served_by_the_planner_node_though_waited_for_on_a_thread_of_its_own(crane):
    """The action's requests are waited for on a helper node's executor (PlannerNode.__init__), but the
    server is the planner's: the graph (what `ros2 action info` reads) names crane_planner, not the helper."""
    from rclpy.action import get_action_server_names_and_types_by_node
    node = crane.driver.node
    served = dict(get_action_server_names_and_types_by_node(node, 'crane_planner', NS))
    assert served.get(f'{NS}/crane_planner/execute_move') == ['crane_interfaces/action/ExecuteMove']
    assert not get_action_server_names_and_types_by_node(node, 'crane_planner_goals', NS)


def test_the_middleware_s_receive_threads_run_just_below_the_threads_they_feed(crane):
    """A goal, a trajectory or a reference reaches the executor only through Fast DDS's receive threads: at
    SCHED_FIFO one below the planner's goals' thread (handover_priority 40), two below the streamer's loop
    (sched_priority 50) and two below the sim's (sched_priority 45), or at normal priority with a warning where
    the privilege is missing. Read from /proc, not the nodes."""
    import os
    expected = {'planner': 39, 'streamer': 48, 'sim': 43}
    for proc in crane.driver.nodes.processes:
        if proc.name not in expected:
            continue
        tasks = Path(f'/proc/{proc.popen.pid}/task')
        receiving = [int(t.name) for t in tasks.iterdir()
                     if (t / 'comm').read_text().startswith(('dds.udp.', 'dds.shm.'))]
        assert receiving, f'{proc.name}: no Fast DDS receive thread among {len(list(tasks.iterdir()))} threads'
        policies = {(os.sched_getscheduler(tid), os.sched_getparam(tid).sched_priority) for tid in receiving}
        if 'receive threads' in proc.log_path.read_text():  # refused: said so, and left at normal priority
            assert policies == {(os.SCHED_OTHER, 0)}
        else:
            assert policies == {(os.SCHED_FIFO, expected[proc.name])}, proc.name


def test_an_independent_client_previews_and_executes_a_move_with_feedback_and_the_measured_residual(
        crane, ros_domain):
    """examples/execute_move.py (the README's client: rclpy and crane_interfaces only) previews with
    PlanMove and executes with ExecuteMove: feedback at >= 10 Hz whose progress rises monotonically
    to 1, and a result whose residual agrees within 0.1 mm with the swing this test computes from
    joint_states over the same window."""
    import json
    import subprocess
    import sys
    from pathlib import Path

    from crane_sim.metrics import residual_load_mm
    example = Path(__file__).resolve().parents[2] / 'examples' / 'execute_move.py'
    T, settle = 3.0, SETTLE
    crane.driver.reset_sim()
    mark = crane.diagnostics.mark()
    before = set(crane.driver.sent_trajectories())
    goal = crane.next_goal()
    out = subprocess.run([sys.executable, str(example), '--goal', str(goal), '--duration', str(T), '--method', 'rvf',
                          '--settle', str(settle), '--delay', str(LEAD), '--json', '--ros-args', '-r', f'__ns:={NS}'],
                         env=ros_domain, capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stdout + out.stderr
    lines = [json.loads(line) for line in out.stdout.splitlines()]
    preview = lines[0]['preview']
    feedback = [line['feedback'] for line in lines if 'feedback' in line]
    result = lines[-1]['result']
    assert preview['method'] == 'rvf' and preview['duration'] == pytest.approx(T, abs=1e-9)
    assert result['success'] and result['duration'] == pytest.approx(T, abs=1e-9), result
    progress = [f['progress'] for f in feedback]
    assert np.all(np.diff(progress) >= 0.0) and progress[-1] == 1.0 and progress[0] == 0.0
    assert len(feedback) >= 10 * (LEAD + T + settle) * 0.8, len(feedback)  # >= 10 Hz (20 Hz sent)
    [stamp] = set(crane.driver.sent_trajectories()) - before
    assert stamp == preview['start_time']
    start_ns = crane.driver.streamed_start(stamp, mark, 'the example')
    rec = crane.driver.states_between(start_ns, start_ns + round((T + settle + 0.05) * 1e9), timeout=10.0)
    t = (rec[:, 0] - start_ns) * 1e-9
    measured = residual_load_mm(t, rec[:, 1], rec[:, 2], NOMINAL.L1, NOMINAL.L2, after=T, until=T + settle)
    assert abs(1e3 * result['residual_swing'] - measured) < 0.1, (result, measured)
    crane.hold = goal


def test_a_goal_canceled_before_its_start_streams_nothing_and_ends_canceled(crane):
    from action_msgs.msg import GoalStatus
    crane.driver.reset_sim()
    crane.driver.sleep(0.3)
    hold, sent = crane.hold, set(crane.driver.sent_trajectories())
    begin = crane.now()
    start_ns = begin + 3_000_000_000  # far enough: the planner holds it until publish_lead before
    handle = crane.planner.send_execute('rvf', hold, crane.next_goal(), 3.0, start_ns)
    crane.driver.sleep(0.5)
    cancel = handle.cancel_goal_async()
    crane.driver.wait_until(cancel.done, 5.0, 'no answer to the cancel')
    assert len(cancel.result().goals_canceling) == 1  # accepted
    response = handle.get_result_async()
    crane.driver.wait_until(response.done, 10.0, 'the canceled goal never ended')
    assert response.result().status == GoalStatus.STATUS_CANCELED
    assert 'nothing was streamed' in response.result().result.message
    crane.sleep_until(start_ns + 3_500_000_000)  # past where the motion would have ended
    states = crane.driver.states_between(begin, start_ns + 3_300_000_000, timeout=5.0)
    assert set(crane.driver.sent_trajectories()) == sent
    assert np.ptp(states[:, 3]) < 1e-9 and states[0, 3] == pytest.approx(hold, abs=1e-4), 'the cart moved'


def test_a_goal_whose_start_time_has_passed_is_streamed_from_now_and_followed_to_its_result(crane):
    """A goal arriving after its own start_time (a client slow to discover the planner, a clock behind): the
    streamer streams it whole from its next tick, and the planner follows that motion to its result. (Aborting
    the goal at once, "not streamed within 1 s of its start", while the crane moved would leave every next goal
    to meet a motion the planner did not know of.) The next goal starts where this one ended; late too, it starts
    at the streamer's next tick, the start CraneHarness.move returns, and CraneHarness.trajectory of that start
    is the trajectory the planner published, stamped with the start asked for (crane-demo reads a late plan so,
    and must not fail under load)."""
    from crane_msgs_py.messages.conversions import stamp_ns
    from crane_sim.metrics import residual_load_mm
    crane.driver.reset_sim()
    crane.driver.sleep(0.3)
    hold, goal, T = crane.hold, crane.next_goal(), 3.0
    sent = crane.now()
    result = crane.planner.execute('zv', hold, goal, T, start_ns=sent - 2_000_000_000, settle=SETTLE)
    assert result.success, result.message
    states = crane.driver.states_between(sent, crane.now(), timeout=5.0)
    moving = np.nonzero(np.abs(states[:, 3] - hold) > 1e-6)[0]
    started = states[moving[0], 0]  # the first joint_states that saw the cart move (plant time)
    assert sent < started < sent + 500_000_000, 'not streamed from when it was sent'
    assert states[-1, 3] == pytest.approx(goal, abs=1e-4)
    t = (states[:, 0] - started) * 1e-9
    measured = residual_load_mm(t, states[:, 1], states[:, 2], NOMINAL.L1, NOMINAL.L2, after=T, until=T + SETTLE)
    assert measured < 1.0 and abs(1e3 * result.residual_swing - measured) < 0.2, (result.residual_swing, measured)
    crane.hold = goal
    hold, goal = crane.hold, crane.next_goal()  # from where it ended: not refused
    asked = crane.now() - 300_000_000
    streamed, _, traj = crane.driver.move('zv', hold, goal, 3.0, start_ns=asked, settle=0.05)
    assert streamed > asked and stamp_ns(traj.header.stamp) == asked
    assert crane.driver.trajectory(streamed) is traj and crane.driver.trajectory(asked) is traj
    assert crane.driver.move_result(streamed).success
    crane.hold = goal


# --------------------------------------------------------------------------- answer time


def test_a_request_exhausting_max_solve_time_delays_no_other(crane):
    """One RVF request that cannot be solved in max_solve_time (10 m in 0.5 s) in flight; 20 typical
    requests sent after it are all answered successfully, the shapers' before it; the slow one is
    refused after running to max_solve_time, naming the budget. (How long each took:
    bench/service_load.py.)"""
    import threading

    from crane_msgs_py.runtime.diagnostics import ERROR, status_float, status_values
    budget = 1.0  # the default max_solve_time
    rng = np.random.default_rng(4)
    typical = []
    while len(typical) < 20:
        method, T = METHODS[rng.integers(len(METHODS))], rng.uniform(2.6, 8.0)
        if method in SHAPER_METHODS and design(method, modal_frequencies(NOMINAL), 0.0).duration >= T:
            continue  # a method that fits T
        typical.append((method, 5.0, 5.0 + rng.uniform(-1.0, 1.0), T))
    answers, answered = {}, []

    def ask(key, method, start, goal, T):
        t0 = time.monotonic()
        response = crane.planner.call(method, start, goal, T, timeout=10.0)
        answers[key] = (time.monotonic() - t0, len(response.trajectory.points), response)
        answered.append(key)

    mark = crane.diagnostics.mark()
    slow = threading.Thread(target=ask, args=('slow', 'rvf', 5.0, 15.0, 0.5))
    slow.start()
    time.sleep(0.1)  # in flight
    threads = [threading.Thread(target=ask, args=(k, *request)) for k, request in enumerate(typical)]
    for th in threads:
        th.start()
    for th in threads + [slow]:
        th.join(15.0)
    planner_side = [{key: status_values(s).get(key) for key in ('method', 'plan_time', 'solve_time', 'build_time',
                                                                   'iterations')}
                    for s in crane.diagnostics.statuses('crane_planner: plan', after=mark)]
    assert len(answers) == 21, planner_side
    # no shaper request waited for the slow one: each was answered before it (the NVF/RVF ones take turns
    # at the other solver processes, and are all answered too: no refusal below)
    cheap = [k for k, request in enumerate(typical) if request[0] in SHAPER_METHODS]
    assert set(answered[:answered.index('slow')]) >= set(cheap), (
        [(k, typical[k][0] if k != 'slow' else 'rvf', round(answers[k][0], 3)) for k in answered], planner_side)
    refusals = [s.message for s in crane.diagnostics.statuses('crane_planner: plan', level=ERROR, after=mark)
                if status_float(s, 'goal') != 15.0]
    assert not refusals, refusals
    for k, request in enumerate(typical):
        elapsed, points, response = answers[k]
        assert response.success and points > 1, request
        assert response.trajectory.points[-1].positions[0] == pytest.approx(request[2], abs=1e-9), request
    elapsed, points, response = answers['slow']
    assert not response.success and points == 0 and elapsed > budget - 0.1  # it ran to its budget
    assert 'max_solve_time 1 s' in response.message, response.message
    status = crane.status('crane_planner', 'plan', mark, level=ERROR,
                          predicate=lambda s: status_float(s, 'goal') == 15.0)
    assert 'max_solve_time 1 s' in status.message, status.message


def test_a_shaper_plan_is_answered_while_the_planner_rebuilds_its_solvers(crane):
    """A parameter that changes the NLPs (intervals) has the solver processes build them anew; an NVF plan
    asked at once needs one of them, and a ZV plan asked after it is answered first (no shaper waits for a
    build). The NVF plan is the new one, or refused naming why (still building on a loaded host)."""
    import threading
    answered, responses = [], {}

    def ask(key, method):
        responses[key] = crane.planner.call(method, 5.0, 5.3, 3.0, timeout=30.0)
        answered.append(key)

    crane.driver.set_parameters('planner', {'intervals': 20})
    try:
        expensive = threading.Thread(target=ask, args=('nvf', 'nvf'))
        expensive.start()
        time.sleep(0.05)  # sent first
        ask('zv', 'zv')
        expensive.join(30.0)
    finally:
        crane.driver.set_parameters('planner', {'intervals': 0})
    assert answered == ['zv', 'nvf'], answered
    assert responses['zv'].success and responses['zv'].trajectory.points[-1].positions[0] == \
        pytest.approx(5.3, abs=1e-9)
    nvf = responses['nvf']
    assert nvf.success or 'no answer within' in nvf.message or 'solver_processes' in nvf.message, nvf.message
    if nvf.success:
        assert nvf.trajectory.points[-1].positions[0] == pytest.approx(5.3, abs=1e-9)


# --------------------------------------------------------------------------- robustness


def test_rvf_leaves_less_swing_than_nvf_on_a_shorter_upper_cable(crane):
    L1 = 0.42  # the paper's perturbed plant (§5); the planner's model keeps 0.47
    crane.driver.set_parameters('sim', {'L1': L1})
    residual = {}
    try:
        for method in ('nvf', 'rvf'):
            crane.driver.reset_sim()
            _, start_ns, _ = crane.move(method, crane.next_goal(), 3.0)
            residual[method], _ = crane.swing_after(start_ns, 3.0, L1)
    finally:
        crane.driver.set_parameters('sim', {'L1': NOMINAL.L1})
    assert residual['rvf'] < residual['nvf'], residual


# --------------------------------------------------------------------------- network impairment


def test_impaired_stream_shows_delay_and_loss_and_every_node_survives(crane):
    delay, jitter, loss = 2e-3, 1e-3, 0.05
    crane.driver.set_parameters('streamer', {'network.delay': delay, 'network.jitter': jitter,
                                             'network.loss': loss, 'network.seed': 7})
    try:
        mark = crane.diagnostics.mark()
        impaired = lambda s: float(_values(s).get('network_loss', 0.0)) == loss  # noqa: E731
        before = crane.values('crane_streamer', 'stream', mark, impaired)
        sim_before = crane.values('crane_sim', 'sim', crane.diagnostics.mark())
        with crane.references(arrival=True) as refs:
            _, start_ns, end_ns = crane.move('zv', crane.next_goal(), 3.0)
            crane.sleep_until(end_ns + 300_000_000)
            deadline = time.monotonic() + 10.0
            while refs[-1][0] < end_ns + 200_000_000:  # this recorder may lag: its queue holds 10 s
                assert time.monotonic() < deadline, 'the recorder never caught up with the stream'
                time.sleep(0.05)
        mark = crane.diagnostics.mark()
        after = crane.values('crane_streamer', 'stream', mark)
        sim_after = crane.values('crane_sim', 'sim', mark)
        statuses = crane.diagnostics.statuses('crane_sim: sim', hardware_id=f'{NS}/crane_sim')
        received = [_values(s) for s in statuses][-4:]  # the last seconds, all impaired
    finally:
        crane.driver.set_parameters('streamer', {'network.delay': 0.0, 'network.jitter': 0.0, 'network.loss': 0.0})
    # the streamer's own account: 5 % of the samples lost on the link
    sent = int(after['sent']) - int(before['sent'])
    dropped = int(after['dropped']) - int(before['dropped'])
    assert dropped / (sent + dropped) == pytest.approx(loss, abs=0.02)
    # the link as a DDS reader sees it: the median sample arrives after the delay (how much later also
    # depends on the host's load, not on the impairment alone)
    rows = np.array(refs, dtype=object)
    stamps, arrivals = rows[:, 0].astype(np.int64), rows[:, 4].astype(np.int64)
    latency = (arrivals - stamps) * 1e-9
    assert delay < np.median(latency), np.percentile(latency, [0, 50, 99])
    # the receiving sim measures it too: no sample sooner than the delay (its figures also hold
    # the time its executor took to get to the sample: a busy machine adds to them, never
    # takes away), and the gaps of the lost samples
    for window in received:
        assert float(window['reference_latency_p50_ms']) * 1e-3 > delay, window
    accepted = int(sim_after['accepted']) - int(sim_before['accepted'])
    missing = int(sim_after['missing']) - int(sim_before['missing'])
    assert missing / (accepted + missing) == pytest.approx(loss, abs=0.02)
    # a sample lost alone (a fraction (1 - loss)^2 of those lost, 90 %) is bridged, never two in a row
    bridged = int(sim_after['bridged']) - int(sim_before['bridged'])
    assert 0.8 * missing < bridged < missing, (bridged, missing)
    # and so does this recorder: gaps in the stamps, never out of order (FIFO link), the motion complete
    assert np.all(np.diff(stamps) > 0)
    assert 1.0 - len(stamps) / ((stamps[-1] - stamps[0]) // 1_000_000 + 1) == pytest.approx(loss, abs=0.02)
    assert rows[-1, 1] == crane.hold
    crane.nodes.check_alive()
    crane.planner.plan('zv', 5.0, 5.3, 3.0)  # the planner still answers


def _values(status):
    from crane_msgs_py.runtime.diagnostics import status_values
    return status_values(status)


# --------------------------------------------------------------------------- streamer refusals


def test_a_jump_and_a_trajectory_or_a_goal_naming_its_start_mid_motion_are_refused_and_the_motion_goes_on(crane):
    """The streamer refuses a trajectory that does not start at its hold (a jump), and one arriving while it
    streams; a goal during a motion takes it over from where it is (test_motion_from_state), so the planner refuses
    one naming a start of its own. The motion goes on unbroken to its successful end."""
    from trajectory_msgs.msg import JointTrajectory

    from crane_msgs_py.messages.names import TRAJECTORY_TOPIC
    from crane_msgs_py.runtime.diagnostics import ERROR
    from crane_msgs_py.runtime.qos import TRAJECTORY_QOS
    pub = crane.publisher(JointTrajectory, TRAJECTORY_TOPIC, TRAJECTORY_QOS)
    try:
        hold = crane.hold
        with crane.references() as refs:
            mark = crane.diagnostics.mark()
            pub.publish(quintic_trajectory(hold + 0.5, hold + 0.6, 1.0))
            jump = crane.status('crane_streamer', 'trajectory', mark, level=ERROR)
            plan, start_ns, end_ns = crane.move('nvf', D if hold < D / 2 else 0.0, 3.0)
            crane.sleep_until(start_ns + 1_000_000_000)
            mark = crane.diagnostics.mark()
            pub.publish(quintic_trajectory(hold, hold + 0.1, 1.0))
            mid = crane.status('crane_streamer', 'trajectory', mark, level=ERROR)
            with pytest.raises(PlanError, match='a goal during a motion starts where the motion is when it takes '
                                                'over'):
                crane.planner.execute('nvf', crane.hold, crane.hold + 0.1, 3.0)
            crane.sleep_until(end_ns + 300_000_000)
    finally:
        crane.node.destroy_publisher(pub)
    assert 'hold position' in jump.message and 'jump' in jump.message
    assert 'streaming' in mid.message
    result = crane.driver.move_result(start_ns)
    assert result.success and crane.driver.now_ns() > end_ns + round(SETTLE * 1e9)
    rows = np.array(refs, dtype=object)
    stamps, x = rows[:, 0].astype(np.int64), rows[:, 1].astype(float)
    assert np.all(x[stamps < start_ns] == hold) and np.all(x[stamps > end_ns] == crane.hold)
    # unbroken: between received samples the position moves no faster than the plan does
    vmax = np.max(np.abs(np.diff(plan.position) / np.diff(plan.t)))
    assert np.all(np.abs(np.diff(x)) <= 1.05 * vmax * np.diff(stamps) * 1e-9 + 1e-9)


# --------------------------------------------------------------------------- bad requests


BAD_REQUESTS = [  # (method, joint_names, start, goal, duration), the field and words of the reason
    (('zv', [], [0.0], [0.3], -1.0), 'duration', 'got -1.0'),
    (('rvf', [], [0.0], [0.3], math.nan), 'duration', 'must be finite'),
    (('rvf', [], [0.0], [0.3], math.inf), 'duration', 'must be finite'),
    (('xyz', [], [0.0], [0.3], 3.0), 'method', "unknown method 'xyz'"),
    (('zv', ['hoist'], [0.0], [0.3], 3.0), 'joint_names', "unknown joint 'hoist'"),
    (('zv', [], [0.0, 0.1], [0.3], 3.0), 'start', '2 value(s) for 1 joint(s)'),
    (('zv', [], [0.0], [0.3, 0.2], 3.0), 'goal', '2 value(s) for 1 joint(s)'),
    (('nvf', [], [math.nan], [0.3], 3.0), 'start', 'must be finite'),
    (('zv', [], [0.0], [math.nan], 3.0), 'goal', 'must be finite'),
    (('zv', [], [0.0], [0.3], 100.0), 'duration', 'exceeds max_duration 60 s'),
    (('rvf', [], [0.0], [25.0], 3.0), 'goal', 'exceeds max_displacement 10 m'),
    (('zvd', [], [0.0], [0.3], 2.0), 'duration', 'longer than its shaper'),
    (('zv', [], [0.0], [0.3], 0.0), 'duration', 'needs max_velocity or max_acceleration'),  # 0: fastest
]


@pytest.mark.parametrize('request_, field, reason', BAD_REQUESTS)
def test_bad_request_is_refused_naming_the_field_moves_nothing_and_a_good_one_succeeds(
        crane, request_, field, reason):
    """Each bad PlanMove is success: false with a message naming the field, also on /diagnostics; the
    same move as an ExecuteMove goal is aborted with the same reason and streams nothing."""
    from crane_msgs_py.messages.conversions import move_message
    from crane_msgs_py.runtime.diagnostics import ERROR, status_values
    method, joints, start, goal, duration = request_
    move = move_message(goal, duration, start, method, joints)
    mark = crane.diagnostics.mark()
    response = crane.planner.call(None, None, 0.0, 0.0, move=move)
    assert not response.success and len(response.trajectory.points) == 0
    assert response.message.startswith(f'move.{field}') and reason in response.message, response.message
    status = crane.status('crane_planner', 'plan', mark, level=ERROR)
    assert status.message == response.message and status_values(status)['error'] == status.message
    # executed: aborted with the same reason, nothing sent to the streamer
    sent = len(crane.driver.sent_trajectories())
    handle = crane.planner.send_execute(None, None, 0.0, 0.0, move=move)
    with pytest.raises(PlanError) as refused:
        crane.planner.result(handle, timeout=10.0)
    assert str(refused.value) == response.message
    crane.nodes.check_alive()
    assert len(crane.driver.sent_trajectories()) == sent
    # a good request right after
    assert crane.planner.plan(method if method != 'xyz' else 'zv', 5.0, 5.3, 3.0).position[-1] == \
        pytest.approx(5.3, abs=1e-9)


@pytest.mark.parametrize('name, value, words', [('L1', -1.0, 'L1'), ('method', 'zz', 'method'),
                                                ('shaper_damping', 1.0, 'damping'),
                                                ('robust_parameters', ['L3'], 'L3'),
                                                ('handover_warmup', -0.01, 'handover_warmup')])
def test_bad_planner_parameter_is_refused_with_reason_and_planning_goes_on(crane, name, value, words):
    from rclpy.parameter import Parameter

    from crane_msgs_py.runtime.diagnostics import ERROR
    mark = crane.diagnostics.mark()
    future = crane.planner_params.set_parameters([Parameter(name, value=value)])
    deadline = time.monotonic() + 5.0
    while not future.done():
        assert time.monotonic() < deadline
        time.sleep(0.01)
    result = future.result().results[0]
    assert not result.successful and words in result.reason
    status = crane.status('crane_planner', 'parameters', mark, level=ERROR)
    assert words in status.message
    plan = crane.planner.plan(None, 5.0, 5.3, 3.0)  # ~/plan: the method parameter, still rvf
    assert plan.position[-1] == pytest.approx(5.3, abs=1e-9)


def test_axis_limit_set_on_the_planner_applies_to_the_next_request(crane):
    """A shaper plan above max_velocity is refused naming the limit; NVF bends its plan
    under it (0.16 m/s: above the mean speed 0.1 m/s, below the unlimited peaks)."""
    crane.driver.set_parameters('planner', {'max_velocity': 0.16})
    try:
        with pytest.raises(PlanError, match='zv plan exceeds max_velocity 0.16'):
            crane.planner.plan('zv', 5.0, 5.3, 3.0)
        plan = crane.planner.plan('nvf', 5.0, 5.3, 3.0)
        speed = np.diff(plan.position) / np.diff(plan.t)  # means between knots
        assert 0.1 < np.max(np.abs(speed)) <= 0.16 * (1 + 1e-6)
    finally:
        crane.driver.set_parameters('planner', {'max_velocity': 0.0})
    assert crane.planner.plan('zv', 5.0, 5.3, 3.0).position[-1] == pytest.approx(5.3, abs=1e-9)


def test_keep_out_boxes_set_on_the_planner_refuse_a_preview_through_one_and_give_the_clearance_of_one_past(crane):
    """A wall across the runway 0.10 m above the load, 0.25 m ahead of the cart at 5 m: a move through it is
    refused naming it (also on /diagnostics); one that stops before it says its clearance; a box of five
    numbers is refused naming the parameter; without boxes the clearance is infinite."""
    from crane_msgs_py.runtime.diagnostics import ERROR
    from crane_planner.tools.harness import HarnessError
    wall = [5.25, 5.35, -math.inf, math.inf, -2.0, -0.76]
    crane.driver.set_parameters('planner', {'keep_out': wall, 'keep_out_margin': 0.02})
    try:
        mark = crane.diagnostics.mark()
        with pytest.raises(PlanError, match=r'move.keep_out: the zv plan does not keep out: the load \(m2\) comes '
                                            r'[0-9.]+ mm into keep_out box 1 \(x 5.25..5.35, y -inf..inf'):
            crane.planner.plan('zv', 5.0, 5.6, 4.0)
        assert crane.diagnostics.wait_for(lambda s: 'keep_out box 1' in s.message, 5.0, after=mark,
                                          name='crane_planner: plan', level=ERROR) is not None
        plan = crane.planner.plan('zv', 5.0, 5.15, 4.0)  # the load swings ~8 mm about its path: 80 mm clear
        assert 0.05 < plan.info.min_clearance < 0.1 and plan.info.route == ''
        # the planner draws the box on crane_markers (once a second, expiring after 2 s)
        from visualization_msgs.msg import MarkerArray

        from crane_msgs_py.messages.names import MARKERS_TOPIC
        from crane_msgs_py.runtime.qos import MARKERS_QOS
        drawn = []
        sub = crane.driver.node.create_subscription(
            MarkerArray, MARKERS_TOPIC, lambda m: drawn.extend(k for k in m.markers if k.ns == 'keep_out'), MARKERS_QOS)
        try:
            crane.driver.wait_until(lambda: drawn, 5.0, 'no keep_out marker on crane_markers within 5 s')
        finally:
            crane.driver.node.destroy_subscription(sub)
        box = drawn[0]
        assert (box.pose.position.x, box.scale.x, box.scale.z) == pytest.approx((5.30, 0.10, 1.24))
        assert box.header.frame_id == 'crane_base' and box.lifetime.sec == 2
        with pytest.raises(HarnessError, match=r'keep_out: .*keep_out: 5 number\(s\); a box is six'):
            crane.driver.set_parameters('planner', {'keep_out': wall[:5]})
    finally:
        crane.driver.set_parameters('planner', {'keep_out': []})
    assert crane.planner.plan('zv', 5.0, 5.6, 4.0).info.min_clearance == math.inf


def fastest_when_built(crane, method: str, start: float, goal: float, within: float = 120.0):
    """``~/fastest/<method>``, asked again every second while the answer is that its solver is still being built
    (limits add the fastest plan's NLPs, which the workers build in the background: a request meanwhile is
    answered within its budget all the same, refused saying so)."""
    deadline = time.monotonic() + within
    while True:
        try:
            return crane.planner.fastest(method, start, goal)
        except PlanError as exc:
            if 'still building' not in str(exc) or time.monotonic() > deadline:
                raise
        crane.driver.sleep(1.0)


def test_fastest_services_answer_the_shortest_plan_within_the_limits_and_refuse_without(crane):
    """~/fastest/<method>: the goal stamp is ignored, the last pose carries the end time, equal to the
    planning core's own fastest plan; refused naming the missing limit when none is set."""
    from crane_msgs_py.crane.params import CraneParams
    from crane_planner.planning import PlanOptions
    from crane_planner.serving import Planner
    with pytest.raises(PlanError, match='needs max_velocity or max_acceleration'):
        crane.planner.fastest('zv', 5.0, 5.3)
    # the budget of 1 s is what a loaded host can exceed for a free-time NLP; what is asserted here is the plan
    crane.driver.set_parameters('planner', {'max_velocity': 0.25, 'max_acceleration': 0.5, 'max_solve_time': 10.0})
    sent = len(crane.driver.sent_trajectories())
    try:
        offline = Planner()
        for method in ('zv', 'nvf'):
            plan = fastest_when_built(crane, method, 5.0, 5.3)
            expected = offline.fastest(method, 0.3, CraneParams(), PlanOptions(max_velocity=0.25,
                                                                               max_acceleration=0.5))
            assert plan.t[-1] == pytest.approx(expected.duration, rel=1e-6)
            assert plan.position[-1] == pytest.approx(5.3, abs=1e-9)
            speed = np.diff(plan.position) / np.diff(plan.t)
            assert np.max(np.abs(speed)) <= 0.25 * (1 + 1e-6)
        crane.driver.sleep(0.3)
        assert len(crane.driver.sent_trajectories()) == sent  # previews: nothing for the streamer
    finally:
        crane.driver.set_parameters('planner', {'max_velocity': 0.0, 'max_acceleration': 0.0, 'max_solve_time': 1.0})


# --------------------------------------------------------------------------- sim input checks


def test_sim_ignores_and_counts_nonfinite_out_of_order_and_stale_references(crane):
    from trajectory_msgs.msg import JointTrajectory

    from crane_msgs_py.messages.conversions import fill_reference, reference_message
    from crane_msgs_py.messages.names import REFERENCE_TOPIC
    from crane_msgs_py.runtime.qos import REFERENCE_QOS
    crane.driver.reset_sim()
    pub = crane.publisher(JointTrajectory, REFERENCE_TOPIC, REFERENCE_QOS)
    try:
        before = crane.values('crane_sim', 'sim', crane.diagnostics.mark())
        # stamps relative to the moment each is sent: (age ns, position, acceleration)
        bad = [(0, math.nan, 0.0)] * 5                  # non-finite position
        bad += [(0, crane.hold, math.inf)] * 3          # non-finite acceleration
        bad += [(30_000_000, crane.hold, 0.0)] * 4      # older than the stream's newest sample
        bad += [(5_000_000_000, crane.hold, 0.0)] * 2   # stale
        for age, x, a in bad:
            msg = reference_message()
            fill_reference(msg, crane.now() - age, x, 0.0, a)
            pub.publish(msg)
            time.sleep(0.002)
        time.sleep(0.2)
        after = crane.values('crane_sim', 'sim', crane.diagnostics.mark())
    finally:
        crane.node.destroy_publisher(pub)
    counted = {k: int(after[k]) - int(before[k]) for k in ('nonfinite', 'out_of_order', 'stale')}
    assert counted == {'nonfinite': 8, 'out_of_order': 4, 'stale': 2}
    # the plant did not see them: still at rest (reset above), stepping
    assert abs(float(after['theta1'])) < 1e-9 and abs(float(after['theta2'])) < 1e-9
    assert int(after['steps']) > int(before['steps'])  # (its rate is the timing benchmark's business)


# --------------------------------------------------------------------------- position-only output


def test_float64_array_output_drives_the_sim_from_positions_alone(crane, ros_domain, tmp_path):
    """A streamer with ``output: float64_array`` and a sim of their own: the sim detects the type
    and reconstructs the acceleration from the positions, so the cart still ends at the goal; also when
    the streamer stalls (SIGSTOP) 0.4 s mid-motion, longer than the playout delay, within the sim's watchdog
    (set to 0.5 s here: a drive on a link known to stall): its unstamped samples, sent late, are timed from their
    arrival again, a delay the sim must not take for a lost stream."""
    import os
    import signal

    from trajectory_msgs.msg import JointTrajectory

    from crane_msgs_py.runtime.diagnostics import status_values
    from crane_msgs_py.runtime.qos import TRAJECTORY_QOS
    from crane_planner.tools.processes import SIM, STREAMER, NodeGroup
    ns = f'{NS}_f64'
    with NodeGroup(ros_domain, tmp_path) as nodes:
        streamer = nodes.start(*STREAMER, namespace=ns, params={'output': 'float64_array'})
        nodes.start(*SIM, namespace=ns, params={'reference_timeout': 0.5})
        sim_status = dict(name='crane_sim: sim', hardware_id=f'{ns}/crane_sim')
        # the type is known from the streamer's publisher; the streamer takes trajectories once it streams
        # (after the sim's first joint_states): the sim then accepts references
        assert crane.diagnostics.wait_for(lambda s: status_values(s)['reference_type'] == 'float64_array' and
                                          int(status_values(s)['accepted']) > 0,
                                          30.0, after=crane.diagnostics.mark(), **sim_status) is not None
        pub = crane.publisher(JointTrajectory, f'{ns}/trajectory', TRAJECTORY_QOS)
        try:
            start_ns = crane.now() + 500_000_000
            pub.publish(quintic_trajectory(0.0, D, 2.0, start_ns))
            crane.sleep_until(start_ns + 800_000_000)
            os.kill(streamer.popen.pid, signal.SIGSTOP)
            try:
                time.sleep(0.4)
            finally:
                os.kill(streamer.popen.pid, signal.SIGCONT)
            crane.sleep_until(start_ns + 3_900_000_000)  # 2 s motion, its 0.4 s pause, 0.1 s playout, a report
            mark = crane.diagnostics.mark()
            # the sim reports once a second. Unstamped samples are timed by their arrival: a stall of the sim
            # longer than the playout delay delays the rest of the stream by its length (it cannot be told from
            # the sender's pause), so a loaded host may see the cart arrive later: the reference must end at the
            # goal and the cart be there
            status = crane.diagnostics.wait_for(lambda s: abs(float(status_values(s)['y']) - D) < 5e-3 and
                                                abs(float(status_values(s)['cart_reference']) - D) < 1e-6, 15.0,
                                                after=mark, **sim_status)
            seen = crane.diagnostics.wait_for(None, 0.0, after=mark, **sim_status)
            assert status is not None, f'the cart did not end at the goal: {seen and status_values(seen)}'
            values = status_values(status)
        finally:
            crane.node.destroy_publisher(pub)
        nodes.check_alive()
    assert int(values['accepted']) > 2000 and values['reference_type'] == 'float64_array'


def test_markers_draw_the_crane_of_the_published_joint_states(crane):
    """crane_markers at the joint_states rate, in crane_base: the masses where the same joint_states put
    them (x1 = y - L1 sin th1, x2 = x1 - L2 sin(th1 + th2); z down the cables) within 1e-9 m.

    Both streams are read on a node and executor of their own with queues of 10 s, as ``references()``
    does: this process (its Python threads, the harness's executor among them) can stall on a
    loaded host for longer than a reader queue of the markers' own depth (5 frames, 100 ms: RViz's)
    holds while DDS receives every frame on time, and the frames such a queue drops would look like
    a sim publishing markers too slowly.
    """
    import rclpy
    from rclpy.experimental import EventsExecutor
    from sensor_msgs.msg import JointState
    from visualization_msgs.msg import MarkerArray

    from crane_msgs_py.messages.conversions import CABLES_MARKER, CART_MARKER, MASS1_MARKER, MASS2_MARKER, stamp_ns
    from crane_msgs_py.messages.names import JOINT_STATES_TOPIC, MARKERS_TOPIC
    from crane_msgs_py.runtime.qos import JOINT_STATES_QOS, MARKERS_QOS, recording
    from crane_msgs_py.runtime.runner import spinning
    L1, L2 = 0.47, 0.391
    states, markers = {}, {}
    deep_states, deep_markers = (recording(qos, 10.0, 50.0) for qos in (JOINT_STATES_QOS, MARKERS_QOS))
    node = rclpy.create_node('crane_it_markers', namespace=NS)
    newest = {'states': 0, 'markers': 0}  # stamp of the newest message of each stream

    def keep(into: dict, stream: str, stamp: int, msg):
        into.setdefault(stamp, msg)
        newest[stream] = max(newest[stream], stamp)

    node.create_subscription(JointState, JOINT_STATES_TOPIC,
                             lambda m: keep(states, 'states', stamp_ns(m.header.stamp), m), deep_states)
    node.create_subscription(MarkerArray, MARKERS_TOPIC,
                             lambda m: keep(markers, 'markers', stamp_ns(m.markers[0].header.stamp), m), deep_markers)
    executor = EventsExecutor()  # takes no new entities while spinning: everything is added first
    executor.add_node(node)
    try:
        with spinning(executor):
            start_ns, _, _ = crane.driver.move('zv', crane.hold, crane.next_goal(), 2.0)  # let it swing
            crane.hold = crane.next_goal()
            crane.sleep_until(start_ns + 1_500_000_000)
            # what is still queued counts too: both streams up to the newest stamp either has now
            last = max(newest.values())
            crane.driver.wait_until(lambda: min(newest.values()) >= last, 5.0,
                                    'joint_states and crane_markers did not catch up within 5 s')
    finally:
        node.destroy_node()
    common = sorted(set(states) & set(markers))
    assert len(common) >= 50, f'{len(common)} stamps with both joint_states and markers'
    swing = 0.0
    for stamp in common:
        y, th1, th2 = states[stamp].position
        m = markers[stamp].markers
        x1, z1 = y - L1 * np.sin(th1), -L1 * np.cos(th1)
        x2, z2 = x1 - L2 * np.sin(th1 + th2), z1 - L2 * np.cos(th1 + th2)
        assert m[MASS1_MARKER].pose.position.x == pytest.approx(x1, abs=1e-9)
        assert m[MASS1_MARKER].pose.position.z == pytest.approx(z1, abs=1e-9)
        assert m[MASS2_MARKER].pose.position.x == pytest.approx(x2, abs=1e-9)
        assert m[MASS2_MARKER].pose.position.z == pytest.approx(z2, abs=1e-9)
        assert m[CART_MARKER].pose.position.x == pytest.approx(y, abs=1e-12)
        assert [p.x for p in m[CABLES_MARKER].points] == pytest.approx([y, x1, x2], abs=1e-9)
        assert {mk.header.frame_id for mk in m} == {'crane_base'}
        swing = max(swing, abs(th1))
    assert swing > 0.01  # the crane really swung: the check is not of a crane at rest
    rate = (len(common) - 1) / ((common[-1] - common[0]) * 1e-9)
    assert rate == pytest.approx(50.0, rel=0.05)


def test_the_sim_s_sensor_latency_delays_joint_states_and_a_steady_wind_deflects_the_measured_load(crane):
    """sensor_latency 0.05 s: every joint_states sample reaches the middleware 0.05 s later after its stamp than
    without (by construction at least playout_delay + latency - one step after it), all of them, in order. A
    wind of [0.3, 0] m/s^2 at rest swings the measured load about its deflection L w / sqrt(g^2 + w^2) ahead
    of the cart (26 mm: the mean over two periods of the slow mode). Both set back afterwards and the sim
    reset, so no swing is left for the next test.

    Arrival is the DDS reader's receive time (``references(arrival=True)``'s), which this process's own lag
    does not shift."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from sensor_msgs.msg import JointState

    from crane_msgs_py.messages.conversions import stamp_ns
    from crane_msgs_py.messages.names import JOINT_STATES_TOPIC
    from crane_msgs_py.runtime.qos import JOINT_STATES_QOS, recording
    from crane_msgs_py.runtime.runner import spinning
    from crane_planner.tools.harness import state_columns
    latency, playout_delay, step = 0.05, 0.1, 1e-3  # (the sim's playout_delay and step at their defaults)
    driver = crane.driver
    driver.wait_until_holding()  # a motion a test before left running has ended,
    driver.wait_until_still()
    driver.reset_sim()  # and the load is at rest: the wind swings it from there
    rows = []  # (received ns, stamp ns)
    node = rclpy.create_node('crane_it_sensor', namespace=NS)
    node.create_subscription(JointState, JOINT_STATES_TOPIC,
                             lambda m, info: rows.append((info['received_timestamp'], stamp_ns(m.header.stamp))),
                             recording(JOINT_STATES_QOS, 10.0, 50.0))
    executor = SingleThreadedExecutor()
    executor.add_node(node)

    def received(seconds: float) -> np.ndarray:
        begin = len(rows)
        driver.sleep(seconds)
        return np.array(rows[begin:], dtype=np.int64).reshape(-1, 2)

    try:
        with spinning(executor):
            driver.wait_until(lambda: len(rows) > 5, 5.0, 'no joint_states received')
            before = received(1.0)
            driver.set_parameters('sim', {'sensor_latency': latency})
            try:
                driver.sleep(0.2)  # (what the change released at once counts for neither)
                after = received(1.0)
            finally:
                driver.set_parameters('sim', {'sensor_latency': 0.0})
    finally:
        node.destroy_node()
    lag_before, lag_after = ((r[:, 0] - r[:, 1]) * 1e-9 for r in (before, after))
    assert np.median(lag_after) - np.median(lag_before) == pytest.approx(latency, abs=0.01)
    assert lag_after.min() >= playout_delay + latency - step - 1e-3, lag_after.min()
    assert np.all(np.diff(after[:, 1]) > 0) and len(after) >= 45, len(after)  # every sample (50 Hz), in order

    wind = 0.3
    driver.set_parameters('sim', {'wind': [wind, 0.0]})
    try:
        begin = driver.now_ns() + round(0.3e9)
        end = begin + round(2 * 2 * math.pi / modal_frequencies(NOMINAL)[0] * 1e9)
        crane.sleep_until(end)
        rec = state_columns(driver.states_between(begin, end, timeout=5.0))
    finally:
        driver.set_parameters('sim', {'wind': [0.0, 0.0]})
        driver.reset_sim()
    assert len(rec['stamp']) > 40 * (end - begin) * 1e-9
    theta1, theta2 = rec['theta1'], rec['theta2']
    ahead = -(NOMINAL.L1 * np.sin(theta1) + NOMINAL.L2 * np.sin(theta1 + theta2))  # the load's offset along x
    deflection = (NOMINAL.L1 + NOMINAL.L2) * wind / math.hypot(NOMINAL.g, wind)
    assert ahead.mean() == pytest.approx(deflection, rel=0.03)
    assert ahead.min() > -0.1 * deflection and ahead.max() < 2.2 * deflection  # swinging about it, from rest
    assert np.ptp(rec['cart']) < 1e-9  # the cart held: the wind acts on the load
