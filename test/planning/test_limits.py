"""planning.limits: the necessary conditions of the axis limits, against closed forms and ruckig's
time-optimal profiles (an independent solver: no motion within the limits is faster than it)."""
import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from crane_msgs_py.crane.axes import HOIST, AxisLimits
from crane_planner.planning.limits import axis_limit_error, check_fastest_request, shortest_duration_bound
from crane_planner.planning.plan import PlanError
from crane_planner.planning.profiles import limited_base


@pytest.mark.parametrize('D, limits, expected', [
    (0.3, (0.1, None, None), 3.0),                       # coasting at v: D / v
    (0.3, (None, 0.3, None), 2.0),                       # bang-bang: 2 sqrt(D / a)
    (0.3, (None, None, 0.3 * 32.0 / 8.0), 2.0),          # bang-bang jerk: (32 D / j)^(1/3)
    (0.3, (0.2, 0.4, None), 0.3 / 0.2 + 0.2 / 0.4),      # trapezoid: D / v + v / a
    (0.3, (1.0, 0.4, None), 2.0 * math.sqrt(0.3 / 0.4)),  # v never reached: the triangle
])
def test_the_bound_is_the_closed_form_of_the_binding_limit(D, limits, expected):
    assert shortest_duration_bound(D, AxisLimits(*limits)) == pytest.approx(expected, rel=1e-12)
    assert shortest_duration_bound(-D, AxisLimits(*limits)) == pytest.approx(expected, rel=1e-12)


@settings(max_examples=40, deadline=None)
@given(st.floats(0.01, 3.0), st.floats(0.05, 2.0), st.floats(0.1, 5.0), st.floats(0.5, 50.0))
def test_no_time_optimal_jerk_limited_motion_beats_the_bound_and_a_stiff_one_meets_it(D, v, a, j):
    limits = AxisLimits(v, a, j)
    assert shortest_duration_bound(D, limits) <= limited_base(D, v, a, j).duration * (1 + 1e-9)
    # with a jerk limit far above what matters, ruckig's profile is the bang-bang / trapezoid itself
    stiff = limited_base(D, v, a, 1e6).duration
    assert stiff == pytest.approx(shortest_duration_bound(D, AxisLimits(v, a)), rel=2e-3)


@pytest.mark.parametrize('limits, named, needed', [
    ((0.09, None, None), 'max_velocity 0.09 m/s', 0.1),
    ((None, 0.13, None), 'max_acceleration 0.13 m/s^2', 4 * 0.3 / 9),
    ((None, None, 0.35), 'max_jerk 0.35 m/s^3', 32 * 0.3 / 27),
])
def test_a_request_below_a_bang_bang_need_is_refused_naming_the_limit_and_its_need(limits, named, needed):
    err = axis_limit_error(0.3, 3.0, AxisLimits(*limits))
    assert isinstance(err, PlanError) and named in str(err) and f'{needed:g}' in str(err)
    # just above the need: not refused by the necessary condition
    assert axis_limit_error(0.3, 3.0, AxisLimits(*[None if x is None else needed * 1.001 for x in limits])) is None
    # another axis's limit is named as that axis names it
    assert named.replace('max_', 'max_hoist_') in str(axis_limit_error(0.3, 3.0, HOIST.limits(*limits)))


def test_velocity_and_acceleration_together_refuse_what_each_alone_allows():
    v, a = 0.2, 0.4  # alone: D/v = 1.5 s and 2 sqrt(D/a) = 1.73 s; together 2.0 s
    assert axis_limit_error(0.3, 1.9, AxisLimits(v)) is None and axis_limit_error(0.3, 1.9, AxisLimits(None, a)) is None
    err = axis_limit_error(0.3, 1.9, AxisLimits(v, a))
    assert 'together need more than 2 s' in str(err)
    assert axis_limit_error(0.3, 2.01, AxisLimits(v, a)) is None


def test_rounding_of_exactly_the_limit_is_refused_not_accepted():
    # 0.1 m/s * 3 s is 0.30000000000000004 m: exactly the need is infeasible for a smooth motion
    assert axis_limit_error(0.3, 3.0, AxisLimits(0.1)) is not None


def test_a_fastest_request_needs_a_velocity_or_acceleration_limit_and_a_nonzero_move():
    with pytest.raises(PlanError, match='needs max_velocity or max_acceleration'):
        check_fastest_request(0.3, AxisLimits(max_jerk=2.0))
    with pytest.raises(PlanError, match='nonzero displacement'):
        check_fastest_request(0.0, AxisLimits(0.2))
    assert check_fastest_request(-0.3, AxisLimits(0.2)) == -0.3
