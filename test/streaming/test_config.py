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


@pytest.mark.parametrize('name, value, match', [('mode', 'joystick', 'mode'),
                                                ('operator.hoist_range', [2.0, 1.0], 'operator.hoist_range'),
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
