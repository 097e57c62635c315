"""Planner node: ``~/plan_move`` (a preview) and ``~/execute_move`` (an action) for every method
(contract: ROS 2 nodes, planner; interfaces in ``crane_interfaces``).

``~/plan_move`` (``crane_interfaces/srv/PlanMove``) computes and answers: the
plan's knots as a ``JointTrajectory`` and its ``PlanInfo``; it moves nothing.
A refusal is ``success: false`` with the reason, naming the field and the
bound (``serving.moves``). ``~/execute_move``
(``crane_interfaces/action/ExecuteMove``) accepts every goal, plans it (a
refused plan aborts the goal with the reason), holds the trajectory until
``publish_lead`` before its start (so a goal canceled before then streams
nothing), sends it to the streamer on ``trajectory``, and follows it
(``serving.execution``): feedback at 20 Hz with the progress by the
streamer's clock (``stream_state``) and the swing from ``joint_states``, the
result once the settle window after the end has been observed. Every request
gets one status on ``/diagnostics``. Requests run concurrently
(MultiThreadedExecutor, one reentrant group); NVF/RVF solves run in the
serving facade's worker processes (``solver_processes``), each bounded by
``max_solve_time``, so none waits behind another.
"""
from __future__ import annotations

import contextlib
import math
import threading
import time
from dataclasses import dataclass

import numpy as np
import rclpy
from crane_interfaces.action import ExecuteMove
from crane_interfaces.msg import Move as MoveMessage
from crane_interfaces.msg import PlanInfo, StreamState
from crane_interfaces.srv import PlanMove
from rclpy.action import CancelResponse, GoalResponse
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.executors import MultiThreadedExecutor, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.serialization import serialize_message
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory

from crane_msgs_py.action_server import ActionServer
from crane_msgs_py.conversions import (
    OPERATOR,
    joint_state_to_arrays,
    joint_trajectory_to_arrays,
    read_stream_state,
    samples_to_joint_trajectory,
    stamp_ns,
)
from crane_msgs_py.diagnostics import ERROR, OK, WARN, DiagnosticsPublisher
from crane_msgs_py.names import (
    CART_JOINT,
    DEFAULT_FRAME_ID,
    EXECUTE_MOVE_ACTION,
    HOIST_JOINT,
    JOINT_STATES_TOPIC,
    PLAN_MOVE_SERVICE,
    PLANNER_NODE,
    SETTLE_SERVICE,
    SIM_JOINTS,
    STREAM_STATE_TOPIC,
    TRAJECTORY_TOPIC,
    check_joints,
)
from crane_msgs_py.node_parameters import Guard, declare, float_range, int_range
from crane_msgs_py.params import (
    PARAMETER_DESCRIPTIONS,
    PARAMETER_NAMES,
    CraneParams,
    ParameterError,
    check_choice,
    check_nonnegative,
    check_positive,
)
from crane_msgs_py.qos import JOINT_STATES_QOS, PLAN_MOVE_QOS, STREAM_STATE_QOS, TRAJECTORY_QOS
from crane_msgs_py.realtime import fix_mmap_threshold, set_threads_fifo
from crane_msgs_py.runner import run, spinning
from crane_planner.planning import METHODS, ROBUST_PARAMETERS, SHAPER_METHODS, VARIATIONAL_METHODS, PlanOptions
from crane_planner.planning.continuation import MotionState, problem_start
from crane_planner.planning.dispatch import VariationalRequest, hoisting_options
from crane_planner.planning.hoisting import HOIST_SHAPER_DESIGNS
from crane_planner.planning.plan import time_grid
from crane_planner.planning.profiles import BASES
from crane_planner.serving import Planner, transitions
from crane_planner.serving.execution import DONE, FAILED, MOVING, WAITING, Execution
from crane_planner.serving.moves import (
    CheckedMove,
    Move,
    MoveBounds,
    MoveError,
    axis_samples,
    check_move,
    plan_move,
    summarize,
)
from crane_planner.serving.transitions import Measurement, Running
from crane_planner.streaming.knots import knot_times
from crane_planner.streaming.reference_stream import MAX_HANDOVER_SHIFT

#: The planner's per-request diagnostic task (status ``<planner>: plan``), and the executions'.
PLAN_TASK = 'plan'
EXECUTE_TASK = 'execute'
#: Settle window (s) of a goal that gives none (``settle`` 0).
DEFAULT_SETTLE = 2.0
#: How fresh (s) the last ``stream_state`` must be for the streamer to count as heard.
STREAM_FRESH = 1.0
#: Feedback period (s): 20 Hz, above the contract's 10 Hz.
FEEDBACK_PERIOD = 0.05
#: A handover's trajectory must be sent at least this long (s) before the handover, for its transport to
#: the streamer and the streamer's check (1-3 ms on a busy two-core machine); one that arrives late all the
#: same is refused by the streamer and planned again further ahead (``_take_over``).
TRANSPORT_MARGIN = 0.008
#: Attempts at a handover whose plan took longer than its lead (the lead doubles each time).
HANDOVER_ATTEMPTS = 3
#: A goal registered on arrival (``_on_goal``) but not accepted this long after (s) is forgotten.
UNACCEPTED_AFTER = 10.0
#: The lead (s) of a stop's handover: a stop is planned once, from further ahead.
STOP_LEAD = 0.1

#: name -> (default, description, range descriptor fields). Ranges are the
#: outer bounds rclpy enforces; the exact domain (e.g. > 0) is checked by the
#: node, which names the reason and reports it on /diagnostics.
PARAMETERS = {
    'L1': (CraneParams.L1, PARAMETER_DESCRIPTIONS['L1'], float_range(0.0, 100.0)),
    'L2': (CraneParams.L2, PARAMETER_DESCRIPTIONS['L2'], float_range(0.0, 100.0)),
    'm1': (CraneParams.m1, PARAMETER_DESCRIPTIONS['m1'], float_range(0.0, 1e5)),
    'm2': (CraneParams.m2, PARAMETER_DESCRIPTIONS['m2'], float_range(0.0, 1e5)),
    'g': (CraneParams.g, PARAMETER_DESCRIPTIONS['g'], float_range(0.0, 100.0)),
    'tau': (CraneParams.tau, PARAMETER_DESCRIPTIONS['tau'], float_range(0.0, 10.0)),
    'c1': (CraneParams.c1, PARAMETER_DESCRIPTIONS['c1'], float_range(0.0, 1e3)),
    'c2': (CraneParams.c2, PARAMETER_DESCRIPTIONS['c2'], float_range(0.0, 1e3)),
    'tau_hoist': (CraneParams.tau_hoist, PARAMETER_DESCRIPTIONS['tau_hoist'], float_range(0.0, 10.0)),
    'method': ('rvf', f'method of a move that names none: one of {", ".join(METHODS)}',
               {'additional_constraints': f'one of {", ".join(METHODS)}'}),
    'robust_parameters': (['L1'], f'parameters RVF is made insensitive to, among {", ".join(ROBUST_PARAMETERS)}',
                          {'additional_constraints': f'distinct names among {", ".join(ROBUST_PARAMETERS)}'}),
    'shaper_frequencies': ([], 'shaper design frequencies (rad/s), one per mode; empty = the linearized '
                               "model's modal frequencies", {'additional_constraints': 'each > 0'}),
    'shaper_damping': (-1.0, "shaper design damping ratio, >= 0 and < 1; -1 = the model's modal damping "
                             'ratios (0 when c1 = c2 = 0; 0 with shaper_frequencies set)',
                       float_range(-1.0, 1.0)),
    'intervals': (0, 'collocation intervals of NVF/RVF, 4..2000; 0 = the solver default',
                  int_range(0, 2000)),
    'sample_period': (0.0, 'knot spacing of returned plans (s); 0 = knots where the plan needs them '
                           '(its breakpoints, and as few more as keep the streamer\'s quintic Hermite '
                           'interpolation within 1 um); the last knot is exactly at the end',
                      float_range(0.0, 1.0)),
    'frame_id': (DEFAULT_FRAME_ID, 'frame of returned trajectories', {}),
    'joints': (['cart'], "the actuated joints this planner serves: [cart], or [cart, hoist] (the hoist's "
                         "position is the upper cable's length L1; every array of a Move is per joint in this "
                         'order); fixed at start-up',
               {'additional_constraints': '[cart] or [cart, hoist]', 'read_only': True}),
    'publish_lead': (0.3, 'an executed trajectory is sent to the streamer this long (s) before its start '
                          'time, so that a goal canceled before then streams nothing (one starting as '
                          'soon as possible is sent at once)', float_range(0.0, 10.0)),
    'max_duration': (60.0, 'longest motion served (s), > 0', float_range(0.0, 3600.0)),
    'max_displacement': (10.0, 'largest |goal - start| served (m), > 0',
                         float_range(0.0, 1e4)),
    'max_velocity': (0.0, 'axis limit |v| of the reference (m/s); 0 = no limit',
                     float_range(0.0, 1e3)),
    'max_acceleration': (0.0, 'axis limit |a| of the reference (m/s^2); 0 = no limit',
                         float_range(0.0, 1e4)),
    'max_jerk': (0.0, 'axis limit on the jerk of the reference (m/s^3); 0 = no limit',
                 float_range(0.0, 1e6)),
    'max_hoist_velocity': (0.0, 'hoist axis limit |v| of its reference (m/s); 0 = no limit', float_range(0.0, 1e3)),
    'max_hoist_acceleration': (0.0, 'hoist axis limit |a| of its reference (m/s^2); 0 = no limit',
                               float_range(0.0, 1e4)),
    'max_hoist_jerk': (0.0, 'hoist axis limit on the jerk of its reference (m/s^3); 0 = no limit',
                       float_range(0.0, 1e6)),
    'hoist_robust_parameters': (['L2'], 'parameters RVF is made insensitive to in a move that hoists (the '
                                        f'payload\'s cable by default), among {", ".join(ROBUST_PARAMETERS)}',
                                {'additional_constraints': f'distinct names among {", ".join(ROBUST_PARAMETERS)}'}),
    'hoist_shaper': ('adaptive', 'how a shaper follows the rope length in a move that hoists: adaptive (fitted '
                                 'to the hoisting crane) or designed at the start, middle or end length',
                     {'additional_constraints': f'one of {", ".join(HOIST_SHAPER_DESIGNS)}'}),
    'shaper_base': ('quintic', "the motion shapers shape: 'quintic' (the paper's) or 'limits' (the jerk-limited "
                               'time-optimal profile under the axis limits; needs max_velocity or max_acceleration)',
                    {'additional_constraints': f'one of {", ".join(BASES)}'}),
    'handover_lead': (0.042, 'a new NVF/RVF goal during a motion takes over this long (s) after it arrives, from '
                            'the state the motion is in then (a plan taking longer is planned again further ahead)',
                      float_range(0.001, 1.0)),
    'shaper_handover_lead': (0.001, 'the same for a shaper; shorter than its planning and transport on purpose: '
                                    'a change reaching the streamer after its tick starts at the next one, '
                                    'delayed (up to 20 ms, no swing added): the earliest handover possible',
                             float_range(0.001, 1.0)),
    'handover_priority': (40, 'SCHED_FIFO priority (1..99) of the thread that takes ExecuteMove requests and plans '
                              'and sends a shaper\'s handover: 1-2 ms of Python that, at normal priority beside the '
                              '1 kHz nodes, waits as long again for a core; the middleware\'s receive threads run one '
                              'below; 0 = normal scheduling (also without the privilege: a warning)',
                          int_range(0, 99)),
    'handover_warmup': (0.02, 'while a motion streams, every this many s the goals\' thread plans a shaper\'s '
                              'handover of it and serializes its trajectory without sending it (0.5-1 ms each), so '
                              'that a real goal\'s handover runs on warm caches: after 50-250 ms untouched the same '
                              'Python took 3-22 times as long on a shared host; 0 = off',
                        float_range(0.0, 10.0)),
    'settle_method': ('nvf', '~/settle plans with this method: nvf or rvf (a shaper cannot damp a swing it did not '
                             'cause)', {'additional_constraints': 'nvf or rvf'}),
    'max_solve_time': (1.0, 'budget of one NVF/RVF solve (s), > 0: a request not solved within it is '
                            'refused; every request is answered within this + 0.5 s',
                       float_range(0.0, 60.0)),
    'solver_pool_size': (8, 'NVF/RVF solver instances per method in the node process, 1..32, made as '
                            'concurrent requests need them (2-6 MB each; the first of a method builds its NLP, '
                            '~25 MB); they serve every NVF/RVF request when solver_processes is 0, else those '
                            'finding every worker process busy', int_range(1, 32)),
    'solver_processes': (3, 'worker processes solving NVF/RVF side by side, 0..16, started with the node '
                            '(~40 MB each beyond what they share); 0 = solve in threads of the node process '
                            "only, where solves take turns at IPOPT's linear solver (read-only)",
                         dict(int_range(0, 16), read_only=True)),
}


@dataclass(frozen=True)
class Config:
    """One consistent set of the node's parameters, validated; swapped whole on a change."""

    params: CraneParams
    options: PlanOptions
    method: str
    sample_period: float
    frame_id: str
    max_duration: float
    max_displacement: float
    solver_pool_size: int
    solver_processes: int
    joints: tuple
    publish_lead: float
    handover_lead: float = 0.042
    shaper_handover_lead: float = 0.001
    settle_method: str = 'nvf'
    handover_priority: int = 40
    handover_warmup: float = 0.02

    @property
    def bounds(self) -> MoveBounds:
        return MoveBounds(self.joints, self.method, self.max_displacement, self.max_duration)

    @classmethod
    def from_values(cls, v: dict) -> 'Config':
        """From parameter values by name; ParameterError names the bad one."""
        params = CraneParams(**{name: v[name] for name in PARAMETER_NAMES})
        check_choice('method', v['method'], METHODS)
        intervals = int(v['intervals'])
        options = PlanOptions(
            omega=tuple(v['shaper_frequencies']) or None,
            damping=None if v['shaper_damping'] == -1.0 else v['shaper_damping'],
            robust=tuple(v['robust_parameters']), intervals=intervals or None,
            max_velocity=v['max_velocity'] or None, max_acceleration=v['max_acceleration'] or None,
            max_jerk=v['max_jerk'] or None, base=v['shaper_base'],
            max_solve_time=check_positive('max_solve_time', v['max_solve_time']),
            max_hoist_velocity=v['max_hoist_velocity'] or None,
            max_hoist_acceleration=v['max_hoist_acceleration'] or None,
            max_hoist_jerk=v['max_hoist_jerk'] or None, hoist_robust=tuple(v['hoist_robust_parameters']),
            hoist_shaper=v['hoist_shaper'])
        if not v['frame_id']:
            raise ParameterError('frame_id must not be empty')
        joints = check_joints(v['joints'])
        check_choice('settle_method', v['settle_method'], VARIATIONAL_METHODS)
        return cls(params, options, v['method'], check_nonnegative('sample_period', v['sample_period']),
                   v['frame_id'], check_positive('max_duration', v['max_duration']),
                   check_positive('max_displacement', v['max_displacement']), int(v['solver_pool_size']),
                   int(v['solver_processes']), joints, check_nonnegative('publish_lead', v['publish_lead']),
                   check_positive('handover_lead', v['handover_lead']),
                   check_positive('shaper_handover_lead', v['shaper_handover_lead']), v['settle_method'],
                   int(v['handover_priority']), check_nonnegative('handover_warmup', v['handover_warmup']))

    def warmups(self) -> list[VariationalRequest]:
        """Requests that build the NVF/RVF solvers of this configuration.

        A typical move, and with velocity or acceleration limits its fastest
        plan (the free-final-time NLP), so the first of either is answered warm.
        """
        D, duration = min(0.3, self.max_displacement), min(3.0, self.max_duration)
        requests = [VariationalRequest('plan', method, D, duration, self.params, self.options)
                    for method in VARIATIONAL_METHODS]
        if self.options.max_velocity is not None or self.options.max_acceleration is not None:
            requests += [VariationalRequest('fastest', method, D, None, self.params, self.options)
                         for method in VARIATIONAL_METHODS]
        if HOIST_JOINT in self.joints:  # and a move that hoists by a tenth of the rope (another NLP)
            hoisting = hoisting_options(self.options)
            requests += [VariationalRequest('plan', method, (D, -0.1 * self.params.L1), duration, self.params,
                                            hoisting) for method in VARIATIONAL_METHODS]
        # and a plan from a moving, swinging state (a new goal mid-move) and a stop: their own warm starts
        state = MotionState((0.0, 0.1, 0.05), (0.02, 0.0, -0.05, 0.0),
                            hoist=(self.params.L1, 0.0, 0.0) if HOIST_JOINT in self.joints else None)
        start, model = problem_start(state, self.params)
        options = hoisting_options(self.options) if state.hoist else self.options
        for free_end in (False, True):
            displacement = (D, 0.0) if state.hoist else D
            requests += [VariationalRequest('plan', method, displacement, duration, model, options, start, free_end)
                         for method in VARIATIONAL_METHODS]
        return requests


class PlannerNode(Node):
    """The ``crane_planner`` node."""

    def __init__(self, **kwargs):
        super().__init__(PLANNER_NODE, **kwargs)
        warning = fix_mmap_threshold()  # before any solver allocates: keeps the node's size flat
        if warning:
            self.get_logger().warn(warning)
        values = declare(self, PARAMETERS)
        self._diagnostics = DiagnosticsPublisher(self)
        self._config = Config.from_values(values)  # bad overrides: ParameterError, see main()
        Guard(self, PARAMETERS, Config.from_values, self._apply, self._diagnostics)
        self._planner = Planner(self._config.solver_pool_size, processes=self._config.solver_processes)
        self._planner.warmups = self._config.warmups()
        if self._config.solver_processes:
            # before the services exist, so no request finds no worker; the others start meanwhile
            t0 = time.perf_counter()
            if self._planner.start_processes(ready_within=60.0):
                self.get_logger().info(f'first of {self._config.solver_processes} solver processes ready '
                                       f'in {time.perf_counter() - t0:.2f} s')
            else:
                self.get_logger().error('no solver process started within 60 s; NVF/RVF requests will be refused')
        self._trajectory = self.create_publisher(JointTrajectory, TRAJECTORY_TOPIC, TRAJECTORY_QOS)
        # what the streamer holds and streams, and the measured swing: read on a group of their own
        self._lock = threading.Lock()
        self._stream: tuple | None = None  # (ROS time received ns, read_stream_state(...))
        self._goals: list[_Goal] = []  # goals being executed: planned, streaming or settling
        self._measured: Measurement | None = None  # the newest joint_states
        self._running: Running | None = None  # the last motion sent to the streamer (a goal's or a settle's)
        self._handing_over = threading.Lock()  # one handover (goal, stop, settle) planned at a time
        # The two 50 Hz inputs go to a node of their own on a SingleThreadedExecutor thread: through the
        # services' MultiThreadedExecutor their 100 messages a second kept the node at a whole core (4 %
        # this way). Not the EventsExecutor: after 900 previews it ran the inputs about once a second
        # (1 run in 4), and goals then found no stream_state.
        self._inputs = rclpy.create_node(f'{self.get_name()}_inputs', namespace=self.get_namespace(),
                                         start_parameter_services=False)
        self._inputs.create_subscription(StreamState, STREAM_STATE_TOPIC, self._on_stream_state, STREAM_STATE_QOS)
        self._inputs.create_subscription(JointState, JOINT_STATES_TOPIC, self._on_joint_state, JOINT_STATES_QOS)
        inputs_executor = SingleThreadedExecutor()
        inputs_executor.add_node(self._inputs)
        self._inputs_spinning = spinning(inputs_executor)
        self._inputs_spinning.__enter__()
        group = ReentrantCallbackGroup()
        self.create_service(PlanMove, PLAN_MOVE_SERVICE, self._on_plan_move, qos_profile=PLAN_MOVE_QOS,
                            callback_group=group)
        self._arriving: dict = {}  # id(goal request): (_Goal, perf_counter at arrival) until accepted
        self._action = ActionServer(self, ExecuteMove, EXECUTE_MOVE_ACTION, self._execute, goal_callback=self._on_goal,
                                    handle_accepted_callback=self._on_accepted, cancel_callback=self._on_cancel,
                                    callback_group=group)
        # The action's requests (goal, cancel, result) are waited for on a thread of their own: through the
        # MultiThreadedExecutor a goal reached its callback 2-4 ms after it arrived (its wait set rebuilt
        # for every entity, the handler handed to a pool thread), the whole of a shaper's handover budget.
        # The server stays the planner's (its rcl handle is this node's: `ros2 action info` names it); only
        # the waiting moves, to a node without entities of its own. Every callback there returns at once or
        # within a shaper's handover (_on_goal), and the goals still execute on this node's executor.
        self._goals_node = rclpy.create_node(f'{self.get_name()}_goals', namespace=self.get_namespace(),
                                             start_parameter_services=False)
        self.remove_waitable(self._action)
        self._goals_node.add_waitable(self._action)
        goals_executor = SingleThreadedExecutor()
        goals_executor.add_node(self._goals_node)
        # the same thread keeps a shaper's handover warm while a motion streams (_warm_handover)
        self._warm_timer = self._goals_node.create_timer(self._config.handover_warmup or 1.0, self._warm_handover)
        if not self._config.handover_warmup:
            self._warm_timer.cancel()
        # at handover_priority: that thread is a shaper's handover from the goal's arrival to its trajectory
        # sent, and at normal priority beside the 1 kHz nodes it waits for a core as long again as it works
        self._goals_spinning = spinning(goals_executor, priority=lambda: self._config.handover_priority,
                                        refused=self._priority_refused)
        self._goals_spinning.__enter__()
        self._prioritize_receiving(self._config.handover_priority)
        self.create_service(Trigger, SETTLE_SERVICE, self._on_settle, callback_group=group)
        self.get_logger().info(f'serving {", ".join(METHODS)} on {self.get_fully_qualified_name()}/plan_move '
                               '(PlanMove: a preview) and .../execute_move (ExecuteMove: plan, stream, settle)')
        self._warmup = threading.Thread(target=self._build_solvers, name='solver-warmup', daemon=True)
        self._warmup.start()

    def _apply(self, config: Config, values, changes):
        if config.handover_priority != self._config.handover_priority:
            self._prioritize_receiving(config.handover_priority)
        if config.handover_warmup != self._config.handover_warmup:
            if config.handover_warmup:
                self._warm_timer.timer_period_ns = round(config.handover_warmup * 1e9)
                self._warm_timer.reset()
            else:
                self._warm_timer.cancel()
        self._planner.pool_size = config.solver_pool_size
        self._planner.warmups = config.warmups()  # what a replaced worker builds first
        self._config = config  # applies to the next request

    def executor_threads(self) -> int:
        """Enough executor threads for every solver busy at once, plus the shapers' and parameter requests,
        the goals being executed (each holds a thread until its result: one moving, one settling) and
        the stream_state / joint_states callbacks."""
        config = self._config
        return config.solver_processes + config.solver_pool_size * len(VARIATIONAL_METHODS) + 4 + 2 + 1

    # -- requests ---------------------------------------------------------

    def _build_solvers(self):
        """Build every method once with the start-up configuration, so first requests are warm.

        Reported on /diagnostics (task ``solvers``) when done, with the time each took.
        """
        config = self._config
        times, failed = {}, {}
        t_all = time.perf_counter()
        # every worker up before the node says it is ready: one still building takes a core
        if config.solver_processes and not self._planner.start_processes(120.0, all_of_them=True):
            self.get_logger().warn('not every solver process started within 120 s')
        if config.solver_processes:  # the node's own solvers, for requests finding every worker busy
            try:
                self._planner.warm_threads(config.warmups())
            except Exception as exc:
                self.get_logger().warn(f'building the in-node NVF/RVF solvers failed: {exc}')
        for method in METHODS:
            # long enough for every shaper; the variational solvers at a typical request
            duration = min(3.0 if method in VARIATIONAL_METHODS else 10.0, config.max_duration)
            t0 = time.perf_counter()
            try:
                plan = self._planner.plan(method, min(0.3, config.max_displacement), duration,
                                          config.params, config.options)
            except Exception as exc:  # a warm-up failure only means building on first use
                failed[method] = str(exc)
                self.get_logger().warn(f'{method} warm-up failed: {exc}')
                continue
            times[method] = time.perf_counter() - t0
            build = plan.info.get('build_time_s')
            self.get_logger().info(f'{method} ready in {times[method]:.2f} s'
                                   + (f' (solver built in {build:.2f} s)' if build else ''))
        # the handover's predictor (a CasADi function built on first use)
        holding = Running.holding(config.joints, [0.0, config.params.L1][:len(config.joints)], 0)
        measured = Measurement(0, (0.0, 0.0), (0.0, 0.0, 0.0, 0.0), (config.params.L1, 0.0) if len(config.joints) > 1
                               else None)
        transitions.handover_state(holding, 10_000_000, measured, config.params)
        message = f'{len(times)} of {len(METHODS)} methods ready in {time.perf_counter() - t_all:.2f} s'
        self._diagnostics.report('solvers', WARN if failed else OK, message,
                                 **{f'{m}_s': v for m, v in times.items()},
                                 **{f'{m}_error': e for m, e in failed.items()})

    # -- what the streamer and the crane say (their own callback group) -----------------

    def _on_stream_state(self, msg: StreamState):
        state = read_stream_state(msg)
        with self._lock:
            self._stream = (self.get_clock().now().nanoseconds, state)
            executions = [g.execution for g in self._goals if g.execution is not None]
        stamp, _, _, motion_start, motion_duration, motion_origin = state
        for execution in executions:
            execution.on_stream_state(stamp, motion_start, motion_duration, motion_origin)

    def _on_joint_state(self, msg: JointState):
        try:
            position, velocity = joint_state_to_arrays(msg, SIM_JOINTS)
        except ValueError:  # not the crane's joints: nothing to measure the swing with
            return
        length = hoist = None  # with a hoist, the rope length measured with the angles
        if HOIST_JOINT in msg.name:
            k = list(msg.name).index(HOIST_JOINT)
            length = float(msg.position[k])
            hoist = (length, float(msg.velocity[k]) if len(msg.velocity) > k else 0.0)
        stamp = stamp_ns(msg.header.stamp)
        velocity = [0.0 if math.isnan(v) else float(v) for v in velocity]
        measured = Measurement(stamp, (float(position[0]), velocity[0]),
                               (float(position[1]), float(position[2]), velocity[1], velocity[2]), hoist)
        with self._lock:
            self._measured = measured  # what a handover predicts the swing from
            executions = [g.execution for g in self._goals if g.execution is not None]
        for execution in executions:
            execution.on_joint_state(stamp, position[1], position[2], length)

    def _heard(self) -> tuple | None:
        """The streamer's newest state (``read_stream_state``) if it was heard within ``STREAM_FRESH`` s."""
        with self._lock:
            stream = self._stream
        if stream is None or self.get_clock().now().nanoseconds - stream[0] > STREAM_FRESH * 1e9:
            return None
        return stream[1]

    def _hold(self) -> dict | None:
        """Where the streamer holds each joint (m), if it was heard within ``STREAM_FRESH`` s."""
        heard = self._heard()
        return None if heard is None else heard[2]

    # -- planning (PlanMove, and each ExecuteMove goal) --------------------------------

    def _plan(self, move_msg, service: str, execute: bool = False):
        """(checked move, plan, knot samples, status values); MoveError/ValueError says why not."""
        config = self._config
        move = Move(move_msg.method, tuple(move_msg.joint_names), tuple(move_msg.start), tuple(move_msg.goal),
                    move_msg.duration, stamp_ns(move_msg.start_time))
        values = {'service': service, 'method': move.method or config.method,
                  'start': move.start[0] if move.start else math.nan,
                  'goal': move.goal[0] if move.goal else math.nan, 'duration': move.duration}
        hold = self._hold()
        try:
            checked = check_move(move, config.bounds, hold, config.params.L1)
            values.update(method=checked.method, start=checked.start, goal=checked.goal,
                          displacement=checked.displacement)
            if checked.hoist_start is not None:
                values.update(hoist_start=checked.hoist_start, hoist_goal=checked.hoist_goal)
            plan = plan_move(self._planner, checked, config.bounds, config.params, config.options)
            if execute:  # after planning: a preview and a goal of the same bad move give the same reason
                heard = self._heard()
                self._check_executable(checked, hold, heard is not None and heard[1] == OPERATOR)
        except ValueError as exc:
            exc.values = values
            raise
        times = self._knot_times(plan, config)
        values['duration'] = plan.duration
        return checked, plan, axis_samples(plan, times), values

    @staticmethod
    def _check_executable(move: CheckedMove, hold: dict | None, operator: bool = False):
        """What the streamer would refuse, refused before anything is sent."""
        if hold is None:
            raise MoveError('goal', f'no streamer heard on {STREAM_STATE_TOPIC} within {STREAM_FRESH:g} s: nothing '
                                    'would stream the motion (is crane_streamer running and started?)')
        if operator:
            raise MoveError('goal', 'the streamer is in operator mode (it follows cmd_vel): set its mode to '
                                    'trajectory, at rest, to execute moves')
        for joint, start in zip(move.joints, move.starts):
            if joint not in hold:
                raise MoveError('joint_names', f'the streamer does not stream {joint} (it streams '
                                               f'{", ".join(hold)}): start it with joints {list(move.joints)}')
            if abs(start - hold[joint]) > 1e-6:
                raise MoveError('start', f'{start:.6g} m is not where the streamer holds the {joint} '
                                         f'({hold[joint]:.6g} m); leave start empty to start there')

    def _info(self, plan, checked: CheckedMove, planning_time: float) -> PlanInfo:
        summary = summarize(plan, checked.joints, plan.info.get('solve_time_s', planning_time))
        info = PlanInfo()
        info.method, info.duration, info.solve_time = summary.method, summary.duration, summary.solve_time
        info.iterations, info.joint_names = summary.iterations, list(summary.joint_names)
        info.peak_velocity, info.peak_acceleration = list(summary.peak_velocity), list(summary.peak_acceleration)
        info.peak_jerk, info.predicted_residual = list(summary.peak_jerk), summary.predicted_residual
        return info

    def _trajectory_of(self, checked: CheckedMove, samples: list) -> JointTrajectory:
        """The trajectory of every joint the plan moves or holds (``axis_samples``: one Samples per joint)."""
        return samples_to_joint_trajectory(samples, checked.starts, checked.start_ns, self._config.frame_id,
                                           joint=list(checked.joints))

    def _report_plan(self, values: dict, plan, knots: int, t0: float, solved: float, error: str = ''):
        """One /diagnostics status per request: the plan's facts, or the reason it was refused."""
        now = time.perf_counter()
        if error:
            self.get_logger().error(f'{values["service"]} {values["method"]} refused: {error}')
            self._diagnostics.report(PLAN_TASK, ERROR, error, **values, solve_time=0.0, plan_time=now - t0,
                                     iterations=0, knots=0, error=error)
            return
        info = plan.info
        self._diagnostics.report(
            PLAN_TASK, OK, f'{values["method"]}: {knots} knots in {plan.duration:.4f} s', **values,
            solve_time=info.get('solve_time_s', solved - t0), build_time=info.get('build_time_s', 0.0),
            iterations=info.get('iterations', 0), plan_time=solved - t0, message_time=now - solved,
            knots=knots, error='')

    def _on_plan_move(self, request, response):
        t0 = time.perf_counter()
        try:
            checked, plan, samples, values = self._plan(request.move, 'plan_move')
        except ValueError as exc:  # MoveError, PlanError, ParameterError: the request cannot be served
            return self._refuse(response, str(exc), getattr(exc, 'values', {}), t0)
        except Exception as exc:  # a solver bug must not kill the node or leave the caller waiting
            return self._refuse(response, f'internal error: {type(exc).__name__}: {exc}', {}, t0)
        solved = time.perf_counter()
        response.success, response.message = True, ''
        response.trajectory = self._trajectory_of(checked, samples)
        response.info = self._info(plan, checked, solved - t0)
        self._report_plan(values, plan, len(samples[0].t), t0, solved)
        return response

    def _refuse(self, response, reason: str, values: dict, t0: float):
        response.success, response.message = False, reason
        response.trajectory.header.frame_id = self._config.frame_id
        values = {'service': 'plan_move', 'method': '', **values}
        self._report_plan(values, None, 0, t0, t0, error=reason)
        return response

    # -- execution (ExecuteMove) ----------------------------------------------------------

    def _on_cancel(self, goal_handle) -> CancelResponse:
        """Every cancel is accepted: before the goal's trajectory is sent nothing streams; during its motion
        the goal's thread plans a stop (contract "Motion from any state"); after it the goal ends at once."""
        with self._lock:
            goal = next((g for g in self._goals if g.goal_handle is goal_handle), None)
            if goal is not None and not goal.sent:
                goal.cancel = True  # seen by _run under this lock before it sends anything
        return CancelResponse.ACCEPT

    def _on_goal(self, request) -> GoalResponse:
        """Every goal is accepted (a refusal is its result's reason) and registered here, on the goals'
        thread, and a shaper's during a motion handed over at once: before rclpy's acceptance of it (its goal
        handle, response and status, 0.3 ms of that handover's 5 ms; rclpy fails to accept a goal only on an
        internal error, which it logs), and before the executor's next pass runs ``_execute``. A
        variational one (its lead is 42 ms) plans in ``_execute``: the goals' thread never waits on a solver
        process, so a cancel or another goal is not held up behind it."""
        goal, t0, running = _Goal(None), time.perf_counter(), None
        with self._lock:
            for other in self._goals:  # one not sent yet gives way: it never streams
                if not other.sent:
                    other.cancel = other.preempted = True
            self._goals.append(goal)
        self._forget_unaccepted(t0)
        self._arriving[id(request)] = goal, t0
        try:
            running = self._in_motion()
            if running is not None and math.isfinite(request.settle) and request.settle >= 0.0:  # (else _run)
                goal.take_over = (running, t0, None)
                shaper = (request.move.method or self._config.method) not in VARIATIONAL_METHODS
                # not when planning would wait: for the running motion's start on the streamer (_origin) or
                # behind a stop or settle being planned (_handing_over)
                if shaper and running.origin_ns and not self._handing_over.locked():
                    handover = self._send_handover(goal, request, running, request.settle or DEFAULT_SETTLE)
                    goal.take_over = (running, t0, handover)
        except Exception as exc:  # raised again by _take_over: a refusal (ValueError) or a bug's
            goal.take_over = (running, t0, exc)
        return GoalResponse.ACCEPT

    def _on_accepted(self, goal_handle):
        """A goal accepted (``_on_goal`` registered it): executed (``_execute``)."""
        goal, _ = self._arriving.pop(id(goal_handle.request))
        goal.goal_handle = goal_handle
        goal_handle.execute()

    def _forget_unaccepted(self, now: float):
        """Drop goals rclpy never accepted after ``_on_goal`` (an internal error, logged by rclpy)."""
        for key, (goal, arrived) in list(self._arriving.items()):
            if now - arrived > UNACCEPTED_AFTER:
                del self._arriving[key]
                with self._lock:
                    self._goals.remove(goal)
                self.get_logger().error(f'execute_move: a goal was never accepted by the action server '
                                        f'(sent: {goal.sent}); forgotten')

    def _prioritize_receiving(self, handover_priority: int):
        """The middleware's receive threads one below the goals' thread: a goal reaches it through them, and
        at normal priority waits for a core there first (0.2-0.4 ms on a loaded machine)."""
        _, refused = set_threads_fifo(max(0, handover_priority - 1))
        if refused:
            self.get_logger().warn(f'handover_priority: the middleware\'s receive threads: {refused}')

    def _priority_refused(self, reason: str):
        self.get_logger().warn(f'handover_priority: {reason}; shapers\' handovers are planned at normal priority')

    def _execute(self, goal_handle):
        request = goal_handle.request
        result = ExecuteMove.Result()
        result.residual_swing = math.nan
        with self._lock:
            goal = next(g for g in self._goals if g.goal_handle is goal_handle)
        try:
            return self._run(goal, request, result)
        except Exception as exc:  # a bug must not leave the caller waiting forever
            self.get_logger().error(f'execute_move: unexpected {type(exc).__name__}: {exc}')
            if not goal_handle.is_active:  # it already ended: the caller has its status
                return result
            return self._end(goal_handle, result, 'abort', f'internal error: {type(exc).__name__}: {exc}')
        finally:
            with self._lock:
                self._goals.remove(goal)

    def _in_motion(self) -> Running | None:
        """The motion the streamer is streaming (or about to), if any: the last one sent, unless it has
        ended, or the streamer says it holds though the motion should have started 0.1 s ago (refused)."""
        with self._lock:
            running = self._running
        if running is None:
            return None
        # one sent to start as soon as possible (or late) has started once its goal's stream_state says so
        if running.origin_ns == 0 and not self._origin(running, wait=0.0):
            with self._lock:
                if not any(g.running is running for g in self._goals):
                    return None  # its goal ended before the streamer started it: nothing is in motion
        now = self.get_clock().now().nanoseconds
        if running.origin_ns and now >= running.end_ns:
            return None
        heard = self._heard()
        if heard is not None and heard[1] != 'streaming' and running.origin_ns and \
                heard[0] > running.origin_ns + 100_000_000:
            return None
        return running

    def _run(self, goal: '_Goal', request, result):
        goal_handle, config = goal.goal_handle, self._config
        t0 = time.perf_counter()
        if not (math.isfinite(request.settle) and request.settle >= 0.0):
            return self._end(goal_handle, result, 'abort', f'settle: must be finite and >= 0 s (0 = '
                             f'{DEFAULT_SETTLE:g} s), got {request.settle}')
        settle = request.settle or DEFAULT_SETTLE
        if goal.take_over is not None:  # a new goal during a motion: it takes over (preemption)
            running, t0, _ = goal.take_over
            return self._take_over(goal, request, result, running, settle, t0)
        try:
            checked, plan, samples, values = self._plan(request.move, 'execute_move', execute=True)
        except ValueError as exc:
            self._report_plan({'service': 'execute_move', 'method': '', **getattr(exc, 'values', {})},
                              None, 0, t0, t0, error=str(exc))
            return self._end(goal_handle, result, 'abort', str(exc))
        solved = time.perf_counter()
        self._report_plan(values, plan, len(samples[0].t), t0, solved)
        result.info = self._info(plan, checked, solved - t0)
        feedback = ExecuteMove.Feedback(progress=0.0, time_remaining=plan.duration, swing=math.nan)
        goal_handle.publish_feedback(feedback)  # planned: the caller knows at once
        # hold the trajectory until publish_lead before its start: a cancel before then streams nothing
        send_at = checked.start_ns - round(config.publish_lead * 1e9) if checked.start_ns else 0
        while self.get_clock().now().nanoseconds < send_at and not (goal.cancel or goal_handle.is_cancel_requested):
            time.sleep(min(FEEDBACK_PERIOD, max(0.0, (send_at - self.get_clock().now().nanoseconds) * 1e-9)))
        trajectory = self._trajectory_of(checked, samples)
        with self._lock:
            canceled = goal.cancel or goal_handle.is_cancel_requested
            if not canceled:
                goal.sent = True
                now = self.get_clock().now().nanoseconds
                # A start already past (the goal came late, or planning outlasted its lead) is streamed whole from
                # the streamer's next tick, like one as soon as possible: its origin comes from stream_state, and
                # the streamer's time to start it counts from now, not from a start it could never have met.
                origin = checked.start_ns if checked.start_ns > now else 0
                start_ns = origin or now
                for other in self._goals:  # settling goals observe until this motion starts at the latest
                    if other is not goal and other.execution is not None:
                        other.execution.cut(start_ns)
                goal.running = self._running = self._running_of(trajectory, origin, plan)
        if canceled:  # (ended outside the lock: _end may wait for the server's canceling state)
            if goal.preempted:
                return self._end(goal_handle, result, 'abort', 'preempted by a newer goal before its motion '
                                 'started: nothing was streamed')
            return self._end(goal_handle, result, 'cancel', 'canceled before its motion started: nothing '
                             'was streamed')
        goal.execution = Execution(plan.duration, settle, start_ns, config.params.L1, config.params.L2)
        self._trajectory.publish(trajectory)
        if checked.start_ns and not origin:
            self.get_logger().warn(f'execute_move: its start_time had passed {(now - checked.start_ns) * 1e-9:.3f} s '
                                   'before its trajectory was sent: the streamer streams it from its next tick')
        what = f'{checked.method}: {checked.start:g} -> {checked.goal:g} m in {plan.duration:.4g} s'
        return self._follow(goal, result, feedback, settle, what)

    def _take_over(self, goal: '_Goal', request, result, running: Running, settle: float, t0: float):
        """A goal during a motion: plan from the state at the handover, send, and once the streamer has
        taken it over (its stream_state), end the preempted goal and follow this one. A handover the
        streamer did not take (it came late on a busy machine) is planned again further ahead."""
        goal_handle = goal.goal_handle
        self.get_logger().info('execute_move: a goal during a motion: handed over on arrival'
                               if isinstance(goal.take_over[2], tuple) else
                               'execute_move: a goal during a motion: planning the handover')
        lead_scale, feedback = 1.0, None
        for attempt in range(HANDOVER_ATTEMPTS):
            try:
                sent = goal.take_over[2] if attempt == 0 else None  # (planned on arrival, _on_goal)
                if isinstance(sent, Exception):  # a refusal, or a bug's (for _execute)
                    raise sent
                if sent is None:
                    # the first one from the goal's arrival, as if planned then (a variational goal's is
                    # planned here, after the goals' thread accepted it)
                    sent = self._send_handover(goal, request, running, settle, lead_scale,
                                               arrived=t0 if attempt == 0 else None)
            except ValueError as exc:
                self._report_plan({'service': 'execute_move', 'method': '', **getattr(exc, 'values', {})},
                                  None, 0, t0, t0, error=str(exc))
                return self._end(goal_handle, result, 'abort', str(exc))
            checked, plan, trajectory, values, handover = sent
            if feedback is None:
                solved = time.perf_counter()
                self._report_plan(values, plan, len(trajectory.points), t0, solved)
                result.info = self._info(plan, checked, solved - t0)
                feedback = ExecuteMove.Feedback(progress=0.0, time_remaining=plan.duration, swing=math.nan)
                goal_handle.publish_feedback(feedback)
            if self._taken(goal.execution, handover):
                break
            goal.execution = None
            lead_scale *= 4.0
            self.get_logger().warn(f'execute_move: the streamer did not take the handover (late on arrival?): '
                                   f'planning it again {lead_scale:g} times further ahead')
        else:
            return self._end(goal_handle, result, 'abort', f'the streamer took none of {HANDOVER_ATTEMPTS} handovers '
                             '(see its /diagnostics); the running motion goes on')
        with self._lock:
            for other in self._goals:  # the motion is this goal's now
                if other is not goal and other.execution is not None:
                    other.execution.cut(handover)
                    if other.sent and other.execution.phase(0) in (WAITING, MOVING):
                        other.preempted = True
            goal.running = self._running = transitions.taken_over(
                running, self._running_of(trajectory, handover, plan), goal.execution.motion_start_ns)
        what = (f'{checked.method}: from {checked.start:g} m (taking over the motion) -> {checked.goal:g} m in '
                f'{plan.duration:.4g} s')
        return self._follow(goal, result, feedback, settle, what)

    def _send_handover(self, goal: '_Goal', request, running: Running, settle: float, lead_scale: float = 1.0,
                       arrived: float | None = None):
        """Plan ``goal``'s handover of ``running`` (``_preempting``) and send it: (checked, plan, trajectory,
        values, handover ns); ValueError says why not."""
        checked, plan, trajectory, values, handover = self._preempting(request.move, running, lead_scale, arrived)
        config = self._config
        with self._lock:  # (before it is sent: the first stream_state of it finds it)
            goal.sent = True
            goal.execution = Execution(plan.duration, settle, handover, config.params.L1, config.params.L2)
        self._trajectory.publish(trajectory)  # first: the handover is due in milliseconds
        return checked, plan, trajectory, values, handover

    def _warm_handover(self):
        """Plan a shaper's handover of the running motion as ``_on_goal`` would (back to where the motion
        started) and serialize its trajectory as publishing would, sending nothing, every ``handover_warmup``
        s while a motion streams: a real goal's handover is 1-2 ms of Python that, left untouched for 50-250
        ms beside the 1 kHz nodes, took 3-22 times as long (measured on a shared two-core host: caches, not
        page faults). Runs on the goals' thread, between its requests, so it never holds one up by more than
        one rehearsal; not while a handover is being planned (at this thread's priority it would take the
        core from an NVF/RVF handover's solver process, whose lead is tight)."""
        if self._handing_over.locked():
            return
        t0, running = time.perf_counter(), self._in_motion()
        if running is None or not running.origin_ns or running.hoist_moves:  # (a shaper cannot retarget then)
            return
        method = next((m for m in (running.method, self._config.method) if m in SHAPER_METHODS), SHAPER_METHODS[0])
        move = MoveMessage(method=method, goal=[float(running.interps[0].position[0])], duration=running.duration)
        try:
            serialize_message(self._preempting(move, running, rehearse=True)[2])
        except ValueError:  # (a stop's remainder too short for the shaper, the motion ended meanwhile, ...)
            pass
        except Exception as exc:  # a bug: the goals' thread goes on
            self.get_logger().error(f'handover warm-up: {type(exc).__name__}: {exc}', throttle_duration_sec=10.0)
        took = time.perf_counter() - t0
        with self._lock:  # counted for the goal whose motion it is (its status on /diagnostics)
            goal = next((g for g in self._goals if g.running is running), None)
            if goal is not None:
                goal.warmups, goal.warmup_s = goal.warmups + 1, goal.warmup_s + took

    def _taken(self, execution: Execution, handover_ns: int, wait: float = 0.5) -> bool:
        """Whether the streamer streams the handover at ``handover_ns`` (stream_state says so), waiting until
        its clock is 50 ms past the handover, or ``wait`` s."""
        deadline = time.monotonic() + wait
        while time.monotonic() < deadline:
            if execution.motion_start_ns is not None:
                return True
            if execution.stream_ns is not None and execution.stream_ns > handover_ns + 50_000_000:
                return False
            time.sleep(0.002)
        return False

    def _follow(self, goal: '_Goal', result, feedback, settle: float, what: str):
        """Follow the goal's motion to its result: done, preempted by a newer goal, or stopped on a cancel."""
        goal_handle = goal.goal_handle
        stopped = None  # (where the stop ends, m) once a cancel has stopped the motion
        while True:
            execution = goal.execution
            phase = execution.phase(self.get_clock().now().nanoseconds)
            if goal.running is not None:  # a pending motion's origin, kept once this goal has ended too
                self._origin(goal.running, wait=0.0)
            feedback.progress, feedback.time_remaining = execution.progress, execution.time_remaining
            feedback.swing = execution.swing
            goal_handle.publish_feedback(feedback)
            if goal.preempted:
                return self._end(goal_handle, result, 'abort', f'preempted by a newer goal after '
                                 f'{execution.progress * execution.duration:.3f} s of its motion ({what})')
            if goal_handle.is_cancel_requested and stopped is None:
                if phase in (WAITING, MOVING) and goal.running is not None:
                    try:
                        stopped = self._stop(goal, settle)
                    except ValueError as exc:
                        return self._end(goal_handle, result, 'cancel', f'canceled, but no stop could be planned '
                                         f'({exc}): the motion runs to its end')
                    continue
                result.residual_swing = execution.residual
                return self._end(goal_handle, result, 'cancel', 'canceled after its motion had ended')
            if phase in (DONE, FAILED):
                break
            time.sleep(FEEDBACK_PERIOD)
        if phase == FAILED:
            with self._lock:
                if self._running is goal.running:
                    self._running = None  # the streamer did not take it: nothing is in motion
            return self._end(goal_handle, result, 'abort', execution.failure)
        result.residual_swing = execution.residual
        residual = ('no joint_states: residual not measured' if math.isnan(execution.residual)
                    else f'residual swing {1e3 * execution.residual:.3f} mm')
        cut = ('' if execution.window_end_ns == execution.end_ns + round(settle * 1e9) else
               f' (observed {(execution.window_end_ns - execution.end_ns) * 1e-9:.3g} s: the next motion started)')
        if stopped is not None:
            return self._end(goal_handle, result, 'cancel', f'canceled: stopped at {stopped:.6g} m in '
                             f'{execution.duration:.4g} s without swing ({what}); {residual}{cut}')
        return self._end(goal_handle, result, 'succeed', f'{what}; {residual}{cut}', success=True)

    # -- motion from any state: a new goal, a stop, a settle ------------------------------------

    def _running_of(self, trajectory: JointTrajectory, origin_ns: int, plan) -> Running:
        """The motion of ``trajectory`` as the streamer will interpolate it; origin 0 (as soon as possible):
        learned from stream_state when the motion starts (``_origin``)."""
        arrays = [joint_trajectory_to_arrays(trajectory, joint) for joint in trajectory.joint_names]
        t = arrays[0][0]
        return Running(trajectory.joint_names, t, *(np.column_stack([a[k] for a in arrays]) for k in (1, 2, 3)),
                       origin_ns, plan)

    def _origin(self, running: Running, wait: float = 0.2) -> bool:
        """Whether ``running``'s origin is known: the streamer's once stream_state tells it (a trajectory that
        reached it after its stamp starts at its next tick), until then the stamp it was sent with; one sent
        as soon as possible (no stamp) waits up to ``wait`` s for the streamer's."""
        deadline = time.monotonic() + wait
        while not running.confirmed:
            with self._lock:
                goal = next((g for g in self._goals if g.running is running), None)
            origin = goal.execution.motion_origin_ns if goal is not None and goal.execution is not None else None
            if origin is not None:
                running.origin_ns, running.confirmed = origin, True
                break
            if running.origin_ns or time.monotonic() > deadline:
                return running.origin_ns != 0
            time.sleep(0.002)
        return True

    def _handover(self, running: Running, lead: float, make_plan, swing: bool = True, rehearse: bool = False):
        """(plan, handover ns, state): ``make_plan(handover_ns, state)`` planned from the state ``running``
        will be in ``lead`` s from now, planned again further ahead if it took longer than that (None if the
        motion ends first). ``swing``: predict the swing there (not needed by a shaper's change).
        ``rehearse``: planned once, however long it took, for nothing to be sent (``_warm_handover``)."""
        if not self._origin(running):
            raise MoveError('goal', 'the running motion has not started on the streamer yet (no stream_state '
                                    'of it): a goal during it is accepted once it streams')
        with contextlib.nullcontext() if rehearse else self._handing_over:
            for attempt in range(HANDOVER_ATTEMPTS):
                now = self.get_clock().now().nanoseconds
                handover = max(now + round(lead * 1e9), running.origin_ns)
                if handover >= running.end_ns:
                    return None
                with self._lock:
                    measured = self._measured
                t0 = time.perf_counter()
                state = transitions.handover_state(running, handover, measured, self._config.params, swing)
                t1 = time.perf_counter()
                plan = make_plan(handover, state)
                took = time.perf_counter() - t0
                # the transport's share of the lead: TRANSPORT_MARGIN, or with a short lead (a shaper's) 40 % of
                # it. A plan ending no earlier than the running motion (a new goal's) may even arrive late: the
                # streamer delays its change to its next tick, up to MAX_HANDOVER_SHIFT (half of it kept for the
                # transport). A handover arriving too late all the same is refused and planned again.
                slack = (0.5 * MAX_HANDOVER_SHIFT if handover + round(plan.duration * 1e9) >= running.end_ns
                         else -min(TRANSPORT_MARGIN, 0.4 * lead))
                if rehearse or self.get_clock().now().nanoseconds < handover + slack * 1e9:
                    return plan, handover, state
                self.get_logger().warn(f'handover: planning took {1e3 * took:.1f} ms (the state {1e3 * (t1 - t0):.1f} '
                                       f'ms), beyond the lead {1e3 * lead:.1f} ms: planning again further ahead')
                lead = max(2.0 * lead, 1.5 * took + TRANSPORT_MARGIN)
        raise MoveError('duration', f'planning took longer than the handover lead {HANDOVER_ATTEMPTS} times '
                                    f'(last lead {lead / 2:.3f} s); raise handover_lead')

    @staticmethod
    def _knot_times(plan, config: Config):
        """Where a plan is sampled for its trajectory: where it needs knots, or every ``sample_period``."""
        period = config.sample_period
        return knot_times(plan) if period == 0.0 else time_grid(plan.duration, period)

    def _trajectory_from(self, plan, state, joints, handover_ns: int) -> JointTrajectory:
        config = self._config
        times = self._knot_times(plan, config)
        starts = transitions.joint_starts(plan, state)
        return samples_to_joint_trajectory(axis_samples(plan, times), starts, handover_ns, config.frame_id,
                                           joint=list(joints))

    def _preempting(self, move_msg, running: Running, lead_scale: float = 1.0, arrived: float | None = None,
                    rehearse: bool = False):
        """(checked, plan, trajectory, values, handover ns) of a goal arriving during ``running``, handed over
        ``lead_scale`` times the configured lead from now, or from ``arrived`` (time.perf_counter) if given
        (at least half the lead from now); ``rehearse``: see ``_handover``."""
        config = self._config
        move = Move(move_msg.method, tuple(move_msg.joint_names), tuple(move_msg.start), tuple(move_msg.goal),
                    move_msg.duration, stamp_ns(move_msg.start_time))
        values = {'service': 'execute_move', 'method': move.method or config.method,
                  'goal': move.goal[0] if move.goal else math.nan, 'duration': move.duration, 'preempts': True}
        try:
            if move.start:
                raise MoveError('start', 'a goal during a motion starts where the motion is when it takes over: '
                                         'leave start empty')
            if move.start_ns:
                raise MoveError('start_time', 'a goal during a motion takes over at once: leave start_time zero')
            end = dict(zip(running.joints, (float(i.position[-1]) for i in running.interps)))
            checked = check_move(move, config.bounds, end, config.params.L1)
            if checked.duration is None:
                raise MoveError('duration', 'a goal during a motion needs a duration (> 0 s): the fastest plan is '
                                            'planned from rest only')
            goal = {'cart': checked.goal}
            if checked.hoist_goal is not None:
                goal['hoist'] = checked.hoist_goal
            shaper = checked.method not in VARIATIONAL_METHODS
            lead = (config.shaper_handover_lead if shaper else config.handover_lead) * lead_scale
            if arrived is not None:
                lead = max(0.5 * lead, lead - (time.perf_counter() - arrived))

            def make(handover_ns, state):
                return transitions.retarget(self._planner.variational, running, handover_ns, state, checked.method,
                                            goal, checked.duration, config.params, config.options)

            try:
                done = self._handover(running, lead, make, swing=not shaper, rehearse=rehearse)
            except MoveError:
                raise
            except ValueError as exc:
                raise MoveError('duration', str(exc)) from None
            if done is None:
                raise MoveError('goal', 'the running motion ended while this goal was planned; send it again')
        except ValueError as exc:
            exc.values = values
            raise
        plan, handover, state = done
        checked = CheckedMove(checked.method, checked.joint_names, state.cart[0], checked.goal, checked.duration,
                              handover, state.hoist[0] if state.hoist else None, checked.hoist_goal)
        values.update(method=checked.method, start=state.cart[0], goal=checked.goal, duration=plan.duration,
                      handover_lead=(handover - self.get_clock().now().nanoseconds) * 1e-9)
        return checked, plan, self._trajectory_from(plan, state, running.joints, handover), values, handover

    def _stop(self, goal: '_Goal', settle: float) -> float:
        """Stop ``goal``'s motion without swing (a cancel during it): send the stop, follow it from now on.
        Returns where the cart stops (m); ValueError says why no stop could be planned."""
        config, running = self._config, goal.running

        def make(handover_ns, state):
            return transitions.stop(self._planner.variational, running, handover_ns, state, running.method,
                                    config.params, config.options)

        done = self._handover(running, STOP_LEAD, make)
        if done is None:  # the motion ended meanwhile: it is at rest already
            return float(running.interps[0].position[-1])
        plan, handover, state = done
        trajectory = self._trajectory_from(plan, state, running.joints, handover)
        stop = self._running_of(trajectory, handover, plan)
        with self._lock:  # together: the stop's origin is learned from its execution (_origin)
            goal.running = self._running = stop
            goal.execution = Execution(plan.duration, settle, handover, config.params.L1, config.params.L2)
        self._trajectory.publish(trajectory)
        # a stop ending after the motion would have (one near its end) is streamed with its change delayed to
        # the tick at or after its stamp: what a next handover must continue
        if self._taken(goal.execution, handover, wait=STOP_LEAD + 0.2):
            with self._lock:
                if self._running is stop:
                    goal.running = self._running = transitions.taken_over(running, stop,
                                                                          goal.execution.motion_start_ns)
        where = state.cart[0] + plan.displacement
        self.get_logger().info(f'execute_move: canceled during its motion: stopping at {where:.6g} m in '
                               f'{plan.duration:.4g} s ({plan.method})')
        return where

    def _on_settle(self, request, response):
        """``~/settle``: damp the swing measured now by a short motion ending where the cart is held."""
        config = self._config
        response.success = False
        try:
            if self._in_motion() is not None:
                raise MoveError('settle', 'a motion is streaming: settle once it has ended')
            hold = self._hold()
            if hold is None:
                raise MoveError('settle', f'no streamer heard on {STREAM_STATE_TOPIC}: nothing would stream the '
                                          'motion')
            with self._lock:
                measured = self._measured
            now = self.get_clock().now().nanoseconds
            if measured is None or now - measured.stamp_ns > transitions.MEASUREMENT_AGE * 1e9:
                raise MoveError('settle', f'no joint_states within {transitions.MEASUREMENT_AGE:g} s: the swing '
                                          'to damp is not measured')
            joints = tuple(j for j in config.joints if j in hold)
            holding = Running.holding(joints, [hold[j] for j in joints], now)

            def make(handover_ns, state):
                return transitions.settle(self._planner.variational, state, config.params, config.options,
                                          config.settle_method)

            done = self._handover(holding, config.handover_lead, make)
            plan, handover, state = done
            trajectory = self._trajectory_from(plan, state, joints, handover)
            with self._lock:
                self._running = self._running_of(trajectory, handover, plan)
            self._trajectory.publish(trajectory)
        except ValueError as exc:
            response.message = str(exc)
            self.get_logger().warn(f'settle refused: {exc}')
            self._diagnostics.report('settle', WARN, f'settle refused: {exc}', error=str(exc))
            return response
        swing = transitions.swing_of(state, config.params)
        response.success = True
        response.message = (f'settling a swing of about {1e3 * swing:.1f} mm: a {plan.duration:.3g} s {plan.method} '
                            f'motion ending where the cart is held ({hold[CART_JOINT]:.6g} m)')
        self.get_logger().info(response.message)
        self._diagnostics.report('settle', OK, response.message, swing=swing, duration=plan.duration, error='')
        return response

    def _end(self, goal_handle, result, how: str, message: str, success: bool = False):
        """End a goal (``succeed``, ``abort`` or ``cancel``) with ``message``, also on /diagnostics."""
        result.success, result.message = success, message
        if how == 'cancel':  # the server marks the goal canceling just after our cancel callback returned
            deadline = time.monotonic() + 1.0
            while not goal_handle.is_cancel_requested and time.monotonic() < deadline:
                time.sleep(0.001)
        getattr(goal_handle, {'succeed': 'succeed', 'abort': 'abort', 'cancel': 'canceled'}[how])()
        level = OK if success else WARN if how == 'cancel' else ERROR
        with self._lock:
            goal = next((g for g in self._goals if g.goal_handle is goal_handle), None)
        warmups, warmup_s = (goal.warmups, goal.warmup_s) if goal is not None else (0, 0.0)
        if level == OK:  # (one call site per severity: rclpy refuses a site whose severity changes)
            self.get_logger().info(f'execute_move: {message}')
        else:
            self.get_logger().warn(f'execute_move: {message}')
        self._diagnostics.report(EXECUTE_TASK, level, message, outcome=how, residual_swing=result.residual_swing,
                                 error='' if success else message, handover_warmups=warmups,
                                 handover_warmup_ms=1e3 * warmup_s / warmups if warmups else 0.0)
        return result

    def destroy_node(self):
        self._inputs_spinning.__exit__(None, None, None)
        self._inputs.destroy_node()
        self._goals_spinning.__exit__(None, None, None)
        self._goals_node.remove_waitable(self._action)
        self._goals_node.destroy_node()
        # CasADi must not be building in the warm-up thread while the interpreter exits
        if self._warmup.is_alive():
            self.get_logger().info('waiting for the solver warm-up to finish')
            self._warmup.join()
        self._planner.close()
        super().destroy_node()


def main(args=None):
    return run(PlannerNode, MultiThreadedExecutor, args, num_threads=PlannerNode.executor_threads)


class _Goal:
    """An ExecuteMove goal the node is executing: whether its trajectory is sent, how it is followed."""

    def __init__(self, goal_handle):
        self.goal_handle = goal_handle
        self.sent = False  # the trajectory went to the streamer: a cancel now stops the motion
        self.cancel = False  # a cancel was accepted before it was sent
        self.execution: Execution | None = None
        self.preempted = False  # a newer goal took over (or, before it was sent, replaced it)
        self.running: Running | None = None  # its motion as sent (a stop's once canceled)
        # arriving during a motion: (that motion, perf_counter at arrival, its handover as sent by _on_goal
        # or why not: a ValueError, or a bug's exception)
        self.take_over: tuple | None = None
        self.warmups, self.warmup_s = 0, 0.0  # handover warm-ups during its motion (_warm_handover): count, s

    @property
    def phase(self) -> str:
        """The execution's phase; '' while planning or holding the trajectory."""
        return self.execution.phase(0) if self.execution is not None else ''
