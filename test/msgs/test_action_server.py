"""crane_msgs_py.action_server: goal IDs format as hex, and the server is rclpy's otherwise (real DDS)."""
import threading
import uuid

import numpy as np

from crane_msgs_py.action_server import GoalId


def test_a_goal_id_formats_as_its_hex_digits_and_keeps_its_bytes():
    raw = uuid.UUID('0123456789abcdef0011223344556677')
    ids = np.frombuffer(raw.bytes, dtype=np.uint8).copy()
    view = ids.view(GoalId)
    assert f'{view}' == '{0}'.format(view) == raw.hex
    assert f'{view:>34}' == '  ' + raw.hex
    assert bytes(view) == raw.bytes and view.dtype == np.uint8 and view.size == 16
    assert str(view) == str(ids)  # only formatting changes


def test_the_server_accepts_executes_and_logs_the_client_s_goal_id_in_hex(ros_domain, capfd):
    import rclpy
    from crane_interfaces.action import ExecuteMove
    from rclpy.action import ActionClient
    from rclpy.executors import SingleThreadedExecutor

    from crane_msgs_py.action_server import ActionServer

    context = rclpy.Context()
    rclpy.init(context=context)
    seen = {}
    try:
        server_node = rclpy.create_node('goal_id_server', context=context)
        client_node = rclpy.create_node('goal_id_client', context=context)

        def accepted(goal):
            seen['accepted'] = goal.move.method
            return rclpy.action.GoalResponse.ACCEPT

        def execute(handle):
            seen['server_id'] = bytes(handle.goal_id.uuid)
            handle.succeed()
            return ExecuteMove.Result(success=True, message=handle.request.move.method)

        server = ActionServer(server_node, ExecuteMove, 'goal_id_test', execute, goal_callback=accepted)
        rclpy.logging.set_logger_level('goal_id_server.action_server', rclpy.logging.LoggingSeverity.DEBUG)
        client = ActionClient(client_node, ExecuteMove, 'goal_id_test')
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(server_node)
        executor.add_node(client_node)
        stop = threading.Event()
        spin = threading.Thread(target=lambda: [executor.spin_once(0.05) for _ in iter(stop.is_set, True)])
        spin.start()
        try:
            assert client.wait_for_server(timeout_sec=20.0)
            goal = ExecuteMove.Goal()
            goal.move.method = 'zv'
            sent = client.send_goal_async(goal)
            handle = _wait(sent)
            assert handle.accepted
            result = _wait(handle.get_result_async()).result
        finally:
            stop.set()
            spin.join()
            server.destroy()
            client.destroy()
            executor.shutdown()
        assert result.success and result.message == 'zv' and seen['accepted'] == 'zv'
        assert seen['server_id'] == bytes(handle.goal_id.uuid)
        logged = capfd.readouterr().err
        hex_id = bytes(handle.goal_id.uuid).hex()
        assert f'New goal request with ID: {hex_id}' in logged and f'New goal accepted: {hex_id}' in logged
    finally:
        rclpy.shutdown(context=context)


def _wait(future, timeout: float = 20.0):
    event = threading.Event()
    future.add_done_callback(lambda _: event.set())
    assert event.wait(timeout), 'no answer from the action server'
    return future.result()
