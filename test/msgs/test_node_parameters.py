"""crane_msgs_py.runtime.node_parameters: a renamed parameter's former name still works for one release, from the
parameters given at start-up and from a set, applied to the new name with a deprecation warning naming it.

The nodes' own tables (the planner's axis limits ``limits.<joint>.max_velocity``, ..., formerly
``max_velocity``, ``max_bridge_velocity``, ...), on a node of a context of its own in the session's private graph.
"""
from contextlib import contextmanager

from crane_msgs_py.crane.params import renamed
from crane_planner.serving.config import PARAMETERS, Config


class Log:
    """A node's logger as the test sees it: the warnings and errors."""

    def __init__(self):
        self.warnings, self.errors = [], []

    def warning(self, text):
        self.warnings.append(text)

    def error(self, text):
        self.errors.append(text)

    def info(self, text):
        pass


class Diagnostics:
    def __init__(self):
        self.reports = []

    def report(self, *args, **fields):
        self.reports.append((args, fields))


@contextmanager
def node_with(overrides: dict, log: Log):
    """A node ``planner_params`` given ``overrides`` (as a parameters file would), logging into ``log``."""
    import rclpy
    from rclpy.parameter import Parameter
    context = rclpy.Context()
    rclpy.init(context=context)
    node = None
    try:
        node = rclpy.create_node('planner_params', context=context,
                                 parameter_overrides=[Parameter(k, value=v) for k, v in overrides.items()])
        node.get_logger = lambda: log
        yield node
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown(context=context)


def test_the_planners_limits_are_a_map_over_the_joints_each_renamed_from_its_flat_name():
    former = renamed(PARAMETERS)
    assert former == {'max_velocity': 'limits.cart.max_velocity', 'max_acceleration': 'limits.cart.max_acceleration',
                      'max_jerk': 'limits.cart.max_jerk',
                      **{f'max_{a}_{q}': f'limits.{a}.max_{q}' for a in ('bridge', 'hoist')
                         for q in ('velocity', 'acceleration', 'jerk')}}
    for old, new in former.items():
        assert PARAMETERS[new][0] == 0.0 and old not in PARAMETERS  # the defaults unchanged: no limit
    defaults = {name: default for name, (default, _, _) in PARAMETERS.items()}
    config = Config.from_values({**defaults, 'limits.bridge.max_acceleration': 0.4, 'limits.cart.max_velocity': 0.2})
    assert config.options.limits_of('bridge').max_acceleration == 0.4 and config.options.max_velocity == 0.2


def test_a_former_name_given_at_start_up_is_applied_to_the_new_one_with_a_warning(ros_domain):
    from crane_msgs_py.runtime.node_parameters import declare
    log = Log()
    with node_with({'max_velocity': 0.25, 'max_hoist_jerk': 3.0}, log) as node:
        values = declare(node, PARAMETERS)
        assert values['limits.cart.max_velocity'] == 0.25 and values['limits.hoist.max_jerk'] == 3.0
        assert values['limits.bridge.max_velocity'] == 0.0  # the others at their defaults
        assert Config.from_values(values).options.limits_of('hoist').max_jerk == 3.0
    assert len(log.warnings) == 2
    assert 'max_velocity is deprecated' in log.warnings[0] and 'set limits.cart.max_velocity' in log.warnings[0]
    assert 'max_hoist_jerk is deprecated' in log.warnings[1] and 'limits.hoist.max_jerk' in log.warnings[1]


def test_a_former_name_set_is_set_as_the_new_one_with_a_warning_and_checked_as_it(ros_domain):
    from rclpy.parameter import Parameter

    from crane_msgs_py.runtime.node_parameters import Guard, declare
    log, applied = Log(), []
    with node_with({}, log) as node:
        declare(node, PARAMETERS)
        assert not log.warnings
        Guard(node, PARAMETERS, Config.from_values, lambda config, values, changes: applied.append(config),
              Diagnostics())
        result = node.set_parameters([Parameter('max_bridge_velocity', value=0.3)])
        assert [r.successful for r in result] == [True]
        assert node.get_parameter('limits.bridge.max_velocity').value == 0.3
        assert applied[-1].options.limits_of('bridge').max_velocity == 0.3
        assert len(log.warnings) == 1 and 'max_bridge_velocity is deprecated' in log.warnings[0] \
            and 'set limits.bridge.max_velocity' in log.warnings[0]
        # the new name's range holds for the former name too
        result = node.set_parameters([Parameter('max_velocity', value=-1.0)])
        assert not result[0].successful
        assert node.get_parameter('limits.cart.max_velocity').value == 0.0
        # and the new name itself, without a warning
        node.set_parameters([Parameter('limits.cart.max_velocity', value=0.2)])
        assert node.get_parameter('limits.cart.max_velocity').value == 0.2 and len(log.warnings) == 2


def test_the_streamers_former_operator_limits_given_at_start_up_are_its_per_joint_ones(ros_domain):
    from crane_msgs_py.runtime.node_parameters import declare
    from crane_planner.streaming import config as streamer
    log = Log()
    with node_with({'operator.hoist_range': [0.2, 2.0], 'operator.max_bridge_velocity': 0.1}, log) as node:
        values = declare(node, streamer.PARAMETERS)
    config = streamer.StreamerConfig.of(values)
    assert config.operator.hoist_range == (0.2, 2.0) and config.operator.limits[1].max_velocity == 0.1
    assert config.operator.limits[0].max_velocity == 0.3  # the cart's at its default
    assert len(log.warnings) == 2
    assert any('operator.hoist_range is deprecated' in w and 'set operator.limits.hoist.range' in w
               for w in log.warnings)
    assert any('set operator.limits.bridge.max_velocity' in w for w in log.warnings)
