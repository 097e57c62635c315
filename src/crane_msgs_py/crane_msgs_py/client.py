"""A client of the planner node's ``~/plan_move`` service and ``~/execute_move`` action for Python nodes.

    client = PlannerClient(node)             # planner 'crane_planner' in node's namespace
    plan = client.plan('rvf', None, 0.3, 3.0)      # a preview from where the streamer holds the cart (None)
    plan.t, plan.position, plan.info         # knot times (s, from the start), positions (m), PlanInfo
    result = client.execute('rvf', None, 0.3, 3.0)  # plan, stream, watch: the action's result
    result.residual_swing                    # m, measured from joint_states over the settle window

A refused request raises ``PlanError`` with the planner's reason (the
response's or the result's ``message``); a goal aborted after its motion
because the load still swung has its result, residual included, as the
error's ``result``. The node must be spun by an
executor in another thread (or by none: the client then spins it while it
waits); do not call these from a callback of a single-threaded executor
spinning the same node.
"""
from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np
import rclpy
from crane_interfaces.action import ExecuteMove
from crane_interfaces.msg import PlanInfo
from crane_interfaces.srv import PlanMove
from rclpy.callback_groups import ReentrantCallbackGroup
from trajectory_msgs.msg import JointTrajectory

from crane_msgs_py.crane.errors import PlanError
from crane_msgs_py.messages.conversions import joint_trajectory_to_arrays, move_message, stamp_ns
from crane_msgs_py.messages.names import EXECUTE_MOVE_ACTION, PLAN_MOVE_SERVICE, PLANNER_NODE, service_of
from crane_msgs_py.runtime.action_client import ActionClient
from crane_msgs_py.runtime.diagnostics import DiagnosticsReader
from crane_msgs_py.runtime.qos import PLAN_MOVE_QOS


@dataclass(frozen=True)
class MovePlan:
    """A plan as ``~/plan_move`` returns it.

    Attributes:
        t: knot times (s) from the start stamp, the last one exactly at the duration.
        position, velocity, acceleration: the cart reference at each knot (m, m/s, m/s^2).
        start_ns: start stamp (ns; 0 = as soon as possible).
        info: the planner's ``PlanInfo`` (method, duration, solve time, peaks per joint).
        trajectory: the knots as the message itself.
    """

    t: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    start_ns: int
    info: PlanInfo
    trajectory: JointTrajectory


class PlannerClient:
    """Calls ``<planner>/plan_move`` and ``<planner>/execute_move`` of the planner node in the caller's namespace.

    ``diagnostics`` reads ``/diagnostics`` (the planner's and the streamer's statuses).
    """

    def __init__(self, node, planner: str = PLANNER_NODE, callback_group=None):
        self._node = node
        self._group = callback_group or ReentrantCallbackGroup()
        self._plan = node.create_client(PlanMove, service_of(planner, PLAN_MOVE_SERVICE), qos_profile=PLAN_MOVE_QOS,
                                        callback_group=self._group)
        self._execute = ActionClient(node, ExecuteMove, service_of(planner, EXECUTE_MOVE_ACTION),
                                     callback_group=self._group)
        self.diagnostics = DiagnosticsReader(node, callback_group=self._group)
        self.last_sent_ns = 0  # ROS time the newest ExecuteMove goal was handed to rclpy to send

    def wait_for_service(self, timeout: float = 10.0) -> bool:
        """Whether ``~/plan_move`` and ``~/execute_move`` are both up within ``timeout`` s."""
        return self._plan.wait_for_service(timeout_sec=timeout) and self._execute.wait_for_server(timeout_sec=timeout)

    def _wait(self, future, timeout: float, what: str):
        if self._node.executor is None:
            rclpy.spin_until_future_complete(self._node, future, timeout_sec=timeout)
        else:
            done = threading.Event()
            future.add_done_callback(lambda _: done.set())
            done.wait(timeout)
        if not future.done():
            raise TimeoutError(f'no answer from {what} within {timeout:g} s')
        return future.result()

    def call(self, method: str | None, start: float | None, goal: float, duration: float, start_ns: int = 0,
             timeout: float = 60.0, move=None) -> PlanMove.Response:
        """The raw ``PlanMove`` response (or to ``move``, a ``crane_interfaces/Move`` given whole);
        TimeoutError if none within ``timeout`` s."""
        if move is None:
            move = move_message([goal], duration, [] if start is None else [start], method or '', start_ns=start_ns)
        if not self._plan.wait_for_service(timeout_sec=timeout):
            raise TimeoutError(f'planner service {self._plan.srv_name} not available')
        future = self._plan.call_async(PlanMove.Request(move=move))
        try:
            return self._wait(future, timeout, self._plan.srv_name)
        except TimeoutError:
            self._plan.remove_pending_request(future)
            raise

    def plan(self, method: str | None, start: float | None, goal: float, duration: float, start_ns: int = 0,
             timeout: float = 60.0) -> MovePlan:
        """Plan a move of the cart from ``start`` (m; None: where the streamer holds it) to ``goal`` in
        ``duration`` (s; 0 = the fastest within the planner's limits) starting at ``start_ns``; moves nothing.

        ``method`` None: the planner's ``method`` parameter. Raises PlanError with the planner's reason.
        """
        response = self.call(method, start, goal, duration, start_ns, timeout)
        if not response.success:
            raise PlanError(response.message)
        t, p, v, a = joint_trajectory_to_arrays(response.trajectory)
        return MovePlan(t, p, v, a, stamp_ns(response.trajectory.header.stamp), response.info, response.trajectory)

    def fastest(self, method: str | None, start: float | None, goal: float, start_ns: int = 0,
                timeout: float = 60.0) -> MovePlan:
        """The shortest plan to ``goal`` within the planner's axis limits (``duration`` 0); moves nothing."""
        return self.plan(method, start, goal, 0.0, start_ns, timeout)

    def send_execute(self, method: str | None, start: float | None, goal: float, duration: float,
                     start_ns: int = 0, settle: float = 0.0, feedback=None, timeout: float = 10.0, move=None):
        """Send an ``ExecuteMove`` goal (or one of ``move``, a ``crane_interfaces/Move`` given whole) and
        wait until it is accepted: its goal handle.

        ``feedback`` is called with each ``ExecuteMove.Feedback``; the result
        comes from ``result(handle)``; ``handle.cancel_goal_async()`` cancels.
        """
        if not self._execute.wait_for_server(timeout_sec=timeout):
            raise TimeoutError(f'planner action {EXECUTE_MOVE_ACTION} not available')
        if move is None:
            move = move_message([goal], duration, [] if start is None else [start], method or '', start_ns=start_ns)
        goal_msg = ExecuteMove.Goal(move=move, settle=float(settle))
        callback = None if feedback is None else (lambda msg: feedback(msg.feedback))
        self.last_sent_ns = self._node.get_clock().now().nanoseconds
        handle = self._wait(self._execute.send_goal_async(goal_msg, feedback_callback=callback), timeout,
                            'the execute_move action server')
        if not handle.accepted:  # the planner accepts every goal; a refused plan is aborted with its reason
            raise PlanError('the planner rejected the goal')
        return handle

    def result(self, handle, timeout: float = 120.0) -> ExecuteMove.Result:
        """The result of a goal from ``send_execute``; PlanError with its message unless it succeeded, the
        goal's result as its ``result`` (a goal that moved but left the load swinging over the planner's
        residual_tolerance has its ``residual_swing``; its message says ``names.STILL_SWINGING``)."""
        response = self._wait(handle.get_result_async(), timeout, 'the execute_move result')
        if not response.result.success:
            error = PlanError(response.result.message)
            error.result = response.result
            raise error
        return response.result

    def execute(self, method: str | None, start: float | None, goal: float, duration: float, start_ns: int = 0,
                settle: float = 0.0, feedback=None, timeout: float = 120.0) -> ExecuteMove.Result:
        """Plan, stream and watch a move (``send_execute``, then ``result``): the action's result once the
        settle window after the motion has passed. PlanError with the planner's reason if it was refused."""
        return self.result(self.send_execute(method, start, goal, duration, start_ns, settle, feedback), timeout)
