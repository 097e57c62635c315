"""The Fast DDS profile the nodes bring: service answers wait for a client discovered late."""
import xml.etree.ElementTree as ET

from crane_msgs_py.dds import FASTDDS_PROFILES, use_node_profiles

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
