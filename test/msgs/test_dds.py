"""The Fast DDS profiles: the nodes' (service answers wait for a client discovered late) and the loopback-UDP
one the tests and crane-demo run on (no shared memory)."""
import ast
import subprocess
import sys
import xml.etree.ElementTree as ET

import pytest

from crane_msgs_py.runtime.dds import FASTDDS_PROFILES, LOOPBACK_PROFILES, use_loopback_udp, use_node_profiles

NS = {'dds': 'http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles'}


def test_the_service_profile_waits_longer_than_rmw_fastrtps_default():
    """rmw_fastrtps reads the data_writer profile named "service" for every response writer, and drops an
    answer once its reliability max_blocking_time (default 100 ms) passes without the client's reader."""
    root = ET.parse(FASTDDS_PROFILES).getroot()
    [writer] = root.findall('dds:profiles/dds:data_writer', NS)
    assert writer.get('profile_name') == 'service'
    blocking = writer.find('dds:qos/dds:reliability/dds:max_blocking_time', NS)
    seconds = float(blocking.findtext('dds:sec', '0', NS)) + 1e-9 * float(blocking.findtext('dds:nanosec', '0', NS))
    assert seconds >= 1.0
    assert [child.tag.split('}')[1] for child in writer.find('dds:qos', NS)] == ['reliability']  # nothing else


def test_the_profile_is_used_unless_the_user_names_one():
    env = {}
    assert use_node_profiles(env) and env == {'FASTRTPS_DEFAULT_PROFILES_FILE': str(FASTDDS_PROFILES)}
    for name in ('FASTRTPS_DEFAULT_PROFILES_FILE', 'FASTDDS_DEFAULT_PROFILES_FILE'):
        env = {name: '/etc/mine.xml'}
        assert not use_node_profiles(env) and env == {name: '/etc/mine.xml'}


def test_the_loopback_profiles_carry_the_nodes_service_profile():
    """A graph run on ``LOOPBACK_PROFILES`` (the tests, crane-demo) gives service answers the nodes' own time."""
    [ours] = ET.parse(FASTDDS_PROFILES).getroot().findall('dds:profiles/dds:data_writer', NS)
    [loopback] = ET.parse(LOOPBACK_PROFILES).getroot().findall('dds:profiles/dds:data_writer', NS)
    def canonical(element):
        return ET.canonicalize(ET.tostring(element), strip_text=True)
    assert canonical(loopback) == canonical(ours)


def test_loopback_udp_overrides_what_would_bring_shared_memory_back():
    env = {'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST', 'FASTDDS_DEFAULT_PROFILES_FILE': '/etc/mine.xml',
           'FASTDDS_BUILTIN_TRANSPORTS': 'DEFAULT', 'ROS_STATIC_PEERS': '10.0.0.7', 'ROS_DOMAIN_ID': '17',
           'ROS_DISCOVERY_SERVER': '127.0.0.1:11811', 'RMW_IMPLEMENTATION': 'rmw_cyclonedds_cpp'}
    use_loopback_udp(env)
    assert env == {'ROS_AUTOMATIC_DISCOVERY_RANGE': 'SYSTEM_DEFAULT', 'ROS_DOMAIN_ID': '17',
                   'RMW_IMPLEMENTATION': 'rmw_fastrtps_cpp', 'FASTRTPS_DEFAULT_PROFILES_FILE': str(LOOPBACK_PROFILES)}


#: A real process of the real middleware: creates a node and a publisher, then prints the Fast DDS shared-memory
#: files it has mapped and the addresses its UDP sockets are bound to (hex, as /proc/net/udp shows them).
PROBE = '''
import os, rclpy
from std_msgs.msg import String
rclpy.init()
node = rclpy.create_node("loopback_probe")
node.create_publisher(String, "probe", 10)
maps = sorted({line.split()[-1] for line in open("/proc/self/maps") if "/dev/shm/fastrtps" in line})
sockets = set()
for fd in os.listdir("/proc/self/fd"):
    try:
        target = os.readlink(f"/proc/self/fd/{fd}")
    except FileNotFoundError:  # the directory's own descriptor, closed by now
        continue
    if target.startswith("socket:["):
        sockets.add(int(target[8:-1]))
bound = {row.split()[1].split(":")[0] for row in open("/proc/self/net/udp").readlines()[1:]
         if int(row.split()[9]) in sockets}
node.destroy_node()
rclpy.shutdown()  # (its segments, under LOCALHOST, removed)
print(repr((maps, sorted(bound))))
'''


def probe(env) -> tuple[list[str], list[str]]:
    done = subprocess.run([sys.executable, '-c', PROBE], env=env, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    return ast.literal_eval(done.stdout.strip().splitlines()[-1])


@pytest.mark.ros
def test_a_participant_on_loopback_udp_maps_no_shared_memory_and_binds_only_loopback():
    from crane_planner.tools.processes import isolated_ros_env
    maps, bound = probe(isolated_ros_env())
    assert maps == []
    assert bound == ['0100007F']  # 127.0.0.1, little-endian


@pytest.mark.ros
def test_the_probe_sees_the_shared_memory_rmw_fastrtps_brings_for_localhost():
    """The check above can fail: for ``LOCALHOST`` rmw_fastrtps maps a segment and a port of its own, whatever
    ``FASTDDS_BUILTIN_TRANSPORTS`` says."""
    from crane_planner.tools.processes import isolated_ros_env
    env = isolated_ros_env()
    env.pop('FASTRTPS_DEFAULT_PROFILES_FILE')
    env.update(ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST', FASTDDS_BUILTIN_TRANSPORTS='UDPv4')
    maps, _ = probe(env)
    assert any('fastrtps_port' in m for m in maps) and len(maps) >= 2
