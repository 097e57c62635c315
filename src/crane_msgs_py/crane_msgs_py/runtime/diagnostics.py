"""``/diagnostics`` of the crane nodes: publishing statuses and reading them back.

Every node reports on ``/diagnostics`` (``diagnostic_msgs/DiagnosticArray``)
with statuses named ``<node name>: <task>`` (diagnostic_updater's style) and
``hardware_id`` = the node's fully qualified name, so setups in different
namespaces stay apart. Key values are strings; ``status_values`` parses them
back into a dict.
"""
from __future__ import annotations

import itertools
import math
import threading
import time
from collections import deque

import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

from crane_msgs_py.messages.names import DIAGNOSTICS_TOPIC
from crane_msgs_py.runtime.qos import DIAGNOSTICS_QOS

# Levels as ints (the message constants and field are one-byte ``bytes``).
OK, WARN, ERROR, STALE = (c[0] for c in (DiagnosticStatus.OK, DiagnosticStatus.WARN,
                                         DiagnosticStatus.ERROR, DiagnosticStatus.STALE))


def format_value(value) -> str:
    """A key value's text: floats with 9 significant digits, booleans lower case."""
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, float):
        return f'{value:.9g}'
    return str(value)


def status_values(status: DiagnosticStatus) -> dict[str, str]:
    return {kv.key: kv.value for kv in status.values}


def status_float(status: DiagnosticStatus, key: str) -> float:
    """A numeric key value; NaN if absent or not a number."""
    for kv in status.values:
        if kv.key == key:
            try:
                return float(kv.value)
            except ValueError:
                return math.nan
    return math.nan


class DiagnosticsPublisher:
    """Publishes a node's statuses on ``/diagnostics``; thread-safe (one rcl publisher)."""

    def __init__(self, node):
        self._node = node
        self._name = node.get_name()
        self._hardware_id = node.get_fully_qualified_name()
        self._pub = node.create_publisher(DiagnosticArray, DIAGNOSTICS_TOPIC, DIAGNOSTICS_QOS)

    def status(self, task: str, level: int, message: str, **values) -> DiagnosticStatus:
        """A status ``<node name>: <task>`` with ``values`` as key values (in order)."""
        return DiagnosticStatus(
            level=bytes((level,)),
            name=f'{self._name}: {task}', message=message, hardware_id=self._hardware_id,
            values=[KeyValue(key=k, value=format_value(v)) for k, v in values.items()])

    def publish(self, *statuses: DiagnosticStatus):
        msg = DiagnosticArray(status=list(statuses))
        msg.header.stamp = self._node.get_clock().now().to_msg()
        self._pub.publish(msg)

    def report(self, task: str, level: int, message: str, **values):
        """Publish one status at once (see ``status``)."""
        self.publish(self.status(task, level, message, **values))


def level_of(status: DiagnosticStatus) -> int:
    """The status level as an int (OK, WARN, ERROR, STALE)."""
    return status.level[0]


class DiagnosticsReader:
    """Keeps the recent ``/diagnostics`` statuses of a node's subscription and waits for them.

    The node must be spun by an executor; ``wait_for`` spins it itself when it
    is in none, otherwise it waits for the executor's thread (so do not call it
    from a callback of a single-threaded executor spinning the same node).

    Args:
        node: the rclpy node to subscribe with.
        history: how many statuses to keep.
        callback_group: for the subscription (e.g. a ReentrantCallbackGroup).

    The subscription uses DIAGNOSTICS_QOS (transient local, so statuses
    published just before it matched still arrive).
    """

    def __init__(self, node, history: int = 2000, callback_group=None):
        self._node = node
        self._cond = threading.Condition()
        self._statuses: deque = deque(maxlen=history)  # (sequence number, status)
        self._seq = itertools.count(1)
        self._last = 0
        self._sub = node.create_subscription(DiagnosticArray, DIAGNOSTICS_TOPIC, self._on_array, DIAGNOSTICS_QOS,
                                             callback_group=callback_group)

    def _on_array(self, msg: DiagnosticArray):
        with self._cond:
            for status in msg.status:
                self._last = next(self._seq)
                self._statuses.append((self._last, status))
            self._cond.notify_all()

    def mark(self) -> int:
        """A position in the stream: ``wait_for(..., after=mark)`` sees only later statuses."""
        with self._cond:
            return self._last

    def statuses(self, name: str | None = None, level: int | None = None, after: int = 0,
                 hardware_id: str | None = None) -> list[DiagnosticStatus]:
        """Kept statuses, oldest first, filtered by exact name, level and hardware id."""
        with self._cond:
            return [s for seq, s in self._statuses if seq > after and _matches(s, name, level, hardware_id)]

    def wait_for(self, predicate=None, timeout: float = 1.0, after: int = 0, name: str | None = None,
                 level: int | None = None, hardware_id: str | None = None) -> DiagnosticStatus | None:
        """The first status after ``after`` that matches the filters and ``predicate``; None on timeout."""
        deadline = time.monotonic() + timeout
        seen = after
        while True:
            with self._cond:
                for seq, s in self._statuses:
                    if seq > seen and _matches(s, name, level, hardware_id) and (predicate is None or predicate(s)):
                        return s
                seen = max(seen, self._last)
                remaining = deadline - time.monotonic()
                if remaining <= 0.0:
                    return None
                if self._node.executor is not None:
                    self._cond.wait(remaining)
                    continue
            rclpy.spin_once(self._node, timeout_sec=min(remaining, 0.05))


def _matches(status, name, level, hardware_id) -> bool:
    return ((name is None or status.name == name) and (level is None or level_of(status) == level)
            and (hardware_id is None or status.hardware_id == hardware_id))
