"""The body of every crane node's ``main()``: init, build, spin, clean shutdown.

SIGINT and SIGTERM (rclpy's own handlers) end the spin; a signal that comes
while the node is still being built shuts the context down under it, so an
rcl error then is the shutdown, not a fault. Either way the process ends
without a traceback: status 0, or 2 for a bad parameter override.
"""
from __future__ import annotations

import sys

import rclpy
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.executors import ExternalShutdownException

from .params import ParameterError


def run(node_class, executor_class, args=None, **executor_kwargs) -> int:
    """Spin ``node_class()`` on ``executor_class(**executor_kwargs)`` until shut down; the exit status."""
    rclpy.init(args=args)
    node = executor = None
    status = 0
    try:
        node = node_class()
        executor = executor_class(**executor_kwargs)
        executor.add_node(node)
        # Not executor.spin(): a signal that lands while another thread holds
        # the GIL can shut the context down without waking an endless wait.
        while rclpy.ok():
            executor.spin_once(timeout_sec=0.25)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (ParameterError, InvalidParameterValueException, InvalidParameterTypeException) as exc:
        # a bad value in --params-file or -p
        print(f'{getattr(node_class, "__name__", "node")}: {exc}', file=sys.stderr, flush=True)
        status = 2
    except Exception:
        if rclpy.ok():
            raise
    finally:
        if executor is not None:
            executor.shutdown()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return status
