"""The axes registry (crane_msgs_py.crane.axes): records, lookups, the one limits type."""
import math

import pytest

from crane_msgs_py.crane.axes import AXES, AXIS_NAMES, BRIDGE, CART, HOIST, Axis, AxisLimits, axis, check_axes
from crane_msgs_py.crane.params import ParameterError
from crane_msgs_py.messages.names import ACTUATED_JOINTS, CART_JOINT, HOIST_JOINT, SIM_JOINTS, check_joints


def test_the_names_of_the_contract_come_from_the_registry():
    assert AXIS_NAMES == ACTUATED_JOINTS == ('cart', 'bridge', 'hoist') and AXES == (CART, BRIDGE, HOIST)
    assert (CART_JOINT, HOIST_JOINT, SIM_JOINTS[0]) == ('cart', 'hoist', 'cart')
    assert axis('hoist') is HOIST and CART.direction == (1.0, 0.0, 0.0) and HOIST.direction is None
    assert (CART.cmd_vel, HOIST.cmd_vel, HOIST.cmd_vel_sign) == ('linear.x', 'linear.z', -1.0)
    assert axis('bridge') is BRIDGE and BRIDGE.direction == (0.0, 1.0, 0.0) and BRIDGE.cmd_vel == 'linear.y'
    assert BRIDGE.limit_names == ('max_bridge_velocity', 'max_bridge_acceleration', 'max_bridge_jerk')
    # the nodes' parameters: a map over the joints, as ros2_controllers' constraints.<joint>.
    assert CART.limit_parameters() == ('limits.cart.max_velocity', 'limits.cart.max_acceleration',
                                       'limits.cart.max_jerk')
    assert HOIST.limit_parameters('operator')[2] == 'operator.limits.hoist.max_jerk'
    with pytest.raises(ParameterError, match="no axis 'trolley'"):
        axis('trolley')


def test_a_new_travel_axis_is_a_record():
    bridge = Axis('bridge', 'travel', 'y', cmd_vel='linear.y')
    assert bridge.direction == (0.0, 1.0, 0.0) and bridge.sim_joint == 'bridge'
    assert bridge.limit_names == ('max_bridge_velocity', 'max_bridge_acceleration', 'max_bridge_jerk')
    with pytest.raises(ParameterError, match='unit direction'):
        Axis('bridge', 'travel', (1.0, 1.0, 0.0))
    with pytest.raises(ParameterError, match='kind'):
        Axis('slew', 'rotation')


@pytest.mark.parametrize('joints', [['cart'], ['cart', 'hoist'], ['cart', 'bridge'], ['cart', 'bridge', 'hoist']])
def test_joints_are_the_cart_then_others_in_registry_order(joints):
    assert check_joints(joints) == check_axes(joints) == tuple(joints)


@pytest.mark.parametrize('joints', [[], ['hoist'], ['hoist', 'cart'], ['cart', 'cart'], ['cart', 'hoist', 'bridge'],
                                    ['bridge']])
def test_other_joint_lists_are_refused_naming_the_parameter(joints):
    with pytest.raises(ParameterError, match=r'joints must be \[cart\]'):
        check_joints(joints)


def test_limits_none_zero_and_inf_mean_no_limit_and_a_bad_one_is_named_as_its_axis_names_it():
    assert tuple(AxisLimits(0.0, None, math.inf)) == (None, None, None) and not AxisLimits().any
    v, a, j = HOIST.limits(0.2, 0.5)
    assert (v, a, j) == (0.2, 0.5, None) and HOIST.limits(0.2).bounds_speed
    assert AxisLimits(0.2) == HOIST.limits(0.2)  # the names are how it is told, not what it is
    with pytest.raises(ParameterError, match='max_hoist_acceleration must be > 0'):
        HOIST.limits(0.2, -1.0)
    with pytest.raises(ParameterError, match='max_jerk must be > 0'):
        AxisLimits(max_jerk=math.nan)
    with pytest.raises(ParameterError, match='operator mode needs a finite max_hoist_velocity'):
        HOIST.limits(None, 1.0).require(('max_velocity',), 'operator mode')
