"""crane_interfaces end to end: PlanMove and ExecuteMove between two processes over real DDS.

A server subprocess (the venv's Python, started from a clean environment: no LD_LIBRARY_PATH,
no PYTHONPATH, nothing sourced, as a user's shell starts .venv/bin/...) offers ``~/plan_move``
and ``~/execute_move`` as the planner's contract names them; this process is the client. Every
field crosses the wire through the generated type supports (make install builds the package;
the venv finds it through a .pth file and the ROS wheels' bootstrapper, see the Makefile).
"""
import math
import os
import signal
import subprocess
import sys
import time

import pytest

NS = '/iface_test'
NODE = 'crane_planner'

SERVER = '''
import math
import sys
import time

import rclpy
from builtin_interfaces.msg import Duration
from rclpy.action import ActionServer
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor
from trajectory_msgs.msg import JointTrajectoryPoint

from crane_interfaces.action import ExecuteMove
from crane_interfaces.msg import PlanInfo
from crane_interfaces.srv import PlanMove
from crane_msgs_py.runtime.dds import use_node_profiles


def info_for(move):
    """A made-up but checkable PlanInfo: the quintic's peaks for each joint's displacement."""
    d = [g - s for s, g in zip(move.start, move.goal)]
    T = move.duration
    return PlanInfo(method=move.method, duration=T, solve_time=0.25, iterations=4242,
                    joint_names=list(move.joint_names),
                    peak_velocity=[1.875 * abs(x) / T for x in d],
                    peak_acceleration=[5.7735 * abs(x) / T ** 2 for x in d],
                    peak_jerk=[60.0 * abs(x) / T ** 3 for x in d],
                    predicted_residual=float('nan'))


def plan(request, response):
    move = request.move
    response.success = True
    response.message = f'planned {move.method} for {",".join(move.joint_names)}'
    response.trajectory.header.stamp = move.start_time
    response.trajectory.header.frame_id = 'crane_base'
    response.trajectory.joint_names = list(move.joint_names)
    sec = int(move.duration)
    response.trajectory.points = [
        JointTrajectoryPoint(positions=list(move.start), velocities=[0.0] * len(move.start)),
        JointTrajectoryPoint(positions=list(move.goal), velocities=[0.0] * len(move.goal),
                             time_from_start=Duration(sec=sec, nanosec=int(round((move.duration - sec) * 1e9))))]
    response.info = info_for(move)
    return response


def main():
    use_node_profiles()  # as the planner's runner does
    rclpy.init()
    node = rclpy.create_node(NODE, namespace=NS)
    feedback_topic = f'{NS}/{NODE}/execute_move/_action/feedback'

    def execute(goal_handle):
        move = goal_handle.request.move
        deadline = time.monotonic() + 10.0  # the client's feedback subscription, discovered: none is lost
        while node.count_subscribers(feedback_topic) < 1 and time.monotonic() < deadline:
            time.sleep(0.01)
        goal_handle.publish_feedback(ExecuteMove.Feedback(progress=0.5, time_remaining=move.duration / 2,
                                                          swing=float('nan')))
        goal_handle.succeed()
        return ExecuteMove.Result(success=True, message=f'executed {move.method}', info=info_for(move),
                                  residual_swing=goal_handle.request.settle / 1000.0)

    node.create_service(PlanMove, '~/plan_move', plan)
    ActionServer(node, ExecuteMove, '~/execute_move', execute)
    print('ready', flush=True)
    executor = MultiThreadedExecutor(num_threads=2)
    executor.add_node(node)
    try:
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


NS, NODE = sys.argv[1], sys.argv[2]
main()
'''


def clean_env(ros_domain: dict) -> dict:
    """The private graph's environment minus what this (already bootstrapped) process added: the
    server starts as from a user's shell, so the venv alone must make crane_interfaces work."""
    env = dict(ros_domain)
    for name in ('_ROS_WHEELS_BOOTSTRAP_COMPLETE', 'LD_LIBRARY_PATH', 'PYTHONPATH', 'AMENT_PREFIX_PATH'):
        env.pop(name, None)
    return env


@pytest.fixture
def server(ros_domain, tmp_path):
    script = tmp_path / 'interfaces_server.py'
    script.write_text(SERVER)
    log_path = tmp_path / 'server.log'
    with open(log_path, 'w') as log:
        proc = subprocess.Popen([sys.executable, str(script), NS, NODE], env=clean_env(ros_domain),
                                stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    try:
        yield proc, log_path
    finally:  # always stopped: SIGINT to its group, then kill
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGINT)
            try:
                proc.wait(5)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait(5)


@pytest.fixture
def client_node(ros_domain):
    import rclpy
    rclpy.init()
    node = rclpy.create_node('interfaces_client', namespace=NS)
    try:
        yield node
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


def wait_until(node, done, proc, log_path, what, timeout=15.0):
    """Spin ``node`` until ``done()``; fail at once (with the server's log) if the server died."""
    import rclpy
    deadline = time.monotonic() + timeout
    while not done():
        assert proc.poll() is None, f'server exited ({proc.returncode}): {log_path.read_text()}'
        assert time.monotonic() < deadline, f'timed out waiting for {what}: {log_path.read_text()}'
        rclpy.spin_once(node, timeout_sec=0.05)


def make_move():
    from builtin_interfaces.msg import Time
    from crane_interfaces.msg import Move
    return Move(method='zvd', joint_names=['cart', 'hoist'], start=[0.0, 0.42], goal=[0.3, 0.5], duration=3.25,
                start_time=Time(sec=1_700_000_000, nanosec=123_456_789))


def check_info(info, move):
    assert info.method == move.method and info.duration == move.duration
    assert info.solve_time == 0.25 and info.iterations == 4242
    assert list(info.joint_names) == list(move.joint_names)
    d = [g - s for s, g in zip(move.start, move.goal)]
    assert list(info.peak_velocity) == pytest.approx([1.875 * abs(x) / move.duration for x in d])
    assert list(info.peak_acceleration) == pytest.approx([5.7735 * abs(x) / move.duration ** 2 for x in d])
    assert list(info.peak_jerk) == pytest.approx([60.0 * abs(x) / move.duration ** 3 for x in d])
    assert math.isnan(info.predicted_residual)


def test_plan_move_and_execute_move_over_dds(server, client_node):
    from action_msgs.msg import GoalStatus
    from crane_interfaces.action import ExecuteMove
    from crane_interfaces.srv import PlanMove
    from rclpy.action import ActionClient

    proc, log_path = server
    node = client_node
    base = f'{NS}/{NODE}'
    move = make_move()

    # PlanMove: a request/response round trip, every field checked.
    plan_client = node.create_client(PlanMove, f'{base}/plan_move')
    wait_until(node, plan_client.service_is_ready, proc, log_path, 'the plan_move service')
    future = plan_client.call_async(PlanMove.Request(move=move))
    wait_until(node, future.done, proc, log_path, 'the PlanMove response')
    response = future.result()
    assert response.success and response.message == 'planned zvd for cart,hoist'
    traj = response.trajectory
    assert traj.header.frame_id == 'crane_base'
    assert (traj.header.stamp.sec, traj.header.stamp.nanosec) == (1_700_000_000, 123_456_789)
    assert list(traj.joint_names) == ['cart', 'hoist']
    assert [list(p.positions) for p in traj.points] == [[0.0, 0.42], [0.3, 0.5]]
    assert (traj.points[-1].time_from_start.sec, traj.points[-1].time_from_start.nanosec) == (3, 250_000_000)
    check_info(response.info, move)

    # ExecuteMove: a goal, its feedback and its result.
    action_client = ActionClient(node, ExecuteMove, f'{base}/execute_move')
    feedback_topic = f'{base}/execute_move/_action/feedback'
    wait_until(node, lambda: action_client.server_is_ready() and node.count_publishers(feedback_topic) >= 1,
               proc, log_path, 'the execute_move action server')
    feedback = []
    goal_future = action_client.send_goal_async(ExecuteMove.Goal(move=move, settle=2.5),
                                                feedback_callback=lambda msg: feedback.append(msg.feedback))
    wait_until(node, goal_future.done, proc, log_path, 'the goal response')
    goal_handle = goal_future.result()
    assert goal_handle.accepted
    result_future = goal_handle.get_result_async()
    wait_until(node, result_future.done, proc, log_path, 'the ExecuteMove result')
    wait_until(node, lambda: feedback, proc, log_path, 'the ExecuteMove feedback', timeout=5.0)
    assert result_future.result().status == GoalStatus.STATUS_SUCCEEDED
    result = result_future.result().result
    assert result.success and result.message == 'executed zvd'
    assert result.residual_swing == pytest.approx(0.0025)
    check_info(result.info, move)
    [fb] = feedback
    assert fb.progress == 0.5 and fb.time_remaining == pytest.approx(1.625) and math.isnan(fb.swing)
    action_client.destroy()
    assert proc.poll() is None, log_path.read_text()
    # the nodes' Fast DDS profile (crane_msgs_py.runtime.dds) was loaded without a complaint, no answer was dropped
    assert 'XMLPARSER' not in log_path.read_text() and 'failed to send response' not in log_path.read_text()
