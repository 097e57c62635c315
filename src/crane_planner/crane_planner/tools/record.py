"""``crane-record``: record topics of a running setup into a rosbag2 recording in MCAP storage.

What ``ros2 bag record -s mcap`` makes (a folder with ``metadata.yaml`` and the
``.mcap`` file), written with the ``rosbags`` library, for machines without a
ROS install. Each message is stored as received (CDR, no re-serialization),
timestamped with its receive time. The subscription of each topic mirrors its
publishers' QoS, as rosbag2 does: reliable and transient local where every
publisher is, so a latched ``trajectory`` is recorded too. Stops on Ctrl-C,
SIGTERM or after ``--duration``; exit 0, 2 on bad options, 1 if a topic never
appeared.
"""
from __future__ import annotations

import argparse
import importlib
import signal
import sys
import threading
import time
from pathlib import Path

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions

PROG = 'crane-record'
#: What ``crane-demo --record`` records (relative names resolve in the nodes' namespace).
DEFAULT_TOPICS = ('reference', 'joint_states', 'trajectory', '/diagnostics', 'crane_markers')


def message_class(type_name: str):
    """The rclpy message class of ``pkg/msg/Name``."""
    package, _, name = type_name.split('/')
    return getattr(importlib.import_module(f'{package}.msg'), name)


def mirrored_qos(publishers) -> QoSProfile:
    """A subscription QoS that matches every publisher: reliable / transient local only if all are."""
    reliable = bool(publishers) and all(p.qos_profile.reliability == ReliabilityPolicy.RELIABLE for p in publishers)
    latched = bool(publishers) and all(p.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL
                                       for p in publishers)
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1000,
                      reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE)


class Recorder:
    """Subscribes to ``topics`` on ``node`` and writes what arrives into an MCAP rosbag2 at ``out``.

    ``start(timeout)`` waits for every topic to have a publisher (its type is
    taken from there); ``close()`` ends the recording (metadata.yaml is
    written then). Counts per topic in ``counts``.
    """

    def __init__(self, node, topics, out):
        from rosbags.rosbag2 import StoragePlugin, Writer
        from rosbags.typesys import Stores, get_typestore
        self._node = node
        self.topics = [node.resolve_topic_name(t) for t in topics]
        self.out = Path(out)
        if self.out.exists():
            raise FileExistsError(f'{self.out} exists: rosbag2 recordings go into a new folder')
        self._typestore = get_typestore(Stores.ROS2_JAZZY)
        self._writer = Writer(self.out, version=9, storage_plugin=StoragePlugin.MCAP)
        self._writer.open()
        self._lock = threading.Lock()
        self._connections, self._subscriptions = {}, []
        self.counts = {}
        self._closed = False

    def start(self, timeout: float) -> list[str]:
        """Subscribe to every topic once it has a publisher; the topics still missing after ``timeout`` s."""
        deadline = time.monotonic() + timeout
        missing = list(self.topics)
        while missing:
            types = dict(self._node.get_topic_names_and_types())
            for topic in list(missing):
                if topic in types:
                    self._subscribe(topic, types[topic][0])
                    missing.remove(topic)
            if not missing or time.monotonic() > deadline:
                break
            time.sleep(0.05)
        return missing

    def _subscribe(self, topic: str, type_name: str):
        qos = mirrored_qos(self._node.get_publishers_info_by_topic(topic))
        with self._lock:
            self._connections[topic] = self._writer.add_connection(topic, type_name, typestore=self._typestore)
        self.counts[topic] = 0
        # the receive time on the system clock, as ROS time is here: a ROS Time object per message costs more
        self._subscriptions.append(self._node.create_subscription(
            message_class(type_name), topic, lambda data, t=topic: self._write(t, data, time.time_ns()),
            qos, raw=True))

    def _write(self, topic: str, data: bytes, received_ns: int):
        with self._lock:
            if self._closed:
                return
            self._writer.write(self._connections[topic], received_ns, data)
            self.counts[topic] += 1

    def close(self):
        with self._lock:
            if self._closed:
                return
            self._closed = True
            self._writer.close()


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog=PROG, description=__doc__.splitlines()[0].split(': ', 1)[1])
    p.add_argument('--topics', default=','.join(DEFAULT_TOPICS), metavar='T,T,...',
                   help=f'topics to record; relative names resolve in --namespace (default {",".join(DEFAULT_TOPICS)})')
    p.add_argument('--out', required=True, metavar='DIR', help='the recording folder to create')
    p.add_argument('--namespace', default='/', help='namespace relative topic names resolve in (default /)')
    p.add_argument('--duration', type=float, metavar='S', help='stop after S seconds (default: at Ctrl-C)')
    p.add_argument('--wait', type=float, default=10.0, metavar='S',
                   help='seconds to wait for every topic to have a publisher (default 10)')
    return p


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    topics = [t.strip() for t in args.topics.split(',') if t.strip()]
    if not topics:
        print(f'{PROG}: error: --topics names no topic', file=sys.stderr)
        return 2
    if args.duration is not None and not args.duration > 0:
        print(f'{PROG}: error: --duration must be > 0, got {args.duration}', file=sys.stderr)
        return 2
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('crane_record', namespace=args.namespace)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    recorder = None
    try:
        try:
            recorder = Recorder(node, topics, args.out)
        except (FileExistsError, OSError) as exc:
            print(f'{PROG}: error: {exc}', file=sys.stderr)
            return 2
        missing = recorder.start(args.wait)  # the graph is known without spinning: subscribe first
        if missing:
            print(f'{PROG}: error: no publisher of {", ".join(missing)} within {args.wait:g} s', file=sys.stderr)
            return 1
        def spin():
            while not stop.is_set():
                executor.spin_once(timeout_sec=0.1)
        spinner = threading.Thread(target=spin, daemon=True)
        spinner.start()
        print(f'{PROG}: recording {", ".join(recorder.topics)} into {args.out}', file=sys.stderr, flush=True)
        stop.wait(args.duration)
        stop.set()
        spinner.join(timeout=5.0)
        return 0
    finally:
        stop.set()
        if recorder is not None:
            recorder.close()
            print(f'{PROG}: ' + ', '.join(f'{t} {n}' for t, n in recorder.counts.items()), file=sys.stderr)
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    sys.exit(main())
