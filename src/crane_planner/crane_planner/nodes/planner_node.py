"""Planner node: ``~/plan_move`` (a preview), ``~/execute_move`` (an action), ``~/settle`` (contract: planner).

The ROS side only: entities, threads, messages <-> records. What is served is ``serving.service`` (a preview; a
goal planned, held until ``publish_lead`` before its start, sent on ``trajectory``, followed to its result on the
goal runner, feedback every ``following.FEEDBACK_PERIOD``; a goal during a motion takes it over, a cancel stops it),
the goals' states ``serving.goals``, the parameters ``serving.config``, a shared runway ``runway_port``; /diagnostics.
"""
from __future__ import annotations

import threading
import time

import rclpy
from crane_interfaces.action import ExecuteMove
from crane_interfaces.msg import AxisStatus, PlanInfo, StreamState
from crane_interfaces.srv import PlanMove
from rclpy.action import CancelResponse, GoalResponse
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.exceptions import InvalidHandle
from rclpy.executors import MultiThreadedExecutor, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.serialization import serialize_message
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory
from visualization_msgs.msg import MarkerArray

from crane_msgs_py.messages import conversions, names
from crane_msgs_py.runtime import qos
from crane_msgs_py.runtime.action_server import ActionServer
from crane_msgs_py.runtime.diagnostics import ERROR, OK, WARN, DiagnosticsPublisher
from crane_msgs_py.runtime.node_parameters import Guard, declare
from crane_msgs_py.runtime.realtime import fix_mmap_threshold, set_threads_fifo
from crane_msgs_py.runtime.runner import run, spinning
from crane_planner.nodes.runway_port import RunwayPort
from crane_planner.planning.methods import METHODS, Family, methods_of
from crane_planner.serving import Planner, service
from crane_planner.serving.config import PARAMETERS, Config
from crane_planner.serving.crane_view import StreamSample, joint_sample
from crane_planner.serving.moves import Move, summarize


def _move(msg) -> Move:
    return Move(msg.method, tuple(msg.joint_names), tuple(msg.start), tuple(msg.goal), msg.duration,
                conversions.stamp_ns(msg.start_time), tuple(tuple(p.positions) for p in msg.via))


class PlannerNode(Node):
    """The ``crane_planner`` node."""

    def __init__(self, **kwargs):
        super().__init__(names.PLANNER_NODE, **kwargs)
        if warning := fix_mmap_threshold():  # before any solver allocates: keeps the node's size flat
            self.get_logger().warn(warning)
        values = declare(self, PARAMETERS)
        self._diagnostics = DiagnosticsPublisher(self)
        self._config = Config.from_values(values, self.get_namespace())  # bad overrides: ParameterError, see main()
        Guard(self, PARAMETERS, lambda v: Config.from_values(v, self.get_namespace()), self._apply, self._diagnostics)
        self._runway = RunwayPort(self, lambda: self._config, self._diagnostics)  # /runway/occupancy (runway on)
        # a solver process that died (what was done) and its replacement: on /diagnostics (serving.planner.WorkerEvent)
        self._planner = Planner(self._config.solver_pool_size, processes=self._config.solver_processes,
                                on_event=lambda e: self._diagnostics.report('solver_processes', e.level, e.message,
                                                                            **e.values()))
        self._planner.warmups = self._config.warmups()
        service.start_processes(self._planner, self._config, self.get_logger())  # before any request comes
        self._trajectory = self.create_publisher(JointTrajectory, names.TRAJECTORY_TOPIC, qos.TRAJECTORY_QOS)
        markers = self.create_publisher(MarkerArray, names.MARKERS_TOPIC, qos.MARKERS_QOS)  # keep-out boxes, route
        stamp = lambda: self.get_clock().now().nanoseconds  # noqa: E731
        self.create_timer(1.0, lambda: self._config.keep_out and markers.publish(conversions.keep_out_markers(
            [(b.lower, b.upper) for b in self._config.keep_out.boxes], self._config.keep_out.margin,
            self._config.frame_id, stamp())))
        self._service = service.MoveService(  # the goals' steps on its worker thread (worker=True)
            self._planner, lambda: self._config, stamp, lambda t: self._trajectory.publish(self._message(t)),
            self._report, self.get_logger(), worker=True, draw=lambda points, life: markers.publish(
                conversions.route_markers(points, self._config.frame_id, stamp(), life)), runway=self._runway.step)
        # The inputs on a node and executor thread of their own: the services' MultiThreadedExecutor costs far more
        # CPU on the two at 50 Hz; the EventsExecutor fell behind on them after many requests (goals found no stream).
        self._inputs, self._inputs_spinning = self._spun('inputs', lambda node: [node.create_subscription(*t) for t in (
            (StreamState, names.STREAM_STATE_TOPIC, self._on_stream_state, qos.STREAM_STATE_QOS),
            (JointState, names.JOINT_STATES_TOPIC, self._on_joint_state, qos.JOINT_STATES_QOS),
            (AxisStatus, names.AXIS_STATUS_TOPIC, lambda m: self._service.on_axis_status(
                conversions.stamp_ns(m.header.stamp), m.state, m.message), qos.AXIS_STATUS_QOS))])
        group = ReentrantCallbackGroup()
        self.create_service(PlanMove, names.PLAN_MOVE_SERVICE, self._on_plan_move, qos_profile=qos.PLAN_MOVE_QOS,
                            callback_group=group)
        self._action = ActionServer(self, ExecuteMove, names.EXECUTE_MOVE_ACTION, self._execute,
                                    goal_callback=self._on_goal, handle_accepted_callback=self._on_accepted,
                                    cancel_callback=self._on_cancel, callback_group=group)
        # The action's requests (goal, cancel, result) are waited for on a thread of their own: through the
        # MultiThreadedExecutor a goal reached its callback only after its wait set was rebuilt for every entity, which
        # can take a shaper's whole handover budget. The server stays this node's (`ros2 action info` names it); its
        # callbacks return at once or within a shaper's handover (_on_goal); goals execute on this node's executor. The
        # thread keeps a shaper's handover warm (_warm_handover), at handover_priority (beside the 1 kHz nodes).
        self.remove_waitable(self._action)
        self._goals_node, self._goals_spinning = self._spun('goals', self._add_goals, refused=self._priority_refused,
                                                            priority=lambda: self._config.handover_priority)
        self._prioritize_receiving(self._config.handover_priority)
        self.create_service(Trigger, names.SETTLE_SERVICE, self._on_settle, callback_group=group)
        self.get_logger().info(f'serving {", ".join(METHODS)} on {self.get_fully_qualified_name()}/plan_move '
                               '(PlanMove: a preview) and .../execute_move (ExecuteMove: plan, stream, settle)')
        self._warmup = threading.Thread(target=self._build_solvers, name='solver-warmup', daemon=True)
        self._warmup.start()

    def _spun(self, suffix: str, setup, **priority):
        """A node of its own, ``setup(node)``, spun on a SingleThreadedExecutor thread (``runner.spinning``)."""
        node = rclpy.create_node(f'{self.get_name()}_{suffix}', namespace=self.get_namespace(),
                                 start_parameter_services=False)
        setup(node)
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        spun = spinning(executor, **priority)
        spun.__enter__()
        return node, spun

    def _add_goals(self, node):
        node.add_waitable(self._action)
        self._warm_timer = node.create_timer(self._config.handover_warmup or 1.0, self._warm_handover)
        if not self._config.handover_warmup:
            self._warm_timer.cancel()

    def _apply(self, config: Config, values, changes):
        if config.handover_priority != self._config.handover_priority:
            self._prioritize_receiving(config.handover_priority)
        if config.handover_warmup != self._config.handover_warmup:
            self._warm_timer.timer_period_ns = round((config.handover_warmup or 1.0) * 1e9)
            if config.handover_warmup:
                self._warm_timer.reset()
            else:
                self._warm_timer.cancel()
        self._planner.pool_size = config.solver_pool_size
        warmups = config.warmups()  # what the workers build in the background, and a replaced one first
        if warmups != self._planner.warmups:
            self._planner.warmups = warmups
            if config.solver_processes:  # (without workers the first request of a new NLP builds it)
                service.report_when_built(self._planner, lambda text: self._diagnostics.report('solvers', OK, text))
        self._config = config  # applies to the next request

    def executor_threads(self) -> int:
        """Enough executor threads for every solver busy at once, the shapers' and parameter requests and the
        goals being executed (each waits on one for its result: one moving, one settling)."""
        return self._config.solver_processes + self._config.solver_pool_size * len(methods_of(Family.VARIATIONAL)) + 7

    def _build_solvers(self):
        """Every method built once at start-up (``service.build_solvers``); a ``solvers`` status with the times."""
        built = service.build_solvers(self._planner, self._config, self.get_logger())
        self._diagnostics.report('solvers', WARN if built.failed else OK, built.message,
                                 **{f'{m}_s': v for m, v in built.times.items()},
                                 **{f'{m}_error': e for m, e in built.failed.items()})

    def _prioritize_receiving(self, handover_priority: int):
        """The middleware's receive threads one below the goals' thread (a goal reaches it through them)."""
        _, refused = set_threads_fifo(max(0, handover_priority - 1))
        if refused:
            self.get_logger().warn(f'handover_priority: the middleware\'s receive threads: {refused}')

    def _priority_refused(self, reason: str):
        self.get_logger().warn(f'handover_priority: {reason}; shapers\' handovers are planned at normal priority')

    # -- messages <-> records ------------------------------------------------------------

    def _on_stream_state(self, msg: StreamState):
        self._service.on_stream_state(StreamSample(*conversions.read_stream_state(msg)))

    def _on_joint_state(self, msg: JointState):
        try:
            pv = conversions.joint_state_to_arrays(msg, names.SIM_JOINTS)  # (position, velocity)
            measured = joint_sample(conversions.stamp_ns(msg.header.stamp), *pv, msg.name, msg.position, msg.velocity)
        except ValueError:  # not the crane's joints, or not finite (a camera that lost the load): no measurement
            return
        self._service.on_joint_state(measured)

    def _message(self, trajectory) -> JointTrajectory:
        return conversions.samples_to_joint_trajectory(trajectory.samples, trajectory.starts, trajectory.stamp_ns,
                                                       self._config.frame_id, joint=list(trajectory.joints))

    @staticmethod
    def _info(planned: service.Planned) -> PlanInfo:
        summary = summarize(planned.plan, planned.checked.joints, planned.plan.info.get('solve_time_s',
                                                                                       planned.planning_s))
        return PlanInfo(**{k: list(v) if isinstance(v, tuple) else v for k, v in vars(summary).items()})

    def _report(self, values: dict, planned: service.Planned | None, t0: float, solved: float, error: str = ''):
        """One /diagnostics status per request (``service.plan_status``)."""
        message, fields = service.plan_status(values, planned, t0, solved, time.perf_counter(), error)
        if error:
            self.get_logger().error(f'{values["service"]} {values["method"]} refused: {error}')
        self._diagnostics.report('plan', ERROR if error else OK, message, **fields)

    def _on_plan_move(self, request, response):
        t0 = time.perf_counter()
        response.success, response.message = False, ''
        response.trajectory.header.frame_id = self._config.frame_id
        try:
            planned = self._service.plan(_move(request.move), 'plan_move')
        except Exception as exc:  # a refusal (ValueError); a solver bug must not kill the node or hang the caller
            response.message = str(exc) if isinstance(exc, ValueError) else f'internal error: {exc!r}'
            values = {'service': 'plan_move', 'method': '', **getattr(exc, 'values', {})}
            self._report(values, None, t0, t0, error=response.message)
            return response
        response.success = True
        response.trajectory, response.info = self._message(planned.trajectory), self._info(planned)
        self._report(planned.values, planned, t0, t0 + planned.planning_s)
        return response

    def _on_goal(self, request) -> GoalResponse:
        """Every goal is accepted (a refusal is its result's reason) and registered here, on the goals' thread,
        and a shaper's during a motion handed over at once (``MoveService.arrive``): before rclpy accepts it (a
        noticeable share of that handover's budget; rclpy fails to only on an internal error, which it logs)."""
        self._service.arrive(id(request), _move(request.move), request.settle)
        return GoalResponse.ACCEPT

    def _on_accepted(self, goal_handle):
        self._service.goals.accept(id(goal_handle.request), goal_handle)
        goal_handle.execute()

    def _on_cancel(self, goal_handle) -> CancelResponse:
        """Every cancel is accepted: before the goal's trajectory is sent nothing streams; during its motion
        the goal runner plans a stop (contract "Motion from any state"); after it the goal ends at once."""
        self._service.goals.cancel(goal_handle)
        return CancelResponse.ACCEPT

    def _warm_handover(self):
        """Every ``handover_warmup`` s on the goals' thread: a shaper's handover rehearsed, its trajectory
        serialized as publishing would, nothing sent (``MoveService.warm_handover``)."""
        try:
            self._service.warm_handover(lambda t: serialize_message(self._message(t)))
        except Exception as exc:  # a bug: the goals' thread goes on
            self.get_logger().error(f'handover warm-up: {type(exc).__name__}: {exc}', throttle_duration_sec=10.0)

    def _execute(self, goal_handle):
        request, result = goal_handle.request, ExecuteMove.Result(residual_swing=float('nan'))
        goal = self._service.goals.of(goal_handle)
        try:  # the goal runner's outcome, waited for on an Event: rclpy's result is what this callback returns
            outcome = self._service.execute(goal, _move(request.move), request.settle, lambda **feedback: goal_handle
                                            .publish_feedback(ExecuteMove.Feedback(**feedback)),
                                            lambda: goal_handle.is_cancel_requested)
        except Exception as exc:  # a bug must not leave the caller waiting forever
            if isinstance(exc, (InvalidHandle, service.RunnerStopped)) or not self.context.ok():  # shut down
                return result
            self.get_logger().error(f'execute_move: unexpected {type(exc).__name__}: {exc}')
            if not goal_handle.is_active:  # it already ended: the caller has its status
                return result
            outcome = service.Outcome('abort', f'internal error: {type(exc).__name__}: {exc}', warmups=goal.warmups,
                                      warmup_s=goal.warmup_s)
        finally:
            self._service.goals.remove(goal)
        return self._end(goal_handle, result, outcome)

    def _end(self, goal_handle, result, outcome: service.Outcome):
        """End a goal as ``outcome`` says (``succeed``, ``abort`` or ``cancel``), also on /diagnostics."""
        result.success, result.message, result.residual_swing = outcome.success, outcome.message, \
            outcome.residual_swing
        if outcome.plan is not None:
            result.info = self._info(outcome.plan)
        if outcome.how == 'cancel':  # the server marks the goal canceling just after our cancel callback returned
            deadline = time.monotonic() + 1.0
            while not goal_handle.is_cancel_requested and time.monotonic() < deadline:
                time.sleep(0.001)
        getattr(goal_handle, {'succeed': 'succeed', 'abort': 'abort', 'cancel': 'canceled'}[outcome.how])()
        level = OK if outcome.success else WARN if outcome.how == 'cancel' else ERROR
        if level == OK:  # (one call site per severity: rclpy refuses a site whose severity changes)
            self.get_logger().info(f'execute_move: {outcome.message}')
        else:
            self.get_logger().warn(f'execute_move: {outcome.message}')
        self._diagnostics.report('execute', level, outcome.message, **outcome.status())
        return result

    def _on_settle(self, request, response):
        """``~/settle``: damp the swing measured now by a short motion ending where the cart is held."""
        try:
            settled = self._service.settle()
        except ValueError as exc:
            response.success, response.message = False, str(exc)
            self.get_logger().warn(f'settle refused: {exc}')
            self._diagnostics.report('settle', WARN, f'settle refused: {exc}', error=str(exc))
            return response
        response.success, response.message = True, settled.message
        self.get_logger().info(settled.message)
        self._diagnostics.report('settle', OK, settled.message, swing=settled.swing, duration=settled.plan.duration,
                                 error='')
        return response

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
        self._service.close()
        self._planner.close()
        self._runway.close()
        super().destroy_node()


def main(args=None):
    return run(PlannerNode, MultiThreadedExecutor, args, num_threads=PlannerNode.executor_threads)
