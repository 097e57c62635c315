"""What taking one reference costs the simulator: typed (rclpy builds the message) against raw bytes read by
``crane_msgs_py.messages.cdr``, in one run.

A publisher sends bursts of one-point JointTrajectory references (as the streamer does, joints cart and
hoist) to two subscriptions in the same private graph, one typed, one raw, neither spun by an executor;
each burst is taken from both, each message read into (stamp, positions, accelerations) with
``conversions.read_reference``. Reported: microseconds of CPU per message each way and their ratio. An
executor handing the typed messages to a callback adds its own cost on top (not measured here).

    .venv/bin/python bench/reference_take.py [--bursts 20]
"""
import argparse
import json
import sys
import time


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--bursts', type=int, default=20, help='bursts of 500 messages (default 20)')
    args = ap.parse_args()
    from crane_planner.tools.processes import isolated_graph
    with isolated_graph():
        return measure(args.bursts)


def measure(bursts: int) -> int:
    import rclpy
    from trajectory_msgs.msg import JointTrajectory

    from crane_msgs_py.messages.cdr import read_joint_trajectory
    from crane_msgs_py.messages.conversions import fill_reference, read_reference, reference_message
    from crane_msgs_py.runtime.qos import REFERENCE_EVERY_SAMPLE_QOS
    from crane_msgs_py.runtime.taking import take_all

    rclpy.init()
    node = rclpy.create_node('reference_take_bench')
    joints = ('cart', 'hoist')
    publisher = node.create_publisher(JointTrajectory, 'reference', REFERENCE_EVERY_SAMPLE_QOS)
    typed = node.create_subscription(JointTrajectory, 'reference', lambda _: None, REFERENCE_EVERY_SAMPLE_QOS)
    raw = node.create_subscription(JointTrajectory, 'reference', lambda _: None, REFERENCE_EVERY_SAMPLE_QOS,
                                   raw=True)
    deadline = time.monotonic() + 10.0
    while min(typed.get_publisher_count(), raw.get_publisher_count()) < 1 and time.monotonic() < deadline:
        time.sleep(0.01)
    msg = reference_message(joint=joints)
    cpu = {'typed': 0.0, 'raw': 0.0}
    counts = {'typed': 0, 'raw': 0}
    for burst in range(bursts):
        for k in range(500):
            fill_reference(msg, (burst * 500 + k + 1) * 1_000_000, (0.1 * k, 0.47), (0.0, 0.0), (0.2, 0.0))
            publisher.publish(msg)
        time.sleep(0.2)  # delivered
        t0 = time.process_time()
        handle = typed.handle
        with handle:
            while (message := handle.take_message(typed.msg_type, False)) is not None:
                read_reference(message[0], joints)
                counts['typed'] += 1
        t1 = time.process_time()
        for data, _ in take_all(raw):
            read_reference(read_joint_trajectory(data), joints)
            counts['raw'] += 1
        t2 = time.process_time()
        cpu['typed'] += t1 - t0
        cpu['raw'] += t2 - t1
    node.destroy_node()
    rclpy.shutdown()
    per = {k: cpu[k] / max(counts[k], 1) * 1e6 for k in cpu}
    print(json.dumps({'messages': counts, 'typed_us_per_message': round(per['typed'], 1),
                      'raw_us_per_message': round(per['raw'], 1),
                      'typed_over_raw': round(per['typed'] / per['raw'], 2) if per['raw'] else None}))
    return 0 if min(counts.values()) > 0 else 1


if __name__ == '__main__':
    sys.exit(main())
