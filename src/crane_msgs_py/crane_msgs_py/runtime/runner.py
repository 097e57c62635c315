"""Running the crane nodes: ``main()``'s body, their loop threads, executors spun in the background.

``run`` is the body of every node's ``main()``: init, build, spin, clean shutdown.

SIGINT and SIGTERM only set a flag here, and the spin loop checks it between
short ``spin_once`` calls (so the node stops within one of them). rclpy's own
handlers would instead shut the context down from a signal thread, under a
node still being built or an executor in the middle of a wait, which can
end in an rcl error, a hang or a crash depending on timing. Either way the
process ends without a traceback: status 0, or 2 for a bad parameter
override.
"""
from __future__ import annotations

import signal
import sys
import threading
from collections.abc import Callable
from contextlib import contextmanager

import rclpy
from rclpy.exceptions import InvalidHandle, InvalidParameterTypeException, InvalidParameterValueException
from rclpy.signals import SignalHandlerOptions

from crane_msgs_py.crane.params import ParameterError
from crane_msgs_py.runtime.dds import use_node_profiles
from crane_msgs_py.runtime.realtime import die_with_parent, set_fifo, set_threads_fifo, tune_thread


def run(node_class, executor_class, args=None, **executor_kwargs) -> int:
    """Spin ``node_class()`` on ``executor_class(**executor_kwargs)`` until a signal; the exit status.

    A keyword value that is callable is called with the built node (e.g. a
    thread count that depends on the node's parameters).
    """
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    die_with_parent()
    use_node_profiles()  # (before the middleware starts: it reads its profiles once)
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    node = executor = None
    status = 0
    try:
        node = node_class()
        executor = executor_class(**{k: v(node) if callable(v) else v for k, v in executor_kwargs.items()})
        executor.add_node(node)
        spin = Spin(executor, 0.1)
        while not stop.is_set() and rclpy.ok():
            spin()
    except KeyboardInterrupt:
        pass
    except (ParameterError, InvalidParameterValueException, InvalidParameterTypeException) as exc:
        # a bad value in --params-file or -p
        print(f'{getattr(node_class, "__name__", "node")}: {exc}', file=sys.stderr, flush=True)
        status = 2
    except Exception:
        if not stop.is_set():
            raise
    finally:
        if executor is not None:
            executor.shutdown()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return status


#: How many spins in a row may fail to gather their wait set (``spin_once``) before the failure is raised: a
#: destroyed entity is gone from the next gathering, so one that keeps failing is a fault, not that race.
GATHER_FAILURES = 100


def spin_once(executor, timeout_sec: float) -> bool:
    """``executor.spin_once``, unharmed by an entity destroyed on another thread meanwhile; False if its wait
    set could not be gathered because of that.

    rclpy's executor lists a node's entities, then adds each to its wait set;
    a subscription destroyed in between raises InvalidHandle there (from its
    QoS event handlers: ros2/rclpy#1284), which would end a spin loop for
    good and leave every later response and message unread. The next call
    lists the entities again, without the destroyed one. An InvalidHandle
    from anywhere else (a callback using a destroyed entity) is raised.
    """
    try:
        executor.spin_once(timeout_sec=timeout_sec)
    except InvalidHandle as exc:
        tb = exc.__traceback__
        while tb is not None and tb.tb_frame.f_code.co_name != 'add_to_wait_set':
            tb = tb.tb_next
        if tb is None:
            raise
        return False
    return True


class Spin:
    """Repeated ``spin_once`` calls (``__call__``) that count the wait sets in a row they could not gather,
    and raise once there are ``GATHER_FAILURES`` of them."""

    def __init__(self, executor, timeout_sec: float):
        self.executor, self.timeout_sec = executor, timeout_sec
        self.failures = 0

    def __call__(self) -> None:
        if spin_once(self.executor, self.timeout_sec):
            self.failures = 0
            return
        self.failures += 1
        if self.failures >= GATHER_FAILURES:
            raise RuntimeError(f'the executor could not gather its wait set {self.failures} times in a row '
                               '(an entity destroyed but still listed by its node)')


class LoopThread:
    """A node's fixed-rate loop (``crane_msgs_py.runtime.realtime``) on a thread of its own.

    Started by a one-shot timer once the executor spins: until then the main
    thread holds the GIL for long stretches. With ``priority`` > 0 the loop
    runs SCHED_FIFO at that priority, the executor thread that feeds it
    just below (preempted by an ordinary process while holding the GIL it
    would stall the loop, starved by the loop it would drop input) and the
    middleware's receive threads that feed the executor below that (at
    normal priority a message waits for a core, behind whatever else a
    loaded machine runs, before the executor sees it). A failure
    is logged and kept in ``error`` (for the node's diagnostics) instead of
    ending the thread unseen. ``stopping`` is set by ``stop()``; the loop
    checks it.
    """

    def __init__(self, node, target, name: str, priority: int = 0):
        self._node, self._target, self.priority = node, target, priority
        self.error = ''
        self.stopping = threading.Event()
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._kickoff = node.create_timer(0.05, self._start)

    def _start(self):  # on the executor's thread
        self._kickoff.cancel()
        if self._thread.ident is None:
            if self.priority > 1:
                for warning in tune_thread(self.priority - 1):
                    self._node.get_logger().warn(f'executor thread: {warning}')
            if self.priority > 2:
                _, refused = set_threads_fifo(self.priority - 2)
                if refused:
                    self._node.get_logger().warn(f'middleware receive threads: {refused}')
            self._thread.start()

    def _run(self):
        for warning in tune_thread(self.priority):
            self._node.get_logger().warn(warning)
        try:
            self._target()
        except Exception as exc:  # reported by the node (log, /diagnostics), which stays up
            self.error = f'{type(exc).__name__}: {exc}'
            self._node.get_logger().error(f'the loop stopped: {self.error}')

    def stop(self, timeout: float = 2.0):
        self.stopping.set()
        if self._thread.ident is not None:
            self._thread.join(timeout)


@contextmanager
def spinning(executor, priority: Callable[[], int] | None = None, refused: Callable[[str], None] | None = None):
    """Spin ``executor`` on a background thread for the duration of the block.

    Short ``spin_once`` calls until the block ends, then the thread is joined
    before the executor is shut down: an executor's own ``spin()`` shut down
    from another thread can abort the process (rclpy) or deadlock (the
    EventsExecutor, which also takes no new entities while spinning: add
    everything first). ``priority``: the thread's SCHED_FIFO priority (0:
    normal), read before every ``spin_once`` and applied when it changes
    (``realtime.set_fifo``); ``refused`` is told why it could not be.
    """
    stop = threading.Event()

    def run_spin():
        applied, spin = 0, Spin(executor, 0.05)
        while not stop.is_set():
            wanted = applied if priority is None else priority()
            if wanted != applied:
                applied = wanted
                reason = set_fifo(applied)
                if reason and refused is not None:
                    refused(reason)
            spin()

    thread = threading.Thread(target=run_spin, name='spin', daemon=True)
    thread.start()
    try:
        yield executor
    finally:
        stop.set()
        thread.join()
        executor.shutdown()
