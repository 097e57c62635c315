"""A small ROS harness around the three crane nodes, shared by ``crane-demo`` and the tests.

``start_crane_nodes`` starts the planner, streamer and sim executables in one
namespace of a ``NodeGroup``; ``CraneHarness`` is the rclpy side: plan and
stream a move, set parameters, read the sim's joint_states. The demo's
experiment, table and figures stay in ``demo``. One of the two tool modules
that may import ROS (with ``demo``).
"""
from __future__ import annotations

import math
import threading
import time
from collections import deque
from typing import Callable

import numpy as np
import rclpy
from crane_interfaces.msg import AxisStatus, StreamState
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.executors import MultiThreadedExecutor
from rclpy.experimental import EventsExecutor
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory

from crane_msgs_py.client import PlannerClient
from crane_msgs_py.crane.drive import AxisState
from crane_msgs_py.messages.conversions import (
    HOLDING,
    move_message,
    read_reference,
    read_stream_state,
    samples_to_joint_trajectory,
    stamp_ns,
)
from crane_msgs_py.messages.names import (
    ACTUATED_JOINTS,
    AXIS_STATUS_TOPIC,
    BRIDGE_JOINT,
    CART_JOINT,
    HOIST_JOINT,
    JOINT_STATES_TOPIC,
    PLANNER_NODE,
    PUSH_SERVICE,
    REFERENCE_TOPIC,
    RESET_SERVICE,
    SETTLE_SERVICE,
    SIM_NODE,
    STREAM_STATE_TOPIC,
    STREAMER_NODE,
    TRAJECTORY_TOPIC,
    service_of,
)
from crane_msgs_py.runtime.diagnostics import OK, level_of, status_values
from crane_msgs_py.runtime.qos import (
    AXIS_STATUS_QOS,
    JOINT_STATES_QOS,
    REFERENCE_EVERY_SAMPLE_QOS,
    STREAM_STATE_QOS,
    TRAJECTORY_QOS,
    recording,
)
from crane_msgs_py.runtime.runner import spinning

from .processes import PLANNER, SIM, STREAMER, NodeGroup

#: The columns of the joint_states rows the harness keeps (``states_between``, ``last_state``): the stamp (ns),
#: the in-plane swing angles, every actuated joint's position, then the out-of-plane angles (NaN for what the
#: setup does not have: a joint it lacks, phi without a bridge). Read them by name (``state_columns``).
STATE_COLUMNS = ('stamp', 'theta1', 'theta2', *ACTUATED_JOINTS, 'phi1', 'phi2')


def state_columns(rows: np.ndarray) -> dict[str, np.ndarray]:
    """The columns of joint_states ``rows`` (``states_between``) by their names in ``STATE_COLUMNS``."""
    return dict(zip(STATE_COLUMNS, np.asarray(rows).reshape(-1, len(STATE_COLUMNS)).T))


def measured_masses(rec: dict, L1: float, L2: float) -> tuple[np.ndarray, np.ndarray]:
    """(m1, m2): both masses' positions (n, 3) in crane_base from recorded joint_states columns
    (``state_columns``): the cart, the bridge and the rope (the hoist's column) where they are served, else
    0, 0 and ``L1``; placed by crane_sim's own cable directions, not the planner's."""
    from crane_sim.spatial import mass_paths
    served = {name: rec[name] if name in rec and np.all(np.isfinite(rec[name])) else None
              for name in ('bridge', 'hoist', 'phi1', 'phi2')}
    m1, m2 = mass_paths(rec['cart'], 0.0 if served['bridge'] is None else served['bridge'],
                        L1 if served['hoist'] is None else served['hoist'], L2, rec['theta1'], rec['theta2'],
                        *(0.0 if served[k] is None else served[k] for k in ('phi1', 'phi2')))
    return m1.T, m2.T


class HarnessError(RuntimeError):
    """The harness cannot go on (a timeout, a refusal); the message says why."""


def start_crane_nodes(nodes: NodeGroup, namespace: str, streamer_params: dict | None = None,
                      hoist: bool = False, joints=None, planner_params: dict | None = None):
    """Start the planner, streamer and sim executables in ``namespace`` (``hoist``: all three with the joints
    [cart, hoist]; ``joints``: with these, e.g. [cart, bridge]; ``planner_params`` and ``streamer_params``
    besides)."""
    joints = {'joints': list(joints)} if joints else {'joints': ['cart', 'hoist']} if hoist else {}
    nodes.start(*PLANNER, namespace=namespace, params={**joints, **(planner_params or {})} or None)
    nodes.start(*STREAMER, namespace=namespace, params={**joints, **(streamer_params or {})} or None)
    nodes.start(*SIM, namespace=namespace, params=joints or None)


#: How many stream_state corrections the harness keeps (``corrections_between``): 2 minutes at 50 Hz.
CORRECTIONS_KEPT = 6000
#: A load this still (m) with the sway feedback's correction this small (m) is quiet (``wait_until_quiet``).
QUIET_SWING, QUIET_CORRECTION = 2e-4, 5e-5

#: A mode set on the streamer counts as heard by the planner once a stream_state this long (ns) after the change
#: says so (three of them at 50 Hz: the planner gets them as this harness does, on a thread of its own).
MODE_HEARD_AFTER_NS = 60_000_000


class CraneHarness:
    """An rclpy node beside running crane nodes: plans and executes over the planner's
    PlanMove service and ExecuteMove action, sets parameters, resets the sim, reads the streamer's word and records
    joint_states. Spins in a thread of its own from construction to ``close()``.

    Every wait also watches the node processes: a node that dies ends the wait
    with NodeDied; a wait that times out is a HarnessError naming what was awaited.
    """

    def __init__(self, namespace: str, nodes: NodeGroup, log: Callable[[str], None] | None = None,
                 node_name: str = 'crane_harness'):
        """``log`` receives notable events (a trajectory that reached the streamer late)."""
        self.nodes = nodes
        self._log = log or (lambda text: None)
        self._namespace = '/' + namespace.strip('/') if namespace.strip('/') else ''
        self._owns_context = not rclpy.ok()  # (a second harness in this process, another crane's, shares it)
        if self._owns_context:
            rclpy.init()
        self.node = rclpy.create_node(node_name, namespace=namespace)
        group = ReentrantCallbackGroup()
        self.planner = PlannerClient(self.node, PLANNER_NODE, callback_group=group)
        self._params = {target: AsyncParameterClient(self.node, name, callback_group=group)
                        for target, name in (('planner', PLANNER_NODE), ('sim', SIM_NODE),
                                             ('streamer', STREAMER_NODE))}
        self._reset = self.node.create_client(Trigger, service_of(SIM_NODE, RESET_SERVICE), callback_group=group)
        self._push = self.node.create_client(Trigger, service_of(SIM_NODE, PUSH_SERVICE), callback_group=group)
        self._streamer_services = {name: self.node.create_client(Trigger, service_of(STREAMER_NODE, f'~/{name}'),
                                                                 callback_group=group) for name in ('start', 'stop')}
        self._settle = self.node.create_client(Trigger, service_of(PLANNER_NODE, SETTLE_SERVICE),
                                               callback_group=group)
        self._lock = threading.Lock()
        self._slowest_plan = 0.0
        self._states: list = []  # (stamp ns, theta1, theta2, cart, hoist: the rope length, NaN without one)
        self._trajectories: dict = {}  # start stamp ns -> JointTrajectory
        self._stamps: dict = {}  # a late motion's streamed start ns -> its trajectory's stamp (streamed_start)
        self._goals: dict = {}  # start stamp ns -> ExecuteMove goal handle, until its result is read
        # The two 50 Hz inputs on a node of their own, spun by an EventsExecutor (subscriptions only, all made
        # before it spins): through the harness node's executor, which rebuilds its wait set for every client
        # of it, their messages cost a large share of a core, here a small one.
        # Every sample counts (the residuals are computed from them): a queue of seconds for this process's stalls.
        self._inputs = rclpy.create_node(f'{node_name}_inputs', namespace=namespace, start_parameter_services=False)
        self._inputs.create_subscription(JointState, JOINT_STATES_TOPIC, self._on_state,
                                         recording(JOINT_STATES_QOS, 10.0, 50.0))
        self._stream_state: tuple | None = None  # (received ns, read_stream_state of the newest)
        self._corrections: deque = deque(maxlen=CORRECTIONS_KEPT)  # (stamp ns, {joint: correction}) of stream_state
        self._inputs.create_subscription(StreamState, STREAM_STATE_TOPIC, self._on_stream_state, STREAM_STATE_QOS)
        self.node.create_subscription(JointTrajectory, TRAJECTORY_TOPIC, self._on_trajectory, TRAJECTORY_QOS,
                                      callback_group=group)
        self._trajectory_pub = self.node.create_publisher(JointTrajectory, TRAJECTORY_TOPIC, TRAJECTORY_QOS)
        self.axis_state = ''  # the sim's newest axis_status state ('idle' until a reference reaches it)
        self.node.create_subscription(AxisStatus, AXIS_STATUS_TOPIC, self._on_axis_status, AXIS_STATUS_QOS,
                                      callback_group=group)
        self._reference_sub = None  # (node, spinning, rows) while the 1 kHz reference is kept (keep_references)
        self._spinnings = []  # entered here, left in close()
        for node, executor in ((self._inputs, EventsExecutor()), (self.node, MultiThreadedExecutor(3))):
            executor.add_node(node)
            self._spinnings.append(spinning(executor))
            self._spinnings[-1].__enter__()

    # -- callbacks
    def _on_state(self, msg):
        names = list(msg.name)
        row = (msg.position[names.index(j)] if j in names else math.nan for j in STATE_COLUMNS[1:])
        with self._lock:
            self._states.append((stamp_ns(msg.header.stamp), *row))

    def _on_axis_status(self, msg):
        self.axis_state = msg.state

    def _on_stream_state(self, msg):
        state = read_stream_state(msg)
        self._stream_state = (self.now_ns(), state)
        with self._lock:
            self._corrections.append((state[0], state[6]))

    def stream_hold(self, joint: str = 'cart', fresh: float = 0.5) -> float | None:
        """Where the streamer holds (or streams) ``joint`` now (m), from a ``stream_state`` received within
        ``fresh`` s; None if none was."""
        state = self._fresh_stream_state(fresh)
        return None if state is None else state[2].get(joint)

    def held(self, joint: str = 'cart', timeout: float = 10.0) -> float:
        """Where the streamer holds ``joint`` (m), from the next fresh ``stream_state`` (``stream_hold``): a host
        that paused this process may leave the newest one stale for a moment."""
        self.wait_until(lambda: self.stream_hold(joint) is not None, timeout,
                        f'no fresh stream_state saying where the streamer holds {joint} within {timeout:g} s')
        return self.stream_hold(joint, fresh=math.inf)

    def correction(self, timeout: float = 1.0, fresh: float = 0.5) -> dict:
        """What the streamer's sway feedback adds to the reference now (m, by joint; empty before the feedback was
        ever on), from the newest ``stream_state``: one received within ``fresh`` s, waited for up to ``timeout``
        s (HarnessError if none comes)."""
        found = []

        def heard():
            state = self._fresh_stream_state(fresh)
            if state is not None:
                found.append(state)
            return bool(found)
        self.wait_until(heard, timeout, f'no stream_state from the streamer within {timeout:g} s')
        return dict(found[0][6])

    def _fresh_stream_state(self, fresh: float):
        """``read_stream_state`` of the newest ``stream_state`` if it was received within ``fresh`` s, else None."""
        state = self._stream_state
        if state is None or self.now_ns() - state[0] > fresh * 1e9:
            return None
        return state[1]

    def corrections_between(self, begin_ns: int, end_ns: int, joint: str = CART_JOINT) -> np.ndarray:
        """The sway feedback's correction of ``joint`` (m) in the stream_state stamped in [begin, end] (the newest
        ``CORRECTIONS_KEPT``): rows of (stamp ns, correction); 0 where the streamer corrects nothing."""
        with self._lock:
            rows = [(stamp, c.get(joint, 0.0)) for stamp, c in self._corrections if begin_ns <= stamp <= end_ns]
        return np.array(rows, dtype=float).reshape(-1, 2)

    def wait_until_quiet(self, L1: float, L2: float, timeout: float = 20.0):
        """Wait until the load hangs still (within ``QUIET_SWING`` by the newest joint_states, with the cable
        lengths ``L1``, ``L2``) and the sway feedback's correction of the cart is back to nothing: the cart where
        the streamer holds it. (Not the sim's ~/reset while a correction moves the cart: the plant set at rest
        under a moving reference, the sim would keep that velocity's offset.)"""
        from crane_msgs_py.crane.geometry import load_excursion

        def still():
            state, last = self._fresh_stream_state(0.5), self.last_state()
            if state is None or last is None:
                return False
            swing = abs(load_excursion(last[1], last[2], L1, L2))
            return abs(state[6].get(CART_JOINT, 0.0)) < QUIET_CORRECTION and swing < QUIET_SWING
        self.wait_until(still, timeout, f'the load not quiet with the correction back to nothing within {timeout:g} s')

    def trajectories_end_ns(self) -> int:
        """When the newest trajectory seen on the ``trajectory`` topic ends (ns; 0 if none): a motion queued
        on the streamer, not started yet, streams until then although the streamer still says it holds."""
        with self._lock:
            if not self._trajectories:
                return 0
            stamp = max(self._trajectories)
            points = self._trajectories[stamp].points
        return stamp + (stamp_ns(points[-1].time_from_start) if points else 0)  # (no points: one sent to be refused)

    def wait_until_holding(self, timeout: float = 30.0):
        """Wait until the streamer's newest ``stream_state`` (within 0.5 s) says it holds: no motion streams.
        A test that failed mid-motion leaves the motion running, which a goal with a start time would find."""
        def holding():
            state = self._fresh_stream_state(0.5)
            return state is not None and state[1] == HOLDING
        self.wait_until(holding, timeout, f'the streamer did not hold within {timeout:g} s')

    def wait_until_still(self, joints=('cart',), window: float = 0.5, timeout: float = 15.0):
        """Wait until ``joints`` stand still (within 1 um) over ``window`` s of joint_states (plant time), window
        after window: after a test that may have left the crane moving (a stick, a brake), instead of a fixed
        sleep as long as the longest such motion. HarnessError if they still move after ``timeout`` s. The
        joint_states read stay for ``states_between``: a caller may want the motion that came to rest."""
        deadline = time.monotonic() + timeout
        while True:
            begin = self.now_ns()  # (_rows_between waits for the window's end, watching the nodes)
            rows = state_columns(self._rows_between(begin, begin + round(window * 1e9), timeout=30.0))
            # (fewer rows than half the window's 50 Hz samples, a lagging plant: judged by the next window)
            if len(rows['stamp']) >= 25 * window and all(np.ptp(rows[j]) < 1e-6 for j in joints):
                return
            if time.monotonic() > deadline:
                raise HarnessError(f'{", ".join(joints)} still moving {timeout:g} s after the test')

    def home(self, move: Callable[[], int], at_home: Callable[[tuple], bool]):
        """Bring the crane home after a test, whatever it left, and reset the sim: once the newest trajectory
        sent has ended and the streamer holds (a motion a failed test left running or queued, or one its goal
        sent later, is over), ``move()`` (a move home, its start stamp) unless ``at_home(the newest
        joint_states row)``; once more if the planner refused it because a motion started meanwhile after
        all."""
        from crane_msgs_py.crane.errors import PlanError
        for attempt in range(2):
            self.sleep(max(0.0, (self.trajectories_end_ns() - self.now_ns()) * 1e-9))
            self.wait_until_holding()
            last = self.last_state()
            if last is not None and at_home(last):
                break
            try:
                start = move()
            except PlanError:
                if attempt:
                    raise
                continue
            self.move_result(start)
            break
        self.reset_sim()

    def references(self) -> list:
        """The references kept so far (``keep_references``): rows of (stamp ns, position, velocity,
        acceleration, received ns)."""
        return list(self._reference_sub[2]) if self._reference_sub is not None else []

    def keep_references(self, keep: bool = True, joints=(CART_JOINT,)) -> np.ndarray | None:
        """Start (``keep``: once they flow) or stop keeping the streamed references at 1 kHz; stopping
        returns those of ``joints`` (given when starting) as rows of (stamp ns, position, velocity, acceleration
        of the first joint, received ns of system time, then the others' position, velocity, acceleration).

        On a node of their own spun by an EventsExecutor: the harness's executor would spend a core on them.
        """
        if keep:
            if self._reference_sub is not None:
                return None
            rows: list = []
            node = rclpy.create_node(f'{self.node.get_name()}_references', namespace=self.node.get_namespace())
            joints = list(joints)

            def keep_one(m):
                stamp, p, v, a = read_reference(m, joints if len(joints) > 1 else None)
                if len(joints) == 1:
                    rows.append((stamp, p, v, a, time.time_ns()))
                else:
                    rows.append((stamp, p[0], v[0], a[0], time.time_ns(), *(x for k in range(1, len(joints))
                                                                           for x in (p[k], v[k], a[k]))))

            node.create_subscription(JointTrajectory, REFERENCE_TOPIC, keep_one,
                                     recording(REFERENCE_EVERY_SAMPLE_QOS, 10.0, 1000.0))
            executor = EventsExecutor()
            executor.add_node(node)
            spin = spinning(executor)
            spin.__enter__()
            self._reference_sub = (node, spin, rows, 2 + 3 * len(joints))
            self.wait_until(lambda: bool(rows), 5.0, 'no reference received')
            return None
        if self._reference_sub is None:
            return None
        node, spin, rows, width = self._reference_sub
        self._reference_sub = None
        spin.__exit__(None, None, None)
        node.destroy_node()
        return np.array(rows, dtype=float).reshape(-1, width)

    def _on_trajectory(self, msg):
        with self._lock:
            self._trajectories[stamp_ns(msg.header.stamp)] = msg

    # -- helpers
    def now_ns(self) -> int:
        return self.node.get_clock().now().nanoseconds

    def wait_until(self, ready, timeout: float, failure: str, interval: float = 0.01):
        """Poll ``ready()`` until true while watching the nodes; HarnessError ``failure`` after ``timeout`` s."""
        deadline = time.monotonic() + timeout
        while not ready():
            self.nodes.check_alive()
            if time.monotonic() > deadline:
                raise HarnessError(failure)
            time.sleep(interval)

    def _wait(self, future, timeout: float, what: str):
        self.wait_until(future.done, timeout, f'no answer from {what} within {timeout:g} s')
        return future.result()

    def sleep(self, seconds: float):
        """Sleep while watching the nodes: a node that dies ends the sleep at once (NodeDied)."""
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            self.nodes.check_alive()
            time.sleep(min(0.05, max(0.0, deadline - time.monotonic())))

    def wait_until_up(self, timeout: float):
        """Wait until every service, parameter client and joint_states is up, the sim tracks the streamer's
        reference and the planner has warmed up."""
        deadline = time.monotonic() + timeout
        waits = [('planner plan_move and execute_move', lambda: self.planner.wait_for_service(0.1))]
        waits += [(f'{target} parameters', lambda c=client: c.wait_for_services(0.1))
                  for target, client in self._params.items()]
        waits += [('sim reset service', lambda: self._reset.wait_for_service(0.1)),
                  ('joint_states', lambda: bool(self._states)),
                  # the sim subscribes once it has seen the reference's type: a motion sent before its first
                  # reference arrives would start without it, and the sim's cart would miss that part
                  ('the sim tracking the reference stream', lambda: self.axis_state == AxisState.TRACKING.value),
                  # The planner builds its solvers in the background at start-up;
                  # planning before that is done would be slow and late.
                  ('planner warm-up', lambda: self.planner.diagnostics.wait_for(
                      name='crane_planner: solvers', timeout=0.1) is not None)]
        for what, ready in waits:
            self.wait_until(ready, deadline - time.monotonic(), f'{what} not up within {timeout:g} s')

    def set_parameters(self, target: str, values: dict, atomically: bool = False):
        """Set parameters on the ``planner``, ``sim`` or ``streamer`` node; HarnessError names any refused.
        ``atomically``: all in one change (else one after the other, as ``ros2 param set`` would: a node's loop
        may run a step between them, e.g. the sim's with the wind on and its gusts not yet).

        An empty list is an empty double array (rclpy would take it for a byte array). The streamer's
        ``mode`` returns once its stream_state has said so for a few messages: the planner, which refuses a
        goal while the streamer is in operator mode, hears the mode there."""
        client = self._params[target]
        changed = self.now_ns()
        params = [Parameter(k, Parameter.Type.DOUBLE_ARRAY, []) if isinstance(v, list) and not v
                  else Parameter(k, value=v) for k, v in values.items()]
        if atomically:
            outcome = self._wait(client.set_parameters_atomically(params), 5.0, f'{target} parameter service').result
            refused = [] if outcome.successful else [f'{", ".join(values)}: {outcome.reason}']
        else:
            result = self._wait(client.set_parameters(params), 5.0, f'{target} parameter service')
            refused = [f'{p.name}: {r.reason}' for p, r in zip(params, result.results) if not r.successful]
        if refused:
            raise HarnessError(f'{target} refused parameters: {"; ".join(refused)}')
        if target == 'streamer' and 'mode' in values:
            operator = values['mode'] == 'operator'
            heard_after = changed + MODE_HEARD_AFTER_NS

            def heard():
                state = self._stream_state
                return state is not None and state[1][0] >= heard_after and (state[1][1] == 'operator') == operator

            self.wait_until(heard, 5.0, f'the streamer\'s stream_state never said mode {values["mode"]}')

    def reset_sim(self):
        response = self._wait(self._reset.call_async(Trigger.Request()), 5.0, 'sim reset service')
        if not response.success:
            raise HarnessError(f'sim reset failed: {response.message}')

    def lead(self) -> float:
        """Seconds between a request and its motion start: three times the slowest round trip
        seen so far, at least the planner's default publish_lead (it sends the trajectory at once
        then). A request after a parameter change, on a machine also recording at 1 kHz, can
        take longer than that: such a motion reaches the streamer late and is streamed whole from its
        next tick, and every window follows the start it really got (``streamed_start``). At most 2 s: a route
        past a keep-out box plans for seconds on a loaded machine, and the motions after it need not wait
        three times that."""
        return min(2.0, max(0.3, 3.0 * self._slowest_plan))

    def move(self, method: str, start: float, goal: float, duration: float, start_ns: int | None = None,
             settle: float = 0.0, hoist: tuple[float, float] | None = None,
             bridge: tuple[float, float] | None = None):
        """Execute a move starting at ``start_ns`` (default :meth:`lead` from now) through the planner's
        ``~/execute_move``; (the stamp the motion starts, plan round trip s, served trajectory).
        ``hoist`` = (start, goal) of the rope length (m) moves the hoist too (a planner with joints [cart, hoist]),
        ``bridge`` = (start, goal) (m) the bridge; ``start`` None starts every joint where the streamer holds it
        (a start given with a further axis: each axis's start given too).

        The round trip lasts until the goal's first feedback (sent once it is
        planned); a refused plan raises PlanError with the planner's reason.
        The action's result (after ``settle`` s of observation, 0 = the
        planner's default) is :meth:`move_result`.
        """
        others = [(name, ends) for name, ends in ((BRIDGE_JOINT, bridge), (HOIST_JOINT, hoist)) if ends is not None]
        if start_ns is None:
            start_ns = self.now_ns() + round(self.lead() * 1e9)
        mark = self.planner.diagnostics.mark()
        planned = threading.Event()
        t0 = time.perf_counter()
        starts = [] if start is None else [start, *(ends[0] for _, ends in others)]
        move = None if not others else move_message([goal, *(ends[1] for _, ends in others)], duration, starts,
                                                     method, ['cart', *(name for name, _ in others)], start_ns)
        handle = self.planner.send_execute(method, start, goal, duration, start_ns, settle,
                                           feedback=lambda _: planned.set(), timeout=30.0, move=move)
        outcome = handle.get_result_async()
        self.wait_until(lambda: planned.is_set() or outcome.done(), 30.0, f'the {method} goal was never planned')
        plan_time = time.perf_counter() - t0
        if not planned.is_set():  # ended before any feedback: refused
            self.planner.result(handle, timeout=5.0)  # raises PlanError with the planner's reason
        self._slowest_plan = max(self._slowest_plan, plan_time)
        if self.now_ns() > start_ns:
            # the streamer streams a late trajectory whole from its next tick (never a jump) and says
            # so: streamed_start returns the start it really got, and every window follows it
            self._log(f'planning {method} took {plan_time:.2f} s, past the motion start: the motion starts late')
        # sent publish_lead before its start (or at once): wait that long too
        traj = self.trajectory(start_ns, f'the {method}', timeout=5.0 + max(0.0, (start_ns - self.now_ns()) * 1e-9))
        streamed = self.streamed_start(start_ns, mark, method)
        with self._lock:
            self._goals[streamed] = handle
        return streamed, plan_time, traj

    def retarget(self, method: str, goal: float, duration: float, settle: float = 0.0,
                 hoist_goal: float | None = None, bridge_goal: float | None = None) -> int:
        """Send a new goal during a motion (as soon as possible, from where the motion is): the stamp the
        streamer hands the motion over at (the planner's, or the tick it delayed a late handover's change to).
        PlanError (the planner's reason) if it was refused."""
        before = set(self.sent_trajectories())
        mark = self.planner.diagnostics.mark()
        planned = threading.Event()
        others = [(name, g) for name, g in ((BRIDGE_JOINT, bridge_goal), (HOIST_JOINT, hoist_goal)) if g is not None]
        move = move_message([goal, *(g for _, g in others)], duration, [], method,
                            ['cart', *(name for name, _ in others)] if others else [])
        handle = self.planner.send_execute(method, None, goal, duration, 0, settle,
                                           feedback=lambda _: planned.set(), timeout=30.0, move=move)
        outcome = handle.get_result_async()
        self.wait_until(lambda: planned.is_set() or outcome.done(), 30.0, f'the {method} goal was never planned')
        if not planned.is_set():
            self.planner.result(handle, timeout=5.0)  # raises PlanError with the planner's reason

        def new_stamps():
            return [s for s in self.sent_trajectories() if s not in before]

        # the planner plans a handover the streamer refused (late on a busy machine) again, further ahead:
        # the goal's handover is the one the streamer took
        handover, tried = None, 0
        deadline = time.monotonic() + 10.0
        while handover is None:
            self.wait_until(lambda: len(new_stamps()) > tried, max(0.1, deadline - time.monotonic()),
                            f'the {method} handover never appeared on the trajectory topic')
            stamp = new_stamps()[tried]
            tried += 1
            try:
                handover = self.streamed_start(stamp, mark, f'the {method} handover')
            except HarnessError:
                if outcome.done() or time.monotonic() > deadline:
                    raise
        with self._lock:
            self._goals[handover] = handle
        return handover

    def cancel(self, start_ns: int, timeout: float = 30.0):
        """Cancel the goal whose motion started at ``start_ns`` and wait for its end: (status, result)."""
        with self._lock:
            handle = self._goals.pop(start_ns)
        self._wait(handle.cancel_goal_async(), 5.0, 'the cancel')
        response = self._wait(handle.get_result_async(), timeout, 'the canceled goal\'s result')
        return response.status, response.result

    def outcome(self, start_ns: int, timeout: float = 30.0):
        """(status, result) of the goal whose motion started at ``start_ns``, whatever its outcome."""
        with self._lock:
            handle = self._goals.pop(start_ns)
        response = self._wait(handle.get_result_async(), timeout, 'the goal\'s result')
        return response.status, response.result

    def run_tool(self, executable: str, *args: str):
        """A command-line tool (``crane-teleop``, say) on this graph, running (``NodeGroup.run_tool``)."""
        return self.nodes.run_tool(executable, *args)

    def call_streamer(self, name: str):
        """Call the streamer's ``~/start`` or ``~/stop``: its response (success, message)."""
        return self._wait(self._streamer_services[name].call_async(Trigger.Request()), 5.0,
                          f'streamer {name} service')

    def push_sim(self):
        """Set the load swinging (the sim's ``~/push``, ``push_swing`` m aside)."""
        response = self._wait(self._push.call_async(Trigger.Request()), 5.0, 'sim push service')
        if not response.success:
            raise HarnessError(f'sim push failed: {response.message}')

    def settle(self) -> tuple[int, str]:
        """Call the planner's ``~/settle``: (the settle motion's stamp, the planner's message); HarnessError
        with the planner's reason if refused."""
        before = set(self.sent_trajectories())
        response = self._wait(self._settle.call_async(Trigger.Request()), 5.0, 'planner settle service')
        if not response.success:
            raise HarnessError(f'settle refused: {response.message}')
        self.wait_until(lambda: any(s not in before for s in self.sent_trajectories()), 5.0,
                        'the settle motion never appeared on the trajectory topic')
        return [s for s in self.sent_trajectories() if s not in before][-1], response.message

    def goal(self, start_ns: int):
        """The ExecuteMove goal handle of the move that started at ``start_ns`` (to cancel it, say)."""
        with self._lock:
            return self._goals[start_ns]

    def move_result(self, start_ns: int, timeout: float = 30.0):
        """The ExecuteMove result of the move that started at ``start_ns`` (as :meth:`move` returned it), also
        one aborted only because the load still swung over the planner's residual_tolerance (its
        ``success`` false, its ``residual_swing`` measured): what the harness measures. PlanError otherwise."""
        from crane_msgs_py.crane.errors import PlanError
        from crane_msgs_py.messages.names import STILL_SWINGING
        with self._lock:
            handle = self._goals.pop(start_ns)
        try:
            return self.planner.result(handle, timeout)
        except PlanError as exc:
            if STILL_SWINGING not in str(exc):
                raise
            return exc.result

    def send(self, samples, start: float, what: str = 'the test') -> int:
        """Stream a trajectory of one's own (``plan.Samples``, relative) from ``start`` m, :meth:`lead` from now.

        Published on ``trajectory`` as the planner's ``~/execute_move`` does: for a
        test move no method plans, such as a commissioning excitation. The
        stamp the motion starts at.
        """
        start_ns = self.now_ns() + round(self.lead() * 1e9)
        mark = self.planner.diagnostics.mark()
        self._trajectory_pub.publish(samples_to_joint_trajectory(samples, start, start_ns))
        return self.streamed_start(start_ns, mark, what)

    def sent_trajectories(self) -> list[int]:
        """Start stamps (ns) of every trajectory seen on the ``trajectory`` topic, in order."""
        with self._lock:
            return list(self._trajectories)

    def trajectory(self, start_ns: int, what: str = 'the', timeout: float = 5.0):
        """The JointTrajectory the planner published for a motion stamped ``start_ns``, or streamed from it
        (a late one: the start :meth:`move` and :meth:`retarget` return)."""
        with self._lock:
            start_ns = self._stamps.get(start_ns, start_ns)
        self.wait_until(lambda: start_ns in self._trajectories, timeout,
                        f'{what} plan never appeared on the trajectory topic')
        with self._lock:
            return self._trajectories[start_ns]

    def streamed_start(self, start_ns: int, mark: int, what: str = 'the', timeout: float = 5.0) -> int:
        """The stamp the streamer starts the trajectory stamped ``start_ns`` at, from its status.

        A trajectory reaching the streamer after its start stamp is streamed
        whole from the next tick (never a jump): the motion, and every window
        measured after it, moves by the streamer's ``late_start``. A refused
        one is a HarnessError with the streamer's reason.
        """
        status = self.planner.diagnostics.wait_for(
            lambda s: int(status_values(s).get('start_stamp', -1)) == start_ns, timeout, after=mark,
            name=f'{STREAMER_NODE}: trajectory', hardware_id=f'{self._namespace}/{STREAMER_NODE}')
        if status is None:
            raise HarnessError(f'no word from the streamer on {what} trajectory within {timeout:g} s')
        if level_of(status) != OK:
            raise HarnessError(f'the streamer refused {what} trajectory: {status.message}')
        late = float(status_values(status)['late_start'])
        if late > 0.0:
            self._log(f'{what} trajectory reached the streamer late: motion starts {late:.3f} s after its stamp')
            with self._lock:
                self._stamps[start_ns + round(late * 1e9)] = start_ns
        return start_ns + round(late * 1e9)

    def wait_for_state_after(self, stamp_ns: int, timeout: float = 3.0):
        """Wait until a joint_state stamped after ``stamp_ns`` has arrived.

        The sim stamps states with simulated time, which trails the wall clock
        (it plays references out by their stamps, after a jitter buffer).
        """
        def arrived():
            with self._lock:
                return bool(self._states) and self._states[-1][0] >= stamp_ns
        self.wait_until(arrived, timeout, f'no joint_states stamped past the motion within {timeout:g} s', 0.02)

    def last_state(self) -> tuple | None:
        """The newest joint_states row (``STATE_COLUMNS``), None
        before any."""
        with self._lock:
            return self._states[-1] if self._states else None

    def states_between(self, begin_ns: int, end_ns: int, timeout: float = 3.0) -> np.ndarray:
        """joint_states stamped in [begin, end] (dropping everything older than ``end_ns``): rows of
        ``STATE_COLUMNS`` (``state_columns`` names them)."""
        rows = self._rows_between(begin_ns, end_ns, timeout)
        with self._lock:
            self._states = [r for r in self._states if r[0] > end_ns]
        return rows

    def _rows_between(self, begin_ns: int, end_ns: int, timeout: float) -> np.ndarray:
        """joint_states stamped in [begin, end], once one after ``end_ns`` has come; none dropped."""
        self.wait_for_state_after(end_ns, timeout)
        with self._lock:
            rows = [r for r in self._states if begin_ns <= r[0] <= end_ns]
        return np.array(rows).reshape(-1, len(STATE_COLUMNS))

    def close(self):
        self.keep_references(False)
        for spun in self._spinnings:  # the spin thread out of rcl, then the executor shut down
            spun.__exit__(None, None, None)
        self._inputs.destroy_node()
        self.node.destroy_node()
        if self._owns_context:
            rclpy.try_shutdown()
