"""crane_msgs_py.action_client: a response that comes back while its request is still being registered is not
lost (ros2/rclpy#1123), over real DDS with the executor spinning on a thread of its own."""
import threading
import time


class _SlowToRegister:
    """The client's rcl handle, which pauses after sending each request: the window in which rclpy 7.1's
    ActionClient has sent a request but not yet registered it, widened from microseconds to 0.2 s."""

    def __init__(self, handle, pause: float = 0.2):
        self._handle, self._pause = handle, pause

    def __getattr__(self, name):
        attr = getattr(self._handle, name)
        if not name.startswith('send_'):
            return attr

        def sent(*args):
            sequence = attr(*args)
            time.sleep(self._pause)  # the response arrives and the executor thread handles it meanwhile
            return sequence
        return sent

    def __enter__(self):
        return self._handle.__enter__()

    def __exit__(self, *exc):
        return self._handle.__exit__(*exc)


def test_goal_cancel_and_result_responses_arriving_before_registration_complete_their_futures(ros_domain):
    import rclpy
    from crane_interfaces.action import ExecuteMove
    from rclpy.action import CancelResponse, GoalResponse
    from rclpy.executors import MultiThreadedExecutor

    from crane_msgs_py.action_client import ActionClient
    from crane_msgs_py.action_server import ActionServer

    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        server_node = rclpy.create_node('register_server', context=context)
        client_node = rclpy.create_node('register_client', context=context)
        release = threading.Event()

        def execute(handle):
            release.wait(10.0)
            if handle.is_cancel_requested:
                handle.canceled()
                return ExecuteMove.Result(success=False, message='canceled')
            handle.succeed()
            return ExecuteMove.Result(success=True, message=handle.request.move.method)

        server = ActionServer(server_node, ExecuteMove, 'register_test', execute,
                              goal_callback=lambda goal: GoalResponse.ACCEPT,
                              cancel_callback=lambda handle: CancelResponse.ACCEPT)
        client = ActionClient(client_node, ExecuteMove, 'register_test')
        executor = MultiThreadedExecutor(num_threads=4, context=context)
        executor.add_node(server_node)
        executor.add_node(client_node)
        stop = threading.Event()
        spin = threading.Thread(target=lambda: [executor.spin_once(0.05) for _ in iter(stop.is_set, True)])
        spin.start()
        try:
            assert client.wait_for_server(timeout_sec=20.0)
            client._client_handle = _SlowToRegister(client._client_handle)
            goal = ExecuteMove.Goal()
            goal.move.method = 'zv'
            first = _wait(client.send_goal_async(goal))  # its response came within the pause
            assert first.accepted
            result = first.get_result_async()  # sent while the goal still runs
            second = _wait(client.send_goal_async(goal))
            canceled = _wait(second.cancel_goal_async())
            assert len(canceled.goals_canceling) == 1
            release.set()
            assert _wait(result).result.success
            assert _wait(second.get_result_async()).result.message == 'canceled'
        finally:
            release.set()
            stop.set()
            spin.join()
            server.destroy()
            client.destroy()
            executor.shutdown()
    finally:
        rclpy.shutdown(context=context)


def _wait(future, timeout: float = 10.0):
    event = threading.Event()
    future.add_done_callback(lambda _: event.set())
    assert event.wait(timeout), 'the future never completed (its response was dropped)'
    return future.result()
