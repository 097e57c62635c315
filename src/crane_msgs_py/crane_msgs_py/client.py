"""A client of the planner node's ``nav_msgs/srv/GetPlan`` services for other Python nodes.

    client = PlannerClient(node)             # planner 'crane_planner' in node's namespace
    plan = client.plan('rvf', start=0.0, goal=0.3, duration=3.0)     # a preview: moves nothing
    plan.t, plan.position                    # knot times (s, from the start), positions (m)
    client.execute('rvf', start=0.0, goal=0.3, duration=3.0)         # plans and sends it to the streamer

A refused request raises ``PlanError`` with the planner's reason, read from
its ``/diagnostics`` status for that request. The node must be spun by an
executor in another thread (or by none: the client then spins it while it
waits); do not call ``plan`` from a callback of a single-threaded executor
spinning the same node.
"""
from __future__ import annotations

import math
import threading
from dataclasses import dataclass

import numpy as np
import rclpy
from nav_msgs.msg import Path
from nav_msgs.srv import GetPlan
from rclpy.callback_groups import ReentrantCallbackGroup

from .conversions import path_to_arrays, set_stamp
from .diagnostics import ERROR, DiagnosticsReader, status_float, status_values
from .errors import PlanError
from .names import PLANNER_NODE, planner_service, service_of

#: The planner's per-request diagnostic task (status ``<planner>: plan``).
PLAN_TASK = 'plan'


@dataclass(frozen=True)
class PathPlan:
    """A plan as returned by the planner service.

    Attributes:
        t: knot times (s) from the start stamp, the last one exactly at the duration.
        position: cart reference position (m) at each knot.
        start_ns: start stamp (ns; 0 = relative plan starting at time 0).
        path: the message itself.
    """

    t: np.ndarray
    position: np.ndarray
    start_ns: int
    path: Path


def plan_request(start: float, goal: float, duration: float, start_ns: int = 0) -> GetPlan.Request:
    """GetPlan request of the contract: positions in pose.position.x, duration in the stamps."""
    request = GetPlan.Request()
    request.start.pose.position.x = float(start)
    request.goal.pose.position.x = float(goal)
    set_stamp(request.start.header.stamp, start_ns)
    set_stamp(request.goal.header.stamp, start_ns + round(float(duration) * 1e9))
    return request


class PlannerClient:
    """Calls ``<planner>/plan[/<method>]``, ``<planner>/execute[/<method>]``, ``.../fastest/<method>``
    and ``.../execute_fastest/<method>`` of the planner node in the caller's namespace."""

    def __init__(self, node, planner: str = PLANNER_NODE, callback_group=None):
        self._node = node
        self._planner = planner
        self._group = callback_group or ReentrantCallbackGroup()
        self._clients: dict = {}
        self._lock = threading.Lock()
        self.diagnostics = DiagnosticsReader(node, callback_group=self._group)
        self._status_name = f'{planner.rsplit("/", 1)[-1]}: {PLAN_TASK}'

    def _client(self, method: str | None, kind: str = 'plan'):
        with self._lock:
            client = self._clients.get((method, kind))
            if client is None:
                name = service_of(self._planner, planner_service(kind, method))
                client = self._clients[method, kind] = self._node.create_client(
                    GetPlan, name, callback_group=self._group)
            return client

    def wait_for_service(self, method: str | None = None, timeout: float = 10.0, execute: bool = False,
                         kind: str | None = None) -> bool:
        return self._client(method, kind or ('execute' if execute else 'plan')).wait_for_service(timeout_sec=timeout)

    def call(self, method: str | None, start: float, goal: float, duration: float,
             start_ns: int = 0, timeout: float = 60.0, execute: bool = False, kind: str | None = None) -> Path:
        """The raw response path (empty on failure); TimeoutError if no answer in ``timeout`` s.

        ``method`` None calls ``~/plan`` (the planner's ``method`` parameter);
        ``execute`` calls ``~/execute[/<method>]`` instead, ``kind`` any of
        ``names.PLANNER_SERVICES`` (for ``fastest`` kinds ``duration`` is ignored).
        """
        client = self._client(method, kind or ('execute' if execute else 'plan'))
        if not client.wait_for_service(timeout_sec=timeout):
            raise TimeoutError(f'planner service {client.srv_name} not available')
        future = client.call_async(plan_request(start, goal, duration, start_ns))
        if self._node.executor is None:
            rclpy.spin_until_future_complete(self._node, future, timeout_sec=timeout)
        else:
            done = threading.Event()
            future.add_done_callback(lambda _: done.set())
            done.wait(timeout)
        if not future.done():
            client.remove_pending_request(future)
            raise TimeoutError(f'no answer from {client.srv_name} within {timeout} s')
        return future.result().plan

    def plan(self, method: str | None, start: float, goal: float, duration: float,
             start_ns: int = 0, timeout: float = 60.0, reason_timeout: float = 2.0) -> PathPlan:
        """Plan from ``start`` to ``goal`` (m) in ``duration`` (s) starting at ``start_ns``; moves nothing.

        Raises PlanError with the planner's reason (its ERROR status for this
        request), or saying none arrived within ``reason_timeout`` s.
        """
        return self._request('plan', method, start, goal, duration, start_ns, timeout, reason_timeout)

    def fastest(self, method: str, start: float, goal: float, start_ns: int = 0, timeout: float = 60.0,
                reason_timeout: float = 2.0) -> PathPlan:
        """The shortest plan from ``start`` to ``goal`` within the planner's axis limits; moves nothing.

        Its duration is the last knot's time (``PathPlan.t[-1]``).
        """
        return self._request('fastest', method, start, goal, 0.0, start_ns, timeout, reason_timeout)

    def execute_fastest(self, method: str, start: float, goal: float, start_ns: int = 0, timeout: float = 60.0,
                        reason_timeout: float = 2.0) -> PathPlan:
        """Like ``fastest``, and the planner sends the plan to the streamer: the crane moves."""
        return self._request('execute_fastest', method, start, goal, 0.0, start_ns, timeout, reason_timeout)

    def execute(self, method: str | None, start: float, goal: float, duration: float,
                start_ns: int = 0, timeout: float = 60.0, reason_timeout: float = 2.0) -> PathPlan:
        """Like ``plan``, and the planner sends the plan to the streamer: the crane moves.

        The streamer still refuses a plan that does not start at its hold
        position or arrives while it streams another (see its diagnostics).
        """
        return self._request('execute', method, start, goal, duration, start_ns, timeout, reason_timeout)

    def _request(self, service, method, start, goal, duration, start_ns, timeout, reason_timeout) -> PathPlan:
        mark = self.diagnostics.mark()
        path = self.call(method, start, goal, duration, start_ns, timeout, kind=service)
        if path.poses:
            t, x = path_to_arrays(path)
            return PathPlan(t, x, start_ns, path)

        def same_request(status):
            values = status_values(status)
            return ((method is None or values.get('method') == method)
                    and values.get('service', service) == service
                    and _same(status_float(status, 'start'), start)
                    and _same(status_float(status, 'goal'), goal)
                    and (service in ('fastest', 'execute_fastest')
                         or _same(status_float(status, 'duration'), duration)))

        status = self.diagnostics.wait_for(same_request, reason_timeout, after=mark,
                                           name=self._status_name, level=ERROR)
        if status is None:
            raise PlanError(f'the planner returned an empty plan and no reason within {reason_timeout} s')
        raise PlanError(status.message)


def _same(reported: float, requested: float) -> bool:
    """Key values carry 9 significant digits; NaN matches NaN."""
    requested = float(requested)
    if math.isnan(reported) or math.isnan(requested):
        return math.isnan(reported) and math.isnan(requested)
    return math.isclose(reported, requested, rel_tol=1e-8, abs_tol=1e-9)
