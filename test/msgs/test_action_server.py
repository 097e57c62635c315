"""crane_msgs_py.runtime.action_server: goal IDs format as hex, and the server is rclpy's otherwise (real DDS)."""
import uuid

import numpy as np

from crane_msgs_py.runtime.action_server import GoalId

from .action_graph import served, wait


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

    from crane_msgs_py.runtime.action_server import ActionServer
    seen = {}

    def accepted(goal):
        seen['accepted'] = goal.move.method
        return rclpy.action.GoalResponse.ACCEPT

    def execute(handle):
        seen['server_id'] = bytes(handle.goal_id.uuid)
        handle.succeed()
        return ExecuteMove.Result(success=True, message=handle.request.move.method)

    with served(ActionServer, ActionClient, 'goal_id', execute, SingleThreadedExecutor,
                goal_callback=accepted) as (_, client):
        rclpy.logging.set_logger_level('goal_id_server.action_server', rclpy.logging.LoggingSeverity.DEBUG)
        goal = ExecuteMove.Goal()
        goal.move.method = 'zv'
        handle = wait(client.send_goal_async(goal))
        assert handle.accepted
        result = wait(handle.get_result_async()).result
    assert result.success and result.message == 'zv' and seen['accepted'] == 'zv'
    assert seen['server_id'] == bytes(handle.goal_id.uuid)
    logged = capfd.readouterr().err
    hex_id = bytes(handle.goal_id.uuid).hex()
    assert f'New goal request with ID: {hex_id}' in logged and f'New goal accepted: {hex_id}' in logged
