"""The streamer node's parameters: the table it declares (``PARAMETERS``) and ``StreamerConfig``, the values
checked together.

Pure Python, no ROS import: the node turns the table's plain ranges into rcl
descriptors (``node_parameters.declare``), ``devtools/make_params_files.py``
writes ``config/streamer.yaml`` from the same table.
"""
from __future__ import annotations

from dataclasses import dataclass

from crane_msgs_py.crane.axes import AXES, AXIS_NAMES, HOIST, LIMIT_QUANTITIES, LIMITS_MAP
from crane_msgs_py.crane.params import (
    CraneParams,
    ParameterError,
    check_choice,
    model_parameters,
    parameter_range,
    renamed_from,
)
from crane_msgs_py.messages.names import OUTPUT_JOINT_TRAJECTORY, OUTPUTS

from ..runway.config import PARAMETERS as RUNWAY_PARAMETERS
from ..runway.config import RunwayConfig
from .impairment import DISTRIBUTIONS, Impairment
from .operator import OPERATOR_SHAPERS, OperatorStream
from .start_position import HOLD_SOURCES

MODES = ('trajectory', 'operator')
#: Each axis's hold position parameter and its default (the cart's predates the others and has no prefix).
INITIAL_POSITIONS_DEFAULTS = {'cart': ('initial_position', 0.0), 'bridge': ('initial_bridge_position', 0.0),
                              'hoist': ('initial_hoist_position', CraneParams.L1)}
INITIAL_POSITIONS = {joint: name for joint, (name, _) in INITIAL_POSITIONS_DEFAULTS.items()}
_HOLD_WHAT = {'cart': 'hold position (m) of the cart', 'bridge': 'with a bridge: its hold position (m)',
              'hoist': "with a hoist: its hold position (m, the upper cable's length)"}
#: Operator mode's limit of each kind of axis, by quantity (velocity m/s, acceleration m/s^2, jerk m/s^3).
OPERATOR_LIMITS = {'travel': (0.3, 0.5, 5.0), 'hoist': (0.2, 0.5, 5.0)}
_LIMIT_RANGES = ((1e-6, 100.0), (1e-6, 1000.0), (1e-6, 1e6))
#: Operator mode's limits of every axis of the registry, a map over the joints (``Axis.limit_parameters``):
#: ``operator.limits.cart.max_velocity``, ...; each was ``operator.`` and the name the axis gives its limit
#: (``operator.max_velocity``, ``operator.max_hoist_jerk``, ...), still taken for one release.
OPERATOR_LIMIT_PARAMETERS = {
    name: (default, f'operator mode: the {a.name}\'s {quantity} limit ({unit})',
           {**parameter_range(*rng), **renamed_from(f'operator.{former}')})
    for a in AXES
    for name, former, unit, default, rng, (quantity, _) in zip(a.limit_parameters('operator'), a.limit_names,
                                                                a.limit_units, OPERATOR_LIMITS[a.kind],
                                                                _LIMIT_RANGES, LIMIT_QUANTITIES)}
#: The hoist's range in operator mode, among its limits (formerly ``operator.hoist_range``).
HOIST_RANGE = f'operator.{LIMITS_MAP}.{HOIST.name}.range'


#: name -> (default, description, descriptor fields; a range as (lo, hi)).
PARAMETERS = {
    'rate': (1000.0, 'publishing rate of reference (Hz); fixed at start-up',
             {**parameter_range(1.0, 10000.0), 'read_only': True}),
    'output': (OUTPUT_JOINT_TRAJECTORY, 'reference type: joint_trajectory (one point: position, velocity, '
               'acceleration) or float64_array (Float64MultiArray [position]); fixed at start-up',
               {'additional_constraints': f'one of {", ".join(OUTPUTS)}', 'read_only': True}),
    'state_rate': (50.0, 'publishing rate of stream_state (Hz), at most rate; fixed at start-up',
                   {**parameter_range(1.0, 1000.0), 'read_only': True}),
    'auto_start': (True, 'start streaming at start-up (else wait for ~/start)', {'read_only': True}),
    'hold_source': ('joint_states', 'where the hold position comes from at start-up and at every ~/start: '
                    'joint_states (the axes\' measured position, at rest; nothing is streamed before it is known, '
                    'so the first sample is where the axis stands) or initial_position (the configured positions, '
                    'for a bench without feedback)',
                    {'additional_constraints': f'one of {", ".join(HOLD_SOURCES)}', 'read_only': True}),
    'initial_fallback_after': (0.0, 'with hold_source joint_states: hold initial_position if no joint_states at '
                               'all arrive within this many seconds of a start (0 = never: wait for them)',
                               {**parameter_range(0.0, 3600.0), 'read_only': True}),
    **{name: (default, f'{_HOLD_WHAT[joint]} with hold_source initial_position (or its fallback)', {'read_only': True})
       for joint, (name, default) in INITIAL_POSITIONS_DEFAULTS.items()},
    'joints': (['cart'], 'the streamed joints: [cart], [cart, hoist], [cart, bridge] or [cart, bridge, hoist] (the '
                         'reference then carries a column per joint, float64_array in that order); fixed at start-up',
               {'additional_constraints': 'cart, then any of bridge, hoist in this order', 'read_only': True}),
    'start_tolerance': (1e-6, 'largest distance (m) between a trajectory\'s first position and the hold '
                        'position; farther is a jump and the trajectory is refused', parameter_range(0.0, 1.0)),
    'fault_deceleration': (0.5, 'a ~/stop during a motion when no stop without swing can be had in time (the stop '
                           'planner dead, or late every time): every axis brakes along its fastest ramp within this '
                           'deceleration (m/s^2) and fault_jerk, never an abrupt hold', parameter_range(1e-3, 100.0)),
    'fault_jerk': (5.0, 'the jerk limit (m/s^3) of that braking ramp', parameter_range(1e-3, 1e4)),
    # Off by default: whatever share of each tick is spun is that share of a core on every machine, while the
    # sim plays the samples out by their stamps, so a wake-up a little late changes nothing downstream.
    'busy_wait': (0.0, 'the last part (s) of each tick period spent spinning instead of sleeping, for '
                  'wake-up precision at the cost of CPU (1e-4 on a core of its own: a few us late instead of '
                  'some tens)', parameter_range(0.0, 1e-3)),
    'sched_priority': (50, 'SCHED_FIFO priority of the loop thread, 1..99 (as ros2_control\'s controller '
                       'manager; without the privilege a warning and normal scheduling), the executor thread one '
                       'below, the middleware\'s receive threads two below; 0 = normal scheduling',
                       {**parameter_range(0, 99), 'read_only': True}),
    'timing_log': ('', 'file to write every tick lateness to at shutdown, JSON {rate_hz, first_tick_ns (ROS '
                   'time of the first tick), lateness_us: [...]}, ticks of later ~/start runs appended; '
                   'empty = off',
                   {'read_only': True}),
    'network.delay': (0.0, 'impairment: fixed delay (s) of every message', parameter_range(0.0, 10.0)),
    'network.jitter': (0.0, 'impairment: standard deviation (s) of the random delay', parameter_range(0.0, 10.0)),
    'network.distribution': ('normal', f'impairment: jitter distribution, one of {", ".join(DISTRIBUTIONS)} '
                             '(normal/uniform zero-mean, exponential one-sided)',
                             {'additional_constraints': f'one of {", ".join(DISTRIBUTIONS)}'}),
    'network.loss': (0.0, 'impairment: probability that a message is lost', parameter_range(0.0, 1.0)),
    'network.reorder': (False, 'impairment: let messages overtake each other (false = FIFO delivery)', {}),
    'network.seed': (0, 'impairment: seed of the random draws', {}),
    'mode': ('trajectory', 'trajectory: stream the trajectories sent on trajectory; operator: follow cmd_vel '
                           '(geometry_msgs/Twist: linear.x the cart velocity, linear.z the load\'s vertical velocity, '
                           '+ = up), jerk-limited and shaped online; switched only with the crane at rest',
             {'additional_constraints': f'one of {", ".join(MODES)}'}),
    'operator_shaper': ('zv', 'operator mode: the shaper applied online to the jerk-limited command, designed '
                              'every tick for the rope length then (length-adaptive); none = rate limits only',
                        {'additional_constraints': f'one of {", ".join(OPERATOR_SHAPERS)}'}),
    'cmd_timeout': (0.5, 'operator mode: a command older than this (s) counts as zero, so a lost joystick stops '
                         'the crane (without swing)', parameter_range(0.001, 10.0)),
    'feedback': (False, 'closed-loop sway control: add to whatever is streamed (a trajectory, the hold, operator mode) '
                        'a correction of each travel axis computed from the measured swing (joint_states at their '
                        'stamps) and the reference streamed, so that swing the plan did not foresee is damped and the '
                        'axes end where the plan ends; within the operator limits of each axis; switched off, a '
                        'correction left fades to zero', {}),
    'feedback_timeout': (0.2, 'with feedback: no finite joint_states for this long (s) and the correction fades to '
                              'zero within the limits, the plan streaming on open loop, until they return',
                         parameter_range(0.01, 10.0)),
    'feedback_noise': (0.0, 'with feedback: the standard deviation (rad) of the measured angles\' noise, as the '
                            'camera has it (a sway camera: about 1e-3); the estimator weighs measurements by it, and '
                            'a camera noisier than 1e-4 gets a gentler law, lest its noise move the axes (fixed at '
                            'start-up)', {**parameter_range(0.0, 0.1), 'read_only': True}),
    **OPERATOR_LIMIT_PARAMETERS,
    HOIST_RANGE: ([0.1, 3.0], 'operator mode: the shortest and longest rope (m) the hoist may reach',
                  {'additional_constraints': '[shortest, longest], 0 < shortest < longest',
                   **renamed_from('operator.hoist_range')}),
    **model_parameters(lambda description: f'crane model of the operator shaper and of a ~/stop: {description}'),
    **RUNWAY_PARAMETERS,  # (the runway guard: streaming.runway_guard)
}


@dataclass(frozen=True)
class OperatorConfig:
    """Operator mode's settings: the online shaper, ``cmd_timeout`` (s), the limits of every axis of the registry
    (``AxisLimits``, in ``AXES`` order), the hoist's range (shortest, longest rope, m) and the crane model."""

    shaper: str
    cmd_timeout: float
    limits: tuple
    hoist_range: tuple
    model: CraneParams

    def stream(self, period: float, hold, joints=('cart',)) -> OperatorStream:
        """Operator mode's stream at ``period`` (s) of ``joints`` from the axes held at ``hold`` (one joint: a
        float)."""
        start = hold if isinstance(hold, tuple) else (hold,)
        limits = [self.limits[AXIS_NAMES.index(name)] for name in joints]
        return OperatorStream(period, start, limits, self.shaper, self.model, self.cmd_timeout, self.hoist_range,
                              joints=joints)


@dataclass(frozen=True)
class StreamerConfig:
    """The streamer's parameters checked together: the link's impairment, the crane model (of the operator's
    shaper, of a ~/stop and of the sway feedback), the mode and operator mode's settings, the axes' braking ramp
    (m/s^2, m/s^3) of a ~/stop that cannot be one without swing, whether the sway feedback is on (and its
    timeout, s), and the runway's parameters (its guard)."""

    impairment: Impairment
    model: CraneParams
    mode: str
    operator: OperatorConfig
    fault_deceleration: float = 0.5
    fault_jerk: float = 5.0
    feedback: bool = False
    feedback_timeout: float = 0.2
    runway: RunwayConfig = RunwayConfig()

    @classmethod
    def of(cls, values: dict, current: 'StreamerConfig | None' = None, at_rest: bool = True,
           namespace: str = '') -> 'StreamerConfig':
        """The parameters by name checked together, a change of ``current`` (the mode or operator mode's
        settings only ``at_rest``); ``namespace`` names the crane on the runway when ``crane_name`` is empty.
        ParameterError (or ValueError) names the problem."""
        impairment = Impairment(delay=values['network.delay'], jitter=values['network.jitter'],
                                distribution=values['network.distribution'], loss=values['network.loss'],
                                reorder=values['network.reorder'], seed=values['network.seed'])
        model = CraneParams.of(values)
        check_choice('hold_source', values['hold_source'], HOLD_SOURCES)
        check_choice('mode', values['mode'], MODES)
        check_choice('operator_shaper', values['operator_shaper'], OPERATOR_SHAPERS)
        shortest, longest = (list(values[HOIST_RANGE]) + [0.0, 0.0])[:2]
        if len(values[HOIST_RANGE]) != 2 or not 0.0 < shortest < longest:
            raise ParameterError(f'{HOIST_RANGE} must be [shortest, longest] with 0 < shortest < longest (m)')
        limits = tuple(a.limits(*(values[name] for name in a.limit_parameters('operator'))) for a in AXES)
        operator = OperatorConfig(values['operator_shaper'], values['cmd_timeout'], limits, (shortest, longest), model)
        config = cls(impairment, model, values['mode'], operator, values['fault_deceleration'], values['fault_jerk'],
                     bool(values['feedback']), values['feedback_timeout'],
                     RunwayConfig.from_values(values, namespace))
        if current is not None and config.changes_mode(current) and not at_rest:
            raise ParameterError('mode and the operator settings change only with the crane at rest (no motion '
                                 'streaming, the operator\'s command played out)')
        return config

    def changes_mode(self, other: 'StreamerConfig') -> bool:
        """Whether going from ``other`` to this changes the mode or, in operator mode, its settings: only at
        rest."""
        return self.mode != other.mode or (self.mode == 'operator' and self.operator != other.operator)
