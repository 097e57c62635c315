"""crane_msgs_py.runtime.action_client: a response that comes back while its request is still being registered is not
lost (ros2/rclpy#1123), over real DDS with the executor spinning on a thread of its own."""
import threading
import time

from .action_graph import served, wait


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
    from crane_interfaces.action import ExecuteMove
    from rclpy.action import CancelResponse, GoalResponse
    from rclpy.executors import MultiThreadedExecutor

    from crane_msgs_py.runtime.action_client import ActionClient
    from crane_msgs_py.runtime.action_server import ActionServer
    release = threading.Event()

    def execute(handle):
        release.wait(10.0)
        if handle.is_cancel_requested:
            handle.canceled()
            return ExecuteMove.Result(success=False, message='canceled')
        handle.succeed()
        return ExecuteMove.Result(success=True, message=handle.request.move.method)

    with served(ActionServer, ActionClient, 'register', execute, lambda context: MultiThreadedExecutor(
            num_threads=4, context=context), goal_callback=lambda goal: GoalResponse.ACCEPT,
            cancel_callback=lambda handle: CancelResponse.ACCEPT) as (_, client):
        client._client_handle = _SlowToRegister(client._client_handle)
        goal = ExecuteMove.Goal()
        goal.move.method = 'zv'
        try:
            first = wait(client.send_goal_async(goal))  # its response came within the pause
            assert first.accepted
            result = first.get_result_async()  # sent while the goal still runs
            second = wait(client.send_goal_async(goal))
            canceled = wait(second.cancel_goal_async())
            assert len(canceled.goals_canceling) == 1
        finally:
            release.set()  # (also before the executor's shutdown waits for the goals)
        assert wait(result).result.success
        assert wait(second.get_result_async()).result.message == 'canceled'
