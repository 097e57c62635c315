"""The body of every crane node's ``main()``: init, build, spin, clean shutdown.

SIGINT and SIGTERM only set a flag here, and the spin loop checks it between
short ``spin_once`` calls (so the node stops within 0.1 s). rclpy's own
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

import rclpy
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.signals import SignalHandlerOptions

from .params import ParameterError


def run(node_class, executor_class, args=None, **executor_kwargs) -> int:
    """Spin ``node_class()`` on ``executor_class(**executor_kwargs)`` until a signal; the exit status."""
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    node = executor = None
    status = 0
    try:
        node = node_class()
        executor = executor_class(**executor_kwargs)
        executor.add_node(node)
        while not stop.is_set() and rclpy.ok():
            executor.spin_once(timeout_sec=0.1)
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
