"""crane_msgs_py.runner.spinning: a background spin survives an entity destroyed while its executor gathers
the wait set (rclpy raises InvalidHandle there, ros2/rclpy#1284), and goes on serving the node."""
import threading
import time


def _node_with_a_timer(context, name: str):
    import rclpy
    node = rclpy.create_node(name, context=context)
    ticks = []
    node.create_timer(0.01, lambda: ticks.append(time.monotonic()))
    return node, ticks


def _ticks_after(ticks: list, t0: float, count: int, within: float) -> int:
    deadline = time.monotonic() + within
    while time.monotonic() < deadline and sum(t > t0 for t in ticks) < count:
        time.sleep(0.01)
    return sum(t > t0 for t in ticks)


def test_a_waitable_destroyed_while_the_wait_set_is_gathered_does_not_end_the_spin(ros_domain):
    """The failure itself, made certain: a waitable whose handle is gone raises InvalidHandle as the executor
    adds it to the wait set, as a destroyed subscription's event handler does; it is then removed, as
    ``destroy_subscription`` removes it. The spin thread goes on: the node's timer keeps firing."""
    import rclpy
    from rclpy.exceptions import InvalidHandle
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.waitable import NumberOfEntities, Waitable

    from crane_msgs_py.runner import spinning
    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        node, ticks = _node_with_a_timer(context, 'spin_survives')
        raised = threading.Event()

        class Destroyed(Waitable):
            def __init__(self):
                super().__init__(node.default_callback_group)

            def get_num_entities(self):
                return NumberOfEntities()

            def add_to_wait_set(self, wait_set):
                node.remove_waitable(self)  # (what destroy_subscription does, a moment too late)
                raised.set()
                raise InvalidHandle('cannot use Destroyable because destruction was requested')

            def is_ready(self, wait_set):
                return False

            def take_data(self):
                return None

            async def execute(self, taken_data):
                return None

        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        with spinning(executor):
            assert _ticks_after(ticks, 0.0, 3, 10.0) >= 3
            node.add_waitable(Destroyed())
            executor.wake()
            assert raised.wait(10.0)
            t0 = time.monotonic()
            assert _ticks_after(ticks, t0, 5, 10.0) >= 5, 'the spin thread ended'
        node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)
