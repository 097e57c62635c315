"""The streamer's runway guard over ROS (contract "Cranes sharing a runway"): the other cranes' states in on
``/runway/state``, this crane's out at the stream_state cadence, and the guard's word on ``/diagnostics`` and in
the log. The rule is the pure core's (``streaming.runway_guard``: in the loop, one of the streamer's watches);
this module only translates. With ``runway`` false it does nothing."""
from __future__ import annotations

import math

from crane_interfaces.msg import CraneState, Occupancy

from crane_msgs_py.crane.axes import AXIS_NAMES, BRIDGE, CART, HOIST
from crane_msgs_py.crane.geometry import mass_offsets
from crane_msgs_py.messages import conversions
from crane_msgs_py.runtime import qos
from crane_msgs_py.runtime.diagnostics import ERROR, OK, WARN
from crane_planner.nodes.occupancy_messages import OccupancyRefused, from_message
from crane_planner.runway.config import OCCUPANCY_TOPIC, STATE_TOPIC
from crane_planner.runway.guard import Level
from crane_planner.runway.occupancy import RUNWAY_FRAME
from crane_planner.streaming.braking_stop import brake
from crane_planner.streaming.config import StreamerConfig
from crane_planner.streaming.runway_guard import (
    GUARD_LEAD,
    RAMP_MARGIN,
    GuardStops,
    PlannedStop,
    RunwayGuard,
    first_period,
)

TASK = 'runway guard'
#: The guard's levels on /diagnostics: information is OK, a warning a warning, a stop (or a lost crane) an error.
DIAGNOSTIC_LEVELS = {Level.CLEAR: OK, Level.INFO: OK, Level.WARNING: WARN, Level.STOP: ERROR, Level.LOST: ERROR}
#: The guard's word on /diagnostics at least this often (s), and on every change within ``CHECK`` s.
REPORT, CHECK = 1.0, 0.02
ANGLES = ('theta1', 'theta2', 'phi1', 'phi2')


class RunwayPort:
    """The node's runway guard (see the module docstring).

    Args:
        node: the streamer node (its clock, logger, publishers).
        config: its parameters (``runway`` among them).
        joints: the streamed joints.
        streamer: whose watches the guard joins.
        stops: the ``serving.stops.StopWorker`` that plans the guard's stops (a ``~/stop``'s).
        diagnostics: the node's ``DiagnosticsPublisher``.
    """

    def __init__(self, node, config: StreamerConfig, joints, streamer, stops, diagnostics):
        self.core: RunwayGuard | None = None
        if not config.runway.on:
            return
        self._node, self._config, self._diagnostics = node, config, diagnostics
        limits = config.operator.limits[AXIS_NAMES.index(BRIDGE.name)]
        planned = PlannedStop(first_period(config.model), config.fault_deceleration, config.fault_jerk)
        period = streamer.stream.period_ns * 1e-9
        self.core = core = RunwayGuard(config.runway, joints, period, planned, limits.max_velocity,
                                       limits.max_acceleration, limits.max_jerk or 1e9)
        streamer.watches = (core,)
        stream = streamer.stream
        stream.on_accept = core.accepted  # (every trajectory's stops tabulated as it is accepted)

        def now() -> int:
            return node.get_clock().now().nanoseconds

        def planned():  # (the stop ~/stop runs, planned in the stop worker)
            return stops.take_over(stream, now, self._config.model)

        def ramp():
            return brake(stream, now, self._config.fault_deceleration, self._config.fault_jerk)

        def ready() -> bool:  # the stop worker up, and its stop taken over in time
            return stops.ready and stops.lead <= GUARD_LEAD - RAMP_MARGIN

        self._now = now
        self._stops = GuardStops(core, planned, ramp, ready, self._log)
        self._msg = conversions.crane_state_message(core.crane, RUNWAY_FRAME)
        self._masses = ((0.0, 0.0), (0.0, 0.0))  # the hook's and the load's (x, y) in runway, measured
        self._pub = node.create_publisher(CraneState, STATE_TOPIC, qos.RUNWAY_STATE_QOS)
        node.create_subscription(CraneState, STATE_TOPIC, self._on_state, qos.RUNWAY_STATE_QOS)
        # this crane's own occupancy, as its planner publishes it: whether the crane follows its plan
        node.create_subscription(Occupancy, OCCUPANCY_TOPIC, self._on_occupancy, qos.RUNWAY_OCCUPANCY_QOS)
        self._told, self._checks = -1, 0
        node.create_timer(CHECK, self._report)
        node.get_logger().info(f'runway: crane {core.crane} at {list(config.runway.offset)} m in {RUNWAY_FRAME}, '
                               f'guarding on {STATE_TOPIC} (runway_min_distance {config.runway.min_distance:g} m, '
                               f'silent neighbours within {core.guard.reach:.3g} m stop it)')

    # -- the executor's side -------------------------------------------------------------------

    def configure(self, config: StreamerConfig) -> None:
        if self.core is not None:
            self._config = config
            self.core.configure(config.runway)

    def measure(self, names, positions) -> None:
        """A joint_states message: the masses' offsets from below the trolley (``crane.geometry``: the cable
        lengths of the model, the hoist's measured one), and where they are in ``runway``."""
        core = self.core
        if core is None:
            return
        values = dict(zip(names, positions))
        model = self._config.model
        angles = [values.get(name, 0.0) for name in ANGLES]
        if not all(math.isfinite(x) for x in angles):
            return
        hook, load = mass_offsets(*angles, values.get(HOIST.sim_joint, model.L1), model.L2)
        ox, oy = self._config.runway.offset
        x, y = values.get(CART.sim_joint, 0.0) + ox, values.get(BRIDGE.sim_joint, 0.0) + oy
        core.measured(hook, load, y if math.isfinite(y) else None)
        self._masses = ((x + hook[0], y + hook[1]), (x + load[0], y + load[1]))

    def _on_state(self, msg: CraneState) -> None:
        if msg.header.frame_id != RUNWAY_FRAME:
            self.core.ignored += 1
            return
        self.core.heard(msg.crane, msg.reach_low, msg.reach_high, self._now(), (msg.footprint_low, msg.footprint_high),
                        msg.planned)

    def _on_occupancy(self, msg: Occupancy) -> None:
        if msg.crane != self.core.crane:
            return
        try:
            own = from_message(msg)
        except OccupancyRefused:  # (its planner counts and reports what it cannot use)
            return
        self.core.own(own.start_ns, own.t, own.footprint.girder)

    def refusal(self, position) -> str:
        """Why a trajectory (its knots' positions, a column per joint) is refused by the guard; '' if taken."""
        return '' if self.core is None else self.core.refusal(position)

    @property
    def reason(self) -> str:
        """Why the guard last stopped or refused a motion ('' since a trajectory was taken): for stream_state."""
        return '' if self.core is None else self.core.reason

    # -- the loop's side ---------------------------------------------------------------------

    def publish(self, stamp: int, setpoint) -> None:
        """This crane's state on /runway/state (the loop, at the stream_state cadence)."""
        core = self.core
        if core is None:
            return
        y, v, _ = core.last
        position = setpoint.position
        x = (position[core.cart] if type(position) is tuple else position) + self._config.runway.offset[0]
        verdict, mine, footprint = core.verdict, core.mine, core.footprint
        conversions.fill_crane_state(self._msg, stamp, y, v, x, *self._masses, (mine.low, mine.high),
                                     verdict.level.name.lower(), verdict.crane, (footprint.low, footprint.high),
                                     core.follows_plan)
        try:
            self._pub.publish(self._msg)
        except Exception:  # the context is shut down (SIGINT): the reference's publish ends the loop
            pass

    # -- words ---------------------------------------------------------------------------------

    def _report(self) -> None:
        core = self.core
        self._checks += 1
        changed = core.changes != self._told
        if not changed and self._checks * CHECK < REPORT:
            return
        self._checks, self._told = 0, core.changes
        verdict = core.verdict
        level = verdict.level
        what = {Level.STOP: ': motions towards it are stopped without swing and refused until the way is clear',
                Level.LOST: ': motions towards it are stopped without swing and refused until it is heard again'}
        message = f'{level.name.lower()}: {core.describe(verdict)}{what.get(level, "")}'
        mine = core.mine
        self._diagnostics.report(
            TASK, DIAGNOSTIC_LEVELS[level], message, guard=level.name.lower(), crane=verdict.crane, gap=verdict.gap,
            refusing=' '.join(f'{d:+g}' for d in sorted(verdict.blocked)) or 'none', reach_low=mine.low,
            reach_high=mine.high, planned=core.follows_plan,
            neighbours=' '.join(sorted(core.guard.neighbours)) or 'none',
            states_ignored=core.ignored, reason=core.reason)
        if changed:
            self._log(level >= Level.WARNING, f'runway guard: {message}')

    def _log(self, warning: bool, text: str) -> None:
        logger = self._node.get_logger()  # (one call site per severity: rclpy's logger insists)
        if warning:
            logger.warning(text)
        else:
            logger.info(text)

    def close(self) -> None:
        if self.core is not None:
            self._stops.close()
