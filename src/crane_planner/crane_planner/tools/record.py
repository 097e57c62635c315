"""``crane-record``: record topics of a running setup into a rosbag2 recording in MCAP storage.

What ``ros2 bag record -s mcap`` makes (a folder with ``metadata.yaml`` and the
``.mcap`` file), written with the ``rosbags`` library, for machines without a
ROS install. Each message is stored as received (CDR, no re-serialization),
timestamped with its receive time. The subscription of each topic mirrors its
publishers' QoS, as rosbag2 does: reliable and transient local where every
publisher is, so a latched ``trajectory`` is recorded too. Stops on Ctrl-C,
SIGTERM or after ``--duration``; exit 0, 2 on bad options, 1 if a topic never
appeared.

Why no executor: rclpy's executor rebuilds its wait set and runs Python for
every message, which for the 1 kHz ``reference`` costs a large share of a core
beside the streamer and the sim (``bench/recorder.py``). The recorder instead
drains each subscription's queue in batches every ``DRAIN_PERIOD`` (one wake-up
per period, however many messages arrived): a fraction of that, the same messages. Each
is stamped with the middleware's own reception time, so batching does not
blur the receive times; the middleware's receive threads, which take those
times, run at SCHED_FIFO ``--priority`` so a busy machine does not delay them.
"""
from __future__ import annotations

import argparse
import importlib
import math
import signal
import sys
import threading
import time
from pathlib import Path

import rclpy
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rclpy.type_support import check_for_type_support

from crane_msgs_py.runtime.realtime import die_with_parent, set_threads_fifo
from crane_msgs_py.runtime.taking import take_all
from crane_planner.runway.config import OCCUPANCY_TOPIC, STATE_TOPIC

PROG = 'crane-record'
#: What ``crane-demo --record`` records (relative names resolve in the nodes' namespace).
DEFAULT_TOPICS = ('reference', 'joint_states', 'trajectory', '/diagnostics', 'crane_markers')
#: What ``--runway`` adds: every crane's occupancy and live state on a shared runway (global names).
RUNWAY_TOPICS = (OCCUPANCY_TOPIC, STATE_TOPIC)
#: Seconds between two drains of the subscriptions' queues: 10 messages of a 1 kHz topic per drain.
DRAIN_PERIOD = 0.01
#: SCHED_FIFO priority of the middleware's receive threads by default: they stamp each message's receive
#: time, and at normal priority a busy machine delays them by several ticks of a 1 kHz topic.
PRIORITY = 30
#: Queue depth of every recorded subscription: 2 s of a 1 kHz topic, so a recorder that is
#: descheduled for a while (a busy machine) still finds every message when it drains.
QUEUE_DEPTH = 2000


def message_class(type_name: str):
    """The rclpy message class of ``pkg/msg/Name``."""
    package, _, name = type_name.split('/')
    return getattr(importlib.import_module(f'{package}.msg'), name)


def mirrored_qos(publishers) -> QoSProfile:
    """A subscription QoS that matches every publisher: reliable / transient local only if all are."""
    reliable = bool(publishers) and all(p.qos_profile.reliability == ReliabilityPolicy.RELIABLE for p in publishers)
    latched = bool(publishers) and all(p.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL
                                       for p in publishers)
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=QUEUE_DEPTH,
                      reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE)


class Recorder:
    """Subscribes to ``topics`` on ``node`` and writes what arrives into an MCAP rosbag2 at ``out``.

    ``start(timeout)`` waits for every topic to have a publisher (its type is
    taken from there); ``drain()`` writes every message queued since the last
    call (the node is never spun: its subscriptions are only drained);
    ``close()`` ends the recording (metadata.yaml is written then). Messages
    per topic in ``counts``; in ``lost``, for a topic with one publisher, the
    messages it published that never arrived (gaps in its sequence numbers).
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
        self._connections, self._subscriptions, self._expected = {}, {}, {}
        self.counts, self.lost = {}, {}
        self._last_sequence = {}
        self._closed = False

    #: How long (s) the publishers of every topic must stay the same before subscribing (see ``start``).
    graph_settle = 0.5

    def start(self, timeout: float) -> list[str]:
        """Wait for every topic to have publishers and the graph to settle, subscribe, and wait for the
        subscriptions to match their publishers; the topics without a publisher after ``timeout`` s.

        Why wait for the graph to settle: while this process still discovers
        the graph (its first moments), Fast DDS may deliver nothing to its
        readers for a while, then the queued samples all at once, stamped with
        receive times that late. The topic list is also incomplete then (a topic
        seen through its subscribers only: no publisher to match yet).
        """
        deadline = time.monotonic() + timeout
        seen, stable_since = None, time.monotonic()
        while time.monotonic() < deadline:
            types = dict(self._node.get_topic_names_and_types())
            now = {t: (types[t][0], len(self._node.get_publishers_info_by_topic(t))) for t in self.topics if t in types}
            if now != seen:
                seen, stable_since = now, time.monotonic()
            elif (all(t in now and now[t][1] > 0 for t in self.topics)
                  and time.monotonic() - stable_since >= self.graph_settle):
                break
            time.sleep(0.05)
        missing = [t for t in self.topics if t not in (seen or {}) or seen[t][1] == 0]
        present = [t for t in self.topics if t not in missing]
        # Every message class imported and its type support loaded before the first subscription:
        # doing so between two subscriptions (slow on a busy machine) holds up the delivery to the
        # subscriptions already made, whose first samples then arrive late.
        classes = {t: message_class(seen[t][0]) for t in present}
        for cls in classes.values():
            check_for_type_support(cls)
        for topic in present:
            self._subscribe(topic, seen[topic][0], classes[topic])
        # A subscription in the graph is not yet matched with its publishers: what they publish
        # before the match is lost (the demo's first trajectory, say). Recording starts
        # when every subscription counts the publishers the graph showed.
        while time.monotonic() < deadline and any(
                sub.get_publisher_count() < self._expected[topic] for topic, sub in self._subscriptions.items()):
            time.sleep(0.01)
        return missing

    def _subscribe(self, topic: str, type_name: str, cls):
        publishers = self._node.get_publishers_info_by_topic(topic)
        register_type(self._typestore, type_name)
        with self._lock:
            self._connections[topic] = self._writer.add_connection(topic, type_name, typestore=self._typestore)
            self.counts[topic] = 0
            self._expected[topic] = len(publishers)
            if len(publishers) == 1:  # sequence numbers are per publisher: gaps mean something only for one
                self.lost[topic], self._last_sequence[topic] = 0, None
            # the callback never runs (the node is not spun): drain() takes the messages
            self._subscriptions[topic] = self._node.create_subscription(
                cls, topic, lambda _: None, mirrored_qos(publishers), raw=True)

    def drain(self) -> int:
        """Write every message queued on every subscription; how many were written.

        Each is stamped with its reception time in the middleware (system
        clock, ns), not the time it is taken here.
        """
        written = 0
        with self._lock:
            if self._closed:
                return 0
            for topic, sub in self._subscriptions.items():
                connection = self._connections[topic]
                for data, info in take_all(sub):
                    self._writer.write(connection, info['received_timestamp'], data)
                    self.counts[topic] += 1
                    written += 1
                    if topic in self.lost:
                        self._count_gap(topic, info['publication_sequence_number'])
        return written

    def _count_gap(self, topic: str, sequence: int):
        last = self._last_sequence[topic]
        if last is not None and sequence > last + 1:
            self.lost[topic] += sequence - last - 1
        self._last_sequence[topic] = sequence if last is None else max(last, sequence)

    def summary(self) -> str:
        """``topic N (lost M), ...``: what was recorded."""
        return ', '.join(f'{t} {n}' + (f' (lost {self.lost[t]})' if t in self.lost else '')
                         for t, n in self.counts.items())

    def close(self):
        """Write what is still queued, then end the recording."""
        self.drain()
        with self._lock:
            if self._closed:
                return
            self._closed = True
            self._writer.close()


def register_type(typestore, type_name: str) -> None:
    """Teach ``typestore`` a message type it lacks (rosbags knows the ROS 2 distribution's, not this project's
    crane_interfaces): its definition from the package's installed ``.msg``, in the share folder of the prefix its
    Python module lies in (``<prefix>/lib/pythonX.Y/site-packages/<package>``)."""
    if type_name in typestore.fielddefs:
        return
    from rosbags.typesys import get_types_from_msg
    package, _, name = type_name.split('/')
    prefix = Path(importlib.import_module(package).__file__).resolve().parents[4]
    typestore.register(get_types_from_msg((prefix / 'share' / package / 'msg' / f'{name}.msg').read_text(),
                                          type_name))


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog=PROG, description=__doc__.splitlines()[0].split(': ', 1)[1])
    p.add_argument('--topics', default=','.join(DEFAULT_TOPICS), metavar='T,T,...',
                   help=f'topics to record; relative names resolve in --namespace (default {",".join(DEFAULT_TOPICS)})')
    p.add_argument('--runway', action='store_true',
                   help=f'also record {" and ".join(RUNWAY_TOPICS)} (cranes sharing a runway: every crane\'s)')
    p.add_argument('--out', required=True, metavar='DIR', help='the recording folder to create')
    p.add_argument('--namespace', default='/', help='namespace relative topic names resolve in (default /)')
    p.add_argument('--duration', type=float, metavar='S', help='stop after S seconds (default: at Ctrl-C)')
    p.add_argument('--wait', type=float, default=10.0, metavar='S',
                   help='seconds to wait for every topic to have a publisher (default 10)')
    p.add_argument('--priority', type=int, default=PRIORITY, metavar='P',
                   help='SCHED_FIFO priority 1..99 of the middleware\'s receive threads, which stamp each message\'s '
                        f'receive time (default {PRIORITY}; 0 = normal scheduling; without the privilege a warning)')
    return p


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    topics = [t.strip() for t in args.topics.split(',') if t.strip()]
    topics += [t for t in RUNWAY_TOPICS if args.runway and t not in topics]
    if not topics:
        print(f'{PROG}: error: --topics names no topic', file=sys.stderr)
        return 2
    if args.duration is not None and not args.duration > 0:
        print(f'{PROG}: error: --duration must be > 0, got {args.duration}', file=sys.stderr)
        return 2
    if not 0 <= args.priority <= 99:
        print(f'{PROG}: error: --priority must be 0..99, got {args.priority}', file=sys.stderr)
        return 2
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    die_with_parent()
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    # never spun (see the module doc), so it offers no parameter services that could not answer
    node = rclpy.create_node('crane_record', namespace=args.namespace, start_parameter_services=False)
    _, refused = set_threads_fifo(args.priority)
    if refused:
        print(f'{PROG}: warning: the middleware\'s receive threads: {refused}; receive times may lag on a busy '
              'machine', file=sys.stderr)
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
        print(f'{PROG}: recording {", ".join(recorder.topics)} into {args.out}', file=sys.stderr, flush=True)
        end = math.inf if args.duration is None else time.monotonic() + args.duration
        while not stop.wait(DRAIN_PERIOD) and time.monotonic() < end:
            recorder.drain()
        return 0
    finally:
        stop.set()
        if recorder is not None:
            recorder.close()
            print(f'{PROG}: {recorder.summary()}', file=sys.stderr)
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    sys.exit(main())
