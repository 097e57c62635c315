"""Calling the planner from another node: preview a move with PlanMove, then execute it with ExecuteMove.

A complete rclpy client that uses nothing of this project but its interfaces
(``crane_interfaces``), as a node of yours would:

    .venv/bin/python examples/execute_move.py --goal 0.3 --duration 3 --method rvf --ros-args -r __ns:=/crane

The move starts where the streamer holds the cart (``start`` left empty);
``--duration 0`` asks for the fastest move within the planner's axis limits.
``--json`` prints one JSON object per line (the preview, each feedback, the
result) instead of text. The test suite runs this file as it is
(test/ros/test_integration.py).

Both clients find their servers first, and only then is ``--delay`` counted:
discovering a node takes a new process a few hundred milliseconds (more on a
busy machine), and a start time taken before it would be partly spent by the
time the goal arrives.
"""
import argparse
import json
import sys

import rclpy
from crane_interfaces.action import ExecuteMove
from crane_interfaces.msg import Move
from crane_interfaces.srv import PlanMove
from rclpy.action import ActionClient
from rclpy.duration import Duration
from rclpy.utilities import remove_ros_args


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description='Preview, then execute a move of the crane.')
    parser.add_argument('--goal', type=float, required=True, help='cart goal position (m)')
    parser.add_argument('--duration', type=float, default=0.0, help='s; 0 = the fastest within the limits')
    parser.add_argument('--method', default='', help="nvf, rvf, zv, ...; '' = the planner's default")
    parser.add_argument('--settle', type=float, default=0.0, help='s watched after the motion (0 = 2 s)')
    parser.add_argument('--delay', type=float, default=0.0, help='start this long (s) from now; 0 = at once')
    parser.add_argument('--planner', default='crane_planner', help='the planner node, in this namespace')
    parser.add_argument('--json', action='store_true', help='JSON lines instead of text')
    args = parser.parse_args(remove_ros_args(argv if argv is not None else sys.argv)[1:])

    def say(kind: str, text: str, **values):
        print(json.dumps({kind: values}) if args.json else f'{kind}: {text}', flush=True)

    rclpy.init(args=argv)
    node = rclpy.create_node('execute_move_example')
    try:
        preview = node.create_client(PlanMove, f'{args.planner}/plan_move')
        action = ActionClient(node, ExecuteMove, f'{args.planner}/execute_move')
        if not preview.wait_for_service(timeout_sec=10.0):
            say('error', 'no plan_move service', message='no plan_move service')
            return 1
        if not action.wait_for_server(timeout_sec=10.0):
            say('error', 'no execute_move action', message='no execute_move action')
            return 1
        move = Move(method=args.method, goal=[args.goal], duration=args.duration)
        if args.delay > 0.0:  # a start time on the ROS clock (zero: as soon as possible)
            move.start_time = (node.get_clock().now() + Duration(seconds=args.delay)).to_msg()

        # 1. A preview: the plan and its facts; nothing moves.
        future = preview.call_async(PlanMove.Request(move=move))
        rclpy.spin_until_future_complete(node, future, timeout_sec=30.0)
        response = future.result()
        if not response.success:
            say('refused', response.message, message=response.message)
            return 1
        info = response.info
        say('preview', f'{info.method}: {info.duration:.3f} s, {len(response.trajectory.points)} knots, '
                       f'peak velocity {info.peak_velocity[0]:.3f} m/s',
            method=info.method, duration=info.duration, knots=len(response.trajectory.points),
            start_time=response.trajectory.header.stamp.sec * 10**9 + response.trajectory.header.stamp.nanosec,
            peak_velocity=list(info.peak_velocity), peak_acceleration=list(info.peak_acceleration))

        # 2. Execute it: accepted, feedback while it moves and settles, then the result.
        def on_feedback(msg):
            fb = msg.feedback
            say('feedback', f'{100 * fb.progress:5.1f} %, {fb.time_remaining:.2f} s left, swing '
                            f'{1e3 * fb.swing:.2f} mm', progress=fb.progress, time_remaining=fb.time_remaining,
                swing=fb.swing)

        goal = action.send_goal_async(ExecuteMove.Goal(move=move, settle=args.settle), feedback_callback=on_feedback)
        rclpy.spin_until_future_complete(node, goal, timeout_sec=10.0)
        result_future = goal.result().get_result_async()
        rclpy.spin_until_future_complete(node, result_future, timeout_sec=info.duration + args.settle + 30.0)
        result = result_future.result().result
        say('result', result.message, success=result.success, message=result.message,
            residual_swing=result.residual_swing, duration=result.info.duration)
        return 0 if result.success else 1
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    sys.exit(main())
