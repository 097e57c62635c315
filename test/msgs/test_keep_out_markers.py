"""The planner's keep-out boxes as RViz markers (``conversions.keep_out_markers``): each box and its margin a
cube of the box's centre and size, an unbounded side drawn KEEP_OUT_DRAWN beyond the other, expiring."""
import math

import pytest

from crane_msgs_py.messages.conversions import KEEP_OUT_DRAWN, keep_out_markers


def test_each_box_and_its_margin_are_cubes_of_its_centre_and_size():
    msg = keep_out_markers([((0.25, -math.inf, -2.0), (0.35, math.inf, -0.76)), ((1.0, 0.0, 0.0), (2.0, 1.0, 0.5))],
                           0.02, 'crane_base', 123, lifetime=2.5)
    by = {(m.ns, m.id): m for m in msg.markers}
    assert set(by) == {('keep_out', 0), ('keep_out_margin', 0), ('keep_out', 1), ('keep_out_margin', 1)}
    wall, grown = by[('keep_out', 0)], by[('keep_out_margin', 0)]
    assert (wall.pose.position.x, wall.pose.position.y, wall.pose.position.z) == pytest.approx((0.30, 0.0, -1.38))
    assert (wall.scale.x, wall.scale.y, wall.scale.z) == pytest.approx((0.10, 2 * KEEP_OUT_DRAWN, 1.24))
    assert (grown.scale.x, grown.scale.z) == pytest.approx((0.14, 1.28)) and grown.color.a < wall.color.a
    assert (wall.lifetime.sec, wall.lifetime.nanosec) == (2, 500_000_000) and wall.header.frame_id == 'crane_base'
    assert by[('keep_out', 1)].pose.position.x == pytest.approx(1.5)
    # far from the origin: drawn where it is; a side without end KEEP_OUT_DRAWN beyond the other
    [far, _] = keep_out_markers([((5.25, 7.0, -2.0), (5.35, math.inf, -0.76))], 0.0, 'crane_base', 0).markers
    assert (far.pose.position.x, far.scale.x) == pytest.approx((5.30, 0.10))
    assert (far.pose.position.y, far.scale.y) == pytest.approx((7.0 + KEEP_OUT_DRAWN / 2, KEEP_OUT_DRAWN))
    assert keep_out_markers([], 0.02, 'crane_base', 0).markers == []


def test_the_route_is_a_line_strip_through_its_points_expiring():
    from crane_msgs_py.messages.conversions import route_markers
    [line] = route_markers([(0.0, 0.0, -0.861), (0.1, 0.02, -0.8), (0.3, 0.0, -0.861)], 'crane_base', 5,
                           lifetime=4.5).markers
    assert (line.ns, line.type, line.header.frame_id) == ('route', line.LINE_STRIP, 'crane_base')
    assert [(p.x, p.y, p.z) for p in line.points] == [(0.0, 0.0, -0.861), (0.1, 0.02, -0.8), (0.3, 0.0, -0.861)]
    assert (line.lifetime.sec, line.lifetime.nanosec) == (4, 500_000_000) and line.scale.x > 0.0
