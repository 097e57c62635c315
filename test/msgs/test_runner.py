"""crane_msgs_py.runtime.runner's spins: a background spin survives an entity destroyed while its executor gathers the
wait set (rclpy raises InvalidHandle there, ros2/rclpy#1284) and goes on serving the node; an InvalidHandle
from a callback, and a wait set that can never be gathered, are still raised."""
import time
from contextlib import contextmanager

import pytest


@contextmanager
def node_and_executor(name: str):
    """A node with a 100 Hz timer on a SingleThreadedExecutor of a context of its own: (node, executor, ticks)."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    context = rclpy.Context()
    rclpy.init(context=context)
    node = executor = None
    try:
        node = rclpy.create_node(name, context=context)
        ticks = []
        node.create_timer(0.01, lambda: ticks.append(time.monotonic()))
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        yield node, executor, ticks
    finally:
        if executor is not None:
            executor.shutdown()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown(context=context)


def destroyed_waitable(node, remove: bool):
    """A waitable whose handle is gone: adding it to a wait set raises InvalidHandle, as a destroyed
    subscription's QoS event handler does; ``remove``: it leaves the node first, as ``destroy_subscription``
    removes it (a moment too late for the executor's gathering)."""
    from rclpy.exceptions import InvalidHandle
    from rclpy.waitable import NumberOfEntities, Waitable

    class Destroyed(Waitable):
        raised = 0

        def __init__(self):
            super().__init__(node.default_callback_group)

        def get_num_entities(self):
            return NumberOfEntities()

        def add_to_wait_set(self, wait_set):
            if remove:
                node.remove_waitable(self)
            Destroyed.raised += 1
            raise InvalidHandle('cannot use Destroyable because destruction was requested')

        def is_ready(self, wait_set):
            return False

        def take_data(self):
            return None

        async def execute(self, taken_data):
            return None
    return Destroyed()


def _ticks_after(ticks: list, t0: float, count: int, within: float) -> int:
    deadline = time.monotonic() + within
    while time.monotonic() < deadline and sum(t > t0 for t in ticks) < count:
        time.sleep(0.01)
    return sum(t > t0 for t in ticks)


def test_a_waitable_destroyed_while_the_wait_set_is_gathered_does_not_end_the_spin(ros_domain):
    """The failure made certain: the spin thread meets it once, and goes on: the node's timer keeps firing."""
    from crane_msgs_py.runtime.runner import spinning
    with node_and_executor('spin_survives') as (node, executor, ticks), spinning(executor):
        assert _ticks_after(ticks, 0.0, 3, 10.0) >= 3
        waitable = destroyed_waitable(node, remove=True)
        node.add_waitable(waitable)
        executor.wake()
        deadline = time.monotonic() + 10.0
        while not waitable.raised and time.monotonic() < deadline:
            time.sleep(0.01)
        assert waitable.raised == 1
        assert _ticks_after(ticks, time.monotonic(), 5, 10.0) >= 5, 'the spin thread ended'


def test_an_invalid_handle_in_a_callback_and_a_wait_set_never_gathered_are_raised(ros_domain):
    """Only the gathering's race is passed over: a callback's InvalidHandle (a destroyed entity used) is the
    callback's fault, and an entity that stays listed after its destruction fails every gathering."""
    from rclpy.exceptions import InvalidHandle

    from crane_msgs_py.runtime.runner import GATHER_FAILURES, Spin, spin_once
    with node_and_executor('spin_raises') as (node, executor, _):
        def use_a_destroyed_entity():
            raise InvalidHandle('cannot use Destroyable because destruction was requested')
        timer = node.create_timer(0.001, use_a_destroyed_entity)
        with pytest.raises(InvalidHandle):
            for _ in range(100):
                spin_once(executor, 0.05)
        node.destroy_timer(timer)
        waitable = destroyed_waitable(node, remove=False)
        node.add_waitable(waitable)
        spin = Spin(executor, 0.01)
        with pytest.raises(RuntimeError, match=f'could not gather its wait set {GATHER_FAILURES} times'):
            for _ in range(GATHER_FAILURES):
                spin()
        assert waitable.raised == GATHER_FAILURES
        node.remove_waitable(waitable)
