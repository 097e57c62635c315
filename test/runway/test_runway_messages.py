"""The runway's messages without a node: an occupancy through crane_interfaces/Occupancy and back, the other
cranes drawn as markers where their occupancies put them, and crane-record taught the runway's message types
from their installed definitions."""
import numpy as np
import pytest

from crane_planner.runway.occupancy import Footprint, Occupancy, Shape


def moving(crane='crane_b', start_ns=10_000_000_000):
    """A crane whose girder goes from y 2.0 to 2.4 in 1 s, its load 0.1 m in x off the trolley at 0.5."""
    t = np.linspace(0.0, 1.0, 51)
    girder = 2.0 + 0.4 * t
    masses = np.stack([np.stack([np.full_like(t, 0.5), girder], -1), np.stack([np.full_like(t, 0.6), girder], -1)],
                      axis=1)
    return Occupancy(crane, start_ns - 1, start_ns, t, Footprint(girder, masses), Shape(0.05, 0.07))


def test_an_occupancy_goes_through_its_message_and_back_unchanged():
    from crane_planner.nodes.occupancy_messages import from_message, to_message
    o = moving()
    back = from_message(to_message(o))
    assert (back.crane, back.published_ns, back.start_ns, back.shape) == (o.crane, o.published_ns, o.start_ns,
                                                                          o.shape)
    np.testing.assert_array_equal(back.t, o.t)
    np.testing.assert_array_equal(back.footprint.masses, o.footprint.masses)


def test_the_other_cranes_are_drawn_where_they_are_now_in_this_crane_s_frame_and_their_load_s_path_ahead():
    from visualization_msgs.msg import Marker

    from crane_planner.nodes.occupancy_messages import runway_markers
    o = moving()
    offset = (0.2, 1.0)  # this crane's crane_base in runway
    msg = runway_markers([o], o.start_ns + 500_000_000, offset, 'crane_base')  # half way
    by_id = {m.id: m for m in msg.markers}
    assert {m.ns for m in msg.markers} == {'runway/crane_b'} and all(m.header.frame_id == 'crane_base'
                                                                      for m in msg.markers)
    girder, hook, load, path = by_id[0], by_id[1], by_id[2], by_id[3]
    assert girder.type == Marker.CUBE and girder.pose.position.y == pytest.approx(2.2 - 1.0)
    assert girder.scale.y == pytest.approx(0.1)  # twice its girder_half_width
    assert (hook.pose.position.x, load.pose.position.x) == pytest.approx((0.5 - 0.2, 0.6 - 0.2))
    assert load.scale.x == pytest.approx(0.14) and load.pose.position.y == pytest.approx(1.2)
    # the load's path from where it is now to the end: y 2.2 -> 2.4 in runway, 1.2 -> 1.4 here
    ys = [p.y for p in path.points]
    assert ys[0] == pytest.approx(1.2) and ys[-1] == pytest.approx(1.4) and np.all(np.diff(ys) > 0)
    # once the motion is over (or for a hold) no path is drawn, the crane still is
    after = runway_markers([o], o.end_ns + 1, offset, 'crane_base')
    assert sorted(m.id for m in after.markers) == [0, 1, 2]
    assert after.markers[0].pose.position.y == pytest.approx(1.4)
    assert runway_markers([], o.start_ns, offset, 'crane_base').markers == []


def test_crane_record_learns_the_runway_s_message_types_from_their_installed_definitions():
    from rosbags.typesys import Stores, get_typestore

    from crane_planner.tools.record import RUNWAY_TOPICS, build_parser, register_type
    store = get_typestore(Stores.ROS2_JAZZY)
    for name in ('crane_interfaces/msg/Occupancy', 'crane_interfaces/msg/CraneState'):
        assert name not in store.fielddefs
        register_type(store, name)
    fields = dict(store.fielddefs['crane_interfaces/msg/CraneState'][1])
    assert {'crane', 'girder', 'reach_low', 'reach_high', 'guard', 'guard_crane'} <= set(fields)
    assert [f for f, _ in store.fielddefs['crane_interfaces/msg/Occupancy'][1]][:3] == ['header', 'crane', 'start']
    assert RUNWAY_TOPICS == ('/runway/occupancy', '/runway/state')
    assert build_parser().parse_args(['--out', 'x', '--runway']).runway
