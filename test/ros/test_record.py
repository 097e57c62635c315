"""crane-record on its own, as a user runs it beside their nodes: a real DDS publisher here, the
installed executable in a subprocess, the recording read back with the independent mcap reader."""
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

BIN = Path(sys.executable).parent
RECORD = str(BIN / 'crane-record')


def _record(env, *args, timeout=60):
    return subprocess.run([RECORD, *args], env=env, capture_output=True, text=True, timeout=timeout)


def test_every_message_of_a_500_hz_publisher_is_recorded_with_its_receive_time(ros_domain, tmp_path):
    import rclpy
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    from sensor_msgs.msg import JointState

    from crane_msgs_py.runtime.qos import JOINT_STATES_QOS

    rclpy.init()
    node = rclpy.create_node('record_source', namespace='/rec_test')
    publisher = node.create_publisher(JointState, 'joint_states', JOINT_STATES_QOS)
    done = threading.Event()

    def publish():
        msg, k = JointState(name=['cart', 'theta1', 'theta2']), 0
        while not done.is_set():
            k += 1
            now = time.time_ns()
            msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(now, 10**9)
            msg.position = [0.001 * k, -1e-3 * k, 2e-3 * k]
            publisher.publish(msg)
            time.sleep(0.002)

    bag = tmp_path / 'bag'
    thread = threading.Thread(target=publish, daemon=True)
    thread.start()
    try:
        r = _record(ros_domain, '--namespace', '/rec_test', '--topics', 'joint_states', '--out', str(bag),
                    '--duration', '4')
    finally:
        done.set()
        thread.join()
        node.destroy_node()
        rclpy.try_shutdown()
    assert r.returncode == 0, r.stderr
    # the closing summary: what was recorded and, with one publisher, that nothing was lost
    summary = r.stderr.strip().splitlines()[-1]
    assert summary.startswith('crane-record: /rec_test/joint_states ') and summary.endswith('(lost 0)'), summary
    [mcap_file] = bag.glob('*.mcap')
    with open(mcap_file, 'rb') as f:
        got = [(m.log_time, ros) for _, _, m, ros in
               make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages()]
    assert int(summary.split()[2]) == len(got) > 1000  # ~4 s at 500 Hz
    ks = [round(ros.position[0] / 0.001) for _, ros in got]
    assert ks == list(range(ks[0], ks[0] + len(ks)))  # consecutive: none missing, none twice, in order
    for log_time, ros in got:
        k = round(ros.position[0] / 0.001)
        assert list(ros.position) == pytest.approx([0.001 * k, -1e-3 * k, 2e-3 * k], abs=1e-15)
        assert list(ros.name) == ['cart', 'theta1', 'theta2']
        stamp = ros.header.stamp.sec * 10**9 + ros.header.stamp.nanosec
        assert log_time >= stamp, (k, log_time - stamp)  # received after it was sent
    # logged at its receipt (the middleware's receive time), not when drained in batches every 10 ms: the log
    # times are spaced as the 2 ms publishing is, not bunched five to a batch (how late each comes after its
    # publish() measures the host, which can pause for hundreds of milliseconds)
    gaps = np.diff([log_time for log_time, _ in got]) * 1e-6
    assert np.all(gaps >= 0.0) and np.median(gaps) > 1.0, np.percentile(gaps, [10, 50, 90])


@pytest.mark.parametrize('args, message', [
    (['--duration', '0'], '--duration must be > 0'),
    (['--topics', ' , '], '--topics names no topic'),
    (['--priority', '120'], '--priority must be 0..99, got 120'),
])
def test_bad_options_are_one_line_and_exit_2(ros_domain, tmp_path, args, message):
    r = _record(ros_domain, '--out', str(tmp_path / 'bag'), *args)
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1 and lines[0].startswith(f'crane-record: error: {message}'), r.stderr


def test_an_existing_folder_is_not_overwritten(ros_domain, tmp_path):
    (tmp_path / 'bag').mkdir()
    (tmp_path / 'bag' / 'keep.txt').write_text('mine')
    r = _record(ros_domain, '--out', str(tmp_path / 'bag'), '--duration', '1')
    assert r.returncode == 2 and 'exists' in r.stderr and 'Traceback' not in r.stderr
    assert (tmp_path / 'bag' / 'keep.txt').read_text() == 'mine'


def test_a_topic_without_publisher_is_named_and_exits_1(ros_domain, tmp_path):
    r = _record(ros_domain, '--namespace', '/nobody_here', '--topics', 'reference', '--out', str(tmp_path / 'bag'),
                '--wait', '0.5', '--duration', '1')
    assert r.returncode == 1 and 'no publisher of /nobody_here/reference within 0.5 s' in r.stderr
    assert 'Traceback' not in r.stderr


def test_a_topic_seen_only_through_its_subscribers_has_no_publisher_to_record(ros_domain, tmp_path):
    """A topic in the graph because something subscribes to it is not recorded as if it had a publisher
    (subscribed best effort and volatile with nothing to match, it would lose the first latched
    trajectory published later)."""
    import rclpy
    from trajectory_msgs.msg import JointTrajectory

    from crane_msgs_py.runtime.qos import TRAJECTORY_QOS
    rclpy.init()
    node = rclpy.create_node('only_a_subscriber', namespace='/sub_only')
    node.create_subscription(JointTrajectory, 'trajectory', lambda _: None, TRAJECTORY_QOS)
    try:
        r = _record(ros_domain, '--namespace', '/sub_only', '--topics', 'trajectory', '--out', str(tmp_path / 'bag'),
                    '--wait', '2', '--duration', '1')
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    assert r.returncode == 1 and 'no publisher of /sub_only/trajectory within 2 s' in r.stderr, r.stderr
