"""The planner's runway over ROS: ``/runway/occupancy`` published and read (contract "Cranes sharing a runway").

ROS only, on a node and executor thread of its own beside the planner node (with ``runway`` false nothing is
made: no topic). It hands every other crane's occupancy to ``serving.runway_step`` (``Neighbours``), counts an
unusable one on /diagnostics (``runway``: its reason and the count), publishes this crane's, draws the others on
the planner's markers topic (``occupancy_messages.runway_markers``, every ``MARKERS_PERIOD``), and at start-up
refuses a ``runway_offset`` that puts this crane's girder too near another's (``runway_step.startup_conflict``,
after ``STARTUP_WAIT``): a ParameterError, so the planner exits with status 2 and that one line.
"""
from __future__ import annotations

import time
from typing import Callable

import rclpy
from crane_interfaces.msg import Occupancy as OccupancyMsg
from rclpy.executors import SingleThreadedExecutor
from visualization_msgs.msg import MarkerArray

from crane_msgs_py.crane.params import ParameterError
from crane_msgs_py.messages import names
from crane_msgs_py.runtime import qos
from crane_msgs_py.runtime.diagnostics import WARN
from crane_msgs_py.runtime.runner import spinning
from crane_planner.nodes.occupancy_messages import (
    MARKERS_PERIOD,
    OccupancyRefused,
    from_message,
    runway_markers,
    to_message,
)
from crane_planner.runway.config import OCCUPANCY_TOPIC
from crane_planner.serving.config import Config
from crane_planner.serving.crane_view import DISCOVERY_WAIT
from crane_planner.serving.runway_step import Neighbours, RunwayStep, startup_conflict

#: How long (s) the planner listens on /runway/occupancy at start-up before it checks its runway_offset: the
#: other cranes' newest occupancies (transient local) arrive once discovery has matched them, within a participant
#: announcement period of Fast DDS (3 s) if its first announcements were missed (as ``crane_view.DISCOVERY_WAIT``).
STARTUP_WAIT = DISCOVERY_WAIT


class RunwayPort:
    """``step``: the ``RunwayStep`` the planner's service uses (publishing nothing with ``runway`` false)."""

    def __init__(self, node, config: Callable[[], Config], diagnostics):
        self._config, self._diagnostics, self._node = config, diagnostics, None
        clock = lambda: node.get_clock().now().nanoseconds  # noqa: E731
        self.book = Neighbours(lambda: config().runway.crane)
        if not config().runway.on:
            self.step = RunwayStep(config, clock, None, self.book)
            return
        self._node = rclpy.create_node(f'{node.get_name()}_runway', namespace=node.get_namespace(),
                                       start_parameter_services=False)
        self._pub = self._node.create_publisher(OccupancyMsg, OCCUPANCY_TOPIC, qos.RUNWAY_OCCUPANCY_QOS)
        self._node.create_subscription(OccupancyMsg, OCCUPANCY_TOPIC, self._on_occupancy, qos.RUNWAY_OCCUPANCY_QOS)
        # the other cranes drawn where their occupancies put them now, beside this planner's keep-out markers
        markers = self._node.create_publisher(MarkerArray, names.MARKERS_TOPIC, qos.MARKERS_QOS)
        def draw():
            others = self.book.others()
            if others:
                markers.publish(runway_markers(others, clock(), config().runway.offset, config().frame_id))
        self._node.create_timer(MARKERS_PERIOD, draw)
        executor = SingleThreadedExecutor()
        executor.add_node(self._node)
        self._spinning = spinning(executor)
        self._spinning.__enter__()
        self.step = RunwayStep(config, clock, self.publish, self.book)
        time.sleep(STARTUP_WAIT)
        refused = startup_conflict(config(), self.book.others(), 0.0, clock())
        if refused:
            self.close()
            raise ParameterError(refused)
        r, heard = config().runway, sorted(o.crane for o in self.book.others())
        node.get_logger().info(f'on the runway as crane {r.crane!r} at {list(r.offset)}; other cranes heard: '
                               f'{", ".join(heard) or "none"}')

    def publish(self, occupancy) -> None:
        self._pub.publish(to_message(occupancy))

    def _on_occupancy(self, msg: OccupancyMsg) -> None:
        try:
            self.book.heard(from_message(msg))
        except OccupancyRefused as exc:
            count = self.book.ignore(str(exc))
            self._node.get_logger().warn(f'ignored: {exc}', throttle_duration_sec=5.0)
            self._diagnostics.report('runway', WARN, f'ignored an occupancy ({count} so far): {exc}', ignored=count,
                                     error=str(exc))

    def close(self) -> None:
        if self._node is not None:
            self._spinning.__exit__(None, None, None)
            self._node.destroy_node()
            self._node = None
