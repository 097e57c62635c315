"""The streamer's parameters (crane_planner.streaming.config): the table's defaults make a valid config, bad
values are refused naming the parameter, the mode changes only at rest."""
import pytest

from crane_msgs_py.crane.params import ParameterError
from crane_planner.streaming.config import PARAMETERS, StreamerConfig

DEFAULTS = {name: default for name, (default, _, _) in PARAMETERS.items()}


def test_the_defaults_make_a_config_and_every_range_is_plain():
    config = StreamerConfig.of(DEFAULTS)
    assert config.mode == 'trajectory' and not config.impairment.active and config.operator.shaper == 'zv'
    for name, (_, description, extra) in PARAMETERS.items():
        assert description, name
        for key in ('floating_point_range', 'integer_range'):
            assert key not in extra or (isinstance(extra[key], tuple) and len(extra[key]) == 2), name


@pytest.mark.parametrize('name, value, match', [
    ('mode', 'joystick', 'mode'),
    ('operator.limits.hoist.range', [2.0, 1.0], 'operator.limits.hoist.range'),
    ('network.loss', 2.0, 'loss')])
def test_a_bad_value_is_refused_naming_it(name, value, match):
    with pytest.raises(ParameterError, match=match):
        StreamerConfig.of({**DEFAULTS, name: value})


def test_the_mode_and_the_operator_settings_change_only_at_rest():
    current = StreamerConfig.of(DEFAULTS)
    operator = {**DEFAULTS, 'mode': 'operator'}
    with pytest.raises(ParameterError, match='only with the crane at rest'):
        StreamerConfig.of(operator, current, at_rest=False)
    assert StreamerConfig.of(operator, current, at_rest=True).changes_mode(current)
    # the link's impairment changes any time
    assert not StreamerConfig.of({**DEFAULTS, 'network.delay': 0.01}, current, at_rest=False).changes_mode(current)
    # in trajectory mode the operator's settings are not in use: they change any time
    assert not StreamerConfig.of({**DEFAULTS, 'cmd_timeout': 1.0}, current, at_rest=False).changes_mode(current)


def test_each_axis_s_operator_limits_are_a_map_over_the_joints_and_their_former_names_are_kept():
    """``operator.limits.<joint>.max_velocity``, ...: each axis's ``AxisLimits`` in operator mode; the former flat
    names (``operator.max_velocity``, ``operator.max_hoist_jerk``, ``operator.hoist_range``) map onto them."""
    from crane_msgs_py.crane.params import renamed
    values = {**DEFAULTS, 'operator.limits.bridge.max_velocity': 0.1, 'operator.limits.hoist.max_jerk': 2.0}
    limits = StreamerConfig.of(values).operator.limits
    assert (limits[0].max_velocity, limits[1].max_velocity, limits[2].max_jerk) == (0.3, 0.1, 2.0)
    former = renamed(PARAMETERS)
    assert former['operator.max_velocity'] == 'operator.limits.cart.max_velocity'
    assert former['operator.max_bridge_acceleration'] == 'operator.limits.bridge.max_acceleration'
    assert former['operator.max_hoist_jerk'] == 'operator.limits.hoist.max_jerk'
    assert former['operator.hoist_range'] == 'operator.limits.hoist.range'
    assert len(former) == 10 and set(former.values()) <= set(PARAMETERS) and not set(former) & set(PARAMETERS)
