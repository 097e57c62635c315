"""Streamer node: the plan on ``trajectory`` as a 1 kHz ``reference`` (contract: ROS 2 nodes, streamer).

The rules are the pure cores': what streams each tick, its corrections and watches, the state and mode
(``streaming.streamer``: the active source is a ``reference_stream.ReferenceStream`` or an
``operator.OperatorStream``), the parameters ``streaming.config``'s; this node translates messages, keeps time and
reports. It streams nothing before it knows where the axes stand (``start_position``: ``joint_states`` at rest, at
start-up and every ``~/start``). The loop runs on its own thread at absolute deadlines of the monotonic clock, never
waits on the executor, fills one pre-allocated message per tick (with network impairment on, through an
``impairment.Link``) and every ``rate / state_rate`` ticks publishes ``stream_state``. Modes (switched only at
rest): ``trajectory`` streams what the planner sends, ``operator`` follows ``cmd_vel`` (``streaming.operator``).
``~/stop`` stops without swing (``streaming.stop_request``), a motion's stop planned by ``serving.stops`` in a
worker process (this process never loads CasADi). With ``feedback`` the measured swing corrects what streams
(``streaming.feedback_port``); with ``runway`` a guard keeps it clear of other cranes (``streamer_runway``)."""
from __future__ import annotations

import time

from crane_interfaces.msg import AxisStatus, StreamState
from geometry_msgs.msg import Twist
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory

from crane_msgs_py.messages import conversions, names
from crane_msgs_py.runtime import qos
from crane_msgs_py.runtime.diagnostics import ERROR, OK, DiagnosticsPublisher
from crane_msgs_py.runtime.node_parameters import Guard, declare
from crane_msgs_py.runtime.realtime import Lateness, Ticker, lateness_summary_us, sleep_until
from crane_msgs_py.runtime.runner import LoopThread, run
from crane_planner.nodes.streamer_runway import RunwayPort
from crane_planner.serving.stops import StopWorker
from crane_planner.streaming.config import INITIAL_POSITIONS, PARAMETERS, StreamerConfig
from crane_planner.streaming.feedback_port import FeedbackPort
from crane_planner.streaming.impairment import Link
from crane_planner.streaming.operator import twist_velocities
from crane_planner.streaming.reference_stream import CATCH_UP, ReferenceStream, position_text
from crane_planner.streaming.source import Setpoint
from crane_planner.streaming.start_position import Hold, StartPosition
from crane_planner.streaming.status import stream_status
from crane_planner.streaming.stop_request import request_stop
from crane_planner.streaming.streamer import Streamer
from crane_planner.streaming.streamer_state import Mode, State
from crane_planner.streaming.trajectory_intake import trajectory_refusal

STREAM_TASK, TRAJECTORY_TASK = 'stream', 'trajectory'


class StreamerNode(Node):
    """The ``crane_streamer`` node."""

    def __init__(self, **kwargs):
        super().__init__(names.STREAMER_NODE, **kwargs)
        p = declare(self, PARAMETERS)
        self._joints = names.check_joints(p['joints'])  # ValueError: see main()
        self._msg = conversions.reference_message(p['output'], joint=list(self._joints))  # (ParameterError)
        self._write = conversions.reference_writer(self._msg).write  # its bytes, what is published
        self._config = config = self._config_of(p)  # ParameterError on a bad override
        self._impairment = config.impairment
        self._ticker = Ticker(round(1e9 / p['rate']), max_backlog=round(CATCH_UP * p['rate']))
        self._period_ns = self._ticker.period
        self._busy_wait_ns, self._timing_log = round(p['busy_wait'] * 1e9), p['timing_log']
        self._diagnostics = DiagnosticsPublisher(self)
        Guard(self, PARAMETERS, self._config_of, self._apply, self._diagnostics)
        self._publisher = self.create_publisher(type(self._msg), names.REFERENCE_TOPIC, qos.REFERENCE_QOS)
        self._state_msg = conversions.stream_state_message(self._joints)
        self._state_pub = self.create_publisher(StreamState, names.STREAM_STATE_TOPIC, qos.STREAM_STATE_QOS)
        self._state_every = max(1, round(p['rate'] / p['state_rate']))

        # Shared with the loop thread (thread-safe cores); the loop owns the ticker. The streamer's state wakes the
        # loop; nothing streams before the hold is known (start_position). Operator mode's is made at a start.
        initial = tuple(p[INITIAL_POSITIONS[joint]] for joint in self._joints)
        self._start = StartPosition(self._joints, p['hold_source'], initial, p['initial_fallback_after'])
        self._stream = ReferenceStream(self._period_ns, initial if len(initial) > 1 else initial[0],
                                       p['start_tolerance'], stopped=True)
        self._streamer = Streamer(self._stream)
        self._feedback = FeedbackPort(self._streamer, self._joints, self._period_ns * 1e-9, p['feedback_noise'])
        self._feedback.configure(config, self.get_logger().info)
        self._created_ns = self._synced_ns = self.get_clock().now().nanoseconds
        self._lateness, self._first_tick_ns = Lateness(keep_all=bool(self._timing_log)), None
        self.ticks = self.sent = self.skipped = self.accepted = self.refused = self.commands = self._ticks_window = 0
        self._link, self._window_start = Link(), time.monotonic()  # (the loop's link, the impairment of the moment)
        self.create_subscription(JointTrajectory, names.TRAJECTORY_TOPIC, self._on_trajectory, qos.TRAJECTORY_QOS)
        self.create_subscription(Twist, names.CMD_VEL_TOPIC, self._on_cmd_vel, qos.CMD_VEL_QOS)
        self.create_subscription(JointState, names.JOINT_STATES_TOPIC, self._on_joint_state, qos.JOINT_STATES_QOS)
        self.create_subscription(AxisStatus, names.AXIS_STATUS_TOPIC, self._on_axis_status, qos.AXIS_STATUS_QOS)
        self.create_service(Trigger, names.START_SERVICE, self._on_start)
        self.create_service(Trigger, names.STOP_SERVICE, self._on_stop)
        self.create_timer(1.0, self._report)
        self._loop_thread = LoopThread(self, self._loop, 'reference-loop', p['sched_priority'])
        self._stops = StopWorker(self._joints, config.model)  # ~/stop's planner: a process started in the background
        self._runway = RunwayPort(self, config, self._joints, self._streamer, self._stops, self._diagnostics)
        self.get_logger().info(f'{p["output"]} on {self.resolve_topic_name(names.REFERENCE_TOPIC)} at '
                               f'{p["rate"]:g} Hz, joints {", ".join(self._joints)}: '
                               + (self._begin() if p['auto_start'] else 'waiting for ~/start'))

    # -- parameters -------------------------------------------------------

    def _config_of(self, values: dict) -> StreamerConfig:
        """The parameters checked together; a mode or operator setting changes only at rest."""
        at_rest = hasattr(self, '_streamer') and self._streamer.source.at_rest
        return StreamerConfig.of(values, getattr(self, '_config', None), at_rest, self.get_namespace())

    def _source(self, config: StreamerConfig, hold):  # operator mode's fresh: a stick held before does not move it
        operating = Mode(config.mode) is Mode.OPERATOR
        return config.operator.stream(self._period_ns * 1e-9, hold, self._joints) if operating else self._stream

    def _apply(self, config: StreamerConfig, values, changes):
        self._stream.start_tolerance = values['start_tolerance']
        self._busy_wait_ns = round(values['busy_wait'] * 1e9)
        if config.impairment != self._impairment:
            self._impairment = config.impairment  # the loop picks it up at its next tick
            self.get_logger().info(f'network impairment: {config.impairment}')
        self._feedback.configure(config, self.get_logger().info)
        self._runway.configure(config)
        if config.changes_mode(self._config):  # (at rest: the new source starts where the old left the axes)
            self._streamer.use(Mode(config.mode), self._source(config, self._streamer.settle()))
            following = f': following {self.resolve_topic_name(names.CMD_VEL_TOPIC)}, shaper {config.operator.shaper}'
            self.get_logger().info(f'mode {config.mode}' + (following if config.mode == 'operator' else ''))
        self._config = config

    # -- operator mode (executor thread) ------------------------------------------

    def _on_cmd_vel(self, msg: Twist):
        self.commands += 1
        if self._streamer.commanded:  # stopping or stopped: commands wait for ~/start
            self._streamer.source.command(*twist_velocities(msg, self._joints))

    # -- trajectories (executor thread) -------------------------------------

    def _on_trajectory(self, msg: JointTrajectory, info: dict):
        sampled = self._stream.last_tick  # first: a handover takes over at the tick after it
        now_ns, start_ns = self.get_clock().now().nanoseconds, conversions.stamp_ns(msg.header.stamp)
        values = dict(hold_position=position_text(self._stream.hold), points=len(msg.points), start_stamp=start_ns)
        try:
            refusal = trajectory_refusal(info.get('source_timestamp', now_ns), self._created_ns,
                                         self._streamer.mode is Mode.OPERATOR, self._streamer.state is State.STOPPING)
            if refusal:
                raise ValueError(refusal)
            holds = (None, *self._stream.hold[1:]) if len(self._joints) > 1 else None  # a hoist left out: held
            columns = conversions.joint_trajectory_columns(msg, self._joints, holds)
            if refusal := self._runway.refusal(columns[1]):  # (towards a crane its guard stops for)
                raise ValueError(refusal)
            motion = self._stream.accept(*columns, start_ns, now_ns, sampled)
        except ValueError as exc:
            self.refused += 1
            self.get_logger().error(f'trajectory refused: {exc}')
            return self._diagnostics.report(TRAJECTORY_TASK, ERROR, f'trajectory refused: {exc}', error=str(exc),
                                            **values)
        self.accepted += 1
        self.get_logger().info(f'trajectory accepted: {motion.summary}')
        self._diagnostics.report(TRAJECTORY_TASK, OK, f'trajectory accepted: {motion.summary}',
                                 late_start=motion.late, error='', **values)

    def _on_joint_state(self, msg: JointState):
        self._feedback.measure(conversions.stamp_ns(msg.header.stamp), msg.name, msg.position)
        self._runway.measure(msg.name, msg.position)
        hold = self._start.on_joint_state(msg.name, msg.position, msg.velocity)
        if hold is not None:
            self._go(hold)

    def _begin(self) -> str:
        """A start: streaming from the hold once known (at once with hold_source initial_position)."""
        hold = self._start.request(self.get_clock().now().nanoseconds)
        if hold is not None:
            return self._go(hold)
        self._streamer.wait()
        return f'waiting for {self._start.waiting_for} (hold_source)'

    def _on_axis_status(self, msg: AxisStatus):
        """Axes braked to rest by their fault reaction refuse this stream: it starts again where they stand."""
        since = conversions.stamp_ns(msg.header.stamp) > self._synced_ns  # (not a fault from before it began)
        if msg.state == 'fault_hold' and self._streamer.running.is_set() and since:
            self._streamer.halt()
            self.get_logger().warn(f'the axes ran their fault reaction ({msg.message}): {self._begin()}')

    def _go(self, hold: Hold) -> str:
        self._synced_ns = self.get_clock().now().nanoseconds
        self._stream.hold_at(hold.position)
        self._feedback.reset()
        self._streamer.go(Mode(self._config.mode), self._source(self._config, self._stream.hold))
        message = f'streaming, hold {position_text(self._stream.hold)} m ({hold.source}: {hold.reason})'
        self.get_logger().info(message)
        return message

    # -- services ------------------------------------------------------------

    def _on_start(self, request, response):
        stopping = self._streamer.state is State.STOPPING
        response.success = not stopping  # a start measures again: the axes may have moved meanwhile
        response.message = ('stopping (~/stop): start again once stopped' if stopping else
                            'already streaming' if self._streamer.running.is_set() else self._begin())
        self.get_logger().info(response.message)
        return response

    def _on_stop(self, request, response):
        """Stop without swing (``streaming.stop_request``); the stream stops (refusing trajectories until
        ~/start) once at rest."""
        now, config = (lambda: self.get_clock().now().nanoseconds), self._config
        answer = request_stop(self._streamer, lambda: self._stops.take_over(self._stream, now, config.model), now,
                              config.fault_deceleration, config.fault_jerk, self._start.cancel)
        if answer.warning:
            self.get_logger().warn(answer.warning)
        response.success, response.message = True, answer.message
        self.get_logger().info(response.message)
        return response

    # -- the loop (its own thread) -----------------------------------------

    def _loop(self):
        while not self._loop_thread.stopping.is_set():
            if self._streamer.running.wait(0.1):
                self._run()

    def _run(self):
        """Stream until stopped; ticks count from a fresh epoch."""
        ticker, stream, streamer = self._ticker, self._stream, self._streamer
        ros_now, epoch = self.get_clock().now().nanoseconds, ticker.restart()
        epoch_ros = ros_now + (epoch - time.monotonic_ns())  # ROS time of tick 0
        if not streamer.start(epoch_ros, lambda: ticker.tick):
            return  # stopped meanwhile
        if self._first_tick_ns is None:  # where the timing log starts
            self._first_tick_ns = epoch_ros
        write, publisher, lateness, setpoint_at = self._write, self._publisher, self._lateness, streamer.tick
        link = self._link
        # stream.running, not the state: a ~/stop and ~/start between two ticks still restart the epoch
        while stream.running and not self._loop_thread.stopping.is_set():
            self._deliver(link.use(self._impairment))  # a new impairment: what was in flight on the old link
            k, deadline = ticker.tick, ticker.deadline
            now = link.wait(deadline, lambda ns: sleep_until(ns, self._busy_wait_ns), self._deliver)
            lateness.add(now - deadline)
            self.ticks += 1
            stamp = epoch_ros + k * ticker.period
            setpoint = setpoint_at(k, stamp)  # (a ~/stop come to rest stops the stream after this tick)
            if k % self._state_every == 0:
                self._publish_state(stamp, setpoint)
            if link.line is None:
                if not self._publish(write(stamp, *setpoint), publisher):
                    return
            else:
                link.line.send(now * 1e-9, (stamp, *setpoint))
                self._deliver(link.line.deliver(now * 1e-9))
            self.skipped += ticker.advance(now)
        self._deliver(link.use(None))  # what is still in flight; the next run starts a fresh line

    def _publish_state(self, stamp: int, setpoint: Setpoint):
        motion, streamer, m = self._stream.last_motion, self._streamer, self._stream.last_motion is not None
        conversions.fill_stream_state(self._state_msg, stamp, streamer.moving, *setpoint, motion.start_ns if m else 0,
                                      motion.duration if m else 0.0, streamer.mode is Mode.OPERATOR,
                                      motion.origin_ns if m else 0, self._feedback.corrections(), self._runway.reason)
        self._runway.publish(stamp, setpoint)
        try:
            self._state_pub.publish(self._state_msg)
        except Exception:  # the context is shut down (SIGINT): the reference's publish ends the loop
            pass

    def _deliver(self, items):
        for stamp, position, velocity, acceleration in items:
            self._publish(self._write(stamp, position, velocity, acceleration), self._publisher)

    def _publish(self, data: bytes, publisher) -> bool:
        try:
            publisher.publish(data)  # (serialized: rclpy publishes bytes as they are)
        except Exception:  # the context is shut down (SIGINT): end quietly
            self._loop_thread.stopping.set()
            return False
        self.sent += 1
        return True

    # -- diagnostics (executor thread) --------------------------------------

    def _report(self):
        hold = self._start.poll(self.get_clock().now().nanoseconds)  # no joint_states: the initial fallback
        if hold is not None:
            self.get_logger().warn(self._go(hold))
        now = time.monotonic()
        rate = (self.ticks - self._ticks_window) / max(now - self._window_start, 1e-9)
        self._ticks_window, self._window_start = self.ticks, now
        streamer = self._streamer
        status = stream_status(streamer.running.is_set(), streamer.moving, streamer.mode is Mode.OPERATOR,
                               self._start, self._loop_thread.error, self._stops.status, self.skipped, rate)
        self._diagnostics.report(
            STREAM_TASK, status.level, status.message, state=status.state, rate_hz=rate,
            target_rate_hz=1e9 / self._period_ns, **lateness_summary_us(self._lateness.take()),
            ticks=self.ticks, sent=self.sent, dropped=self._link.lost, reordered=self._link.reordered,
            skipped=self.skipped, hold_position=position_text(self._stream.hold), trajectories_accepted=self.accepted,
            trajectories_refused=self.refused, mode=self._config.mode, commands=self.commands,
            stop_planner=self._stops.status, **self._impairment.values(), **self._feedback.status())

    def destroy_node(self):
        self._loop_thread.stop()
        self._stops.close(), self._runway.close()
        if self._timing_log:
            self._lateness.dump(self._timing_log, 1e9 / self._period_ns, self._first_tick_ns)
        super().destroy_node()


def main(args=None):
    return run(StreamerNode, SingleThreadedExecutor, args)
