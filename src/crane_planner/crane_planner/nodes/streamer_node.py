"""Streamer node: the plan on ``trajectory`` as a 1 kHz ``reference`` (contract: ROS 2 nodes, streamer).

The motion rules (which trajectories are accepted, where a motion starts,
what each tick publishes, the hold between motions) are the pure core's,
``reference_stream.ReferenceStream``; this node translates messages, keeps
time and reports. A trajectory published before the node started (a latched
old plan) is refused here: only the transport knows when it was published.
The loop runs on its own thread at absolute deadlines of the monotonic
clock, never waits on the executor, asks the core for each tick's sample,
fills one pre-allocated message per tick and, with network impairment on,
holds samples in a ``impairment.DelayLine`` and publishes them itself when
they are due. Every ``rate / state_rate`` ticks it also publishes the stream's
state (``crane_interfaces/StreamState`` on ``stream_state``, not impaired: a
status, like ros2_controllers' controller_state), from which the planner
follows an executed move by this clock and learns where the axes are held.

Two modes (``mode``, switched only at rest): ``trajectory`` streams what the
planner sends (a trajectory during a motion is a handover, see the core);
``operator`` follows ``cmd_vel`` (``geometry_msgs/Twist``: ``linear.x`` the
cart's velocity, ``linear.z`` the load's vertical velocity, + = up, the rope
shortening) through ``streaming.operator.OperatorStream``: jerk-limited by
ruckig within the ``operator.*`` limits and shaped online by
``operator_shaper`` at every tick. ``~/stop`` stops without swing: in
operator mode by a zero command, during a trajectory's motion by an NVF stop
from the motion's state (``serving.transitions.stop``, the swing the model's);
the stream stops once the crane is at rest.
"""
from __future__ import annotations

import json
import math
import threading
import time
from typing import NamedTuple

import numpy as np
from crane_interfaces.msg import StreamState
from geometry_msgs.msg import Twist
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory

from crane_msgs_py.conversions import (
    fill_reference,
    fill_stream_state,
    joint_trajectory_to_arrays,
    reference_message,
    stamp_ns,
    stream_state_message,
)
from crane_msgs_py.diagnostics import ERROR, OK, WARN, DiagnosticsPublisher
from crane_msgs_py.names import (
    CMD_VEL_TOPIC,
    HOIST_JOINT,
    OUTPUT_JOINT_TRAJECTORY,
    OUTPUTS,
    REFERENCE_TOPIC,
    START_SERVICE,
    STOP_SERVICE,
    STREAM_STATE_TOPIC,
    STREAMER_NODE,
    TRAJECTORY_TOPIC,
    check_joints,
)
from crane_msgs_py.node_parameters import Guard, declare, float_range, int_range
from crane_msgs_py.params import PARAMETER_DESCRIPTIONS, PARAMETER_NAMES, CraneParams, ParameterError, check_choice
from crane_msgs_py.qos import CMD_VEL_QOS, REFERENCE_QOS, STREAM_STATE_QOS, TRAJECTORY_QOS
from crane_msgs_py.realtime import Lateness, Ticker, lateness_summary_us, sleep_until
from crane_msgs_py.runner import LoopThread, run
from crane_planner.streaming.impairment import DISTRIBUTIONS, DelayLine, Impairment
from crane_planner.streaming.operator import OPERATOR_SHAPERS, AxisLimits, OperatorStream
from crane_planner.streaming.reference_stream import ReferenceStream, position_text

MODES = ('trajectory', 'operator')

STREAM_TASK = 'stream'
TRAJECTORY_TASK = 'trajectory'
#: How far ahead (s) a ~/stop during a motion takes over (its NVF stop is planned in milliseconds).
STOP_LEAD = 0.1


class _Config(NamedTuple):
    """The streamer's parameters checked together: the link's impairment, the crane model, the mode and
    the operator mode's settings (shaper, cmd_timeout, limits per axis, hoist range, model)."""

    impairment: Impairment
    model: CraneParams
    mode: str
    operator: tuple


PARAMETERS = {
    'rate': (1000.0, 'publishing rate of reference (Hz); fixed at start-up',
             {**float_range(1.0, 10000.0), 'read_only': True}),
    'output': (OUTPUT_JOINT_TRAJECTORY, 'reference type: joint_trajectory (one point: position, velocity, '
               'acceleration) or float64_array (Float64MultiArray [position]); fixed at start-up',
               {'additional_constraints': f'one of {", ".join(OUTPUTS)}', 'read_only': True}),
    'state_rate': (50.0, 'publishing rate of stream_state (Hz), at most rate; fixed at start-up',
                   {**float_range(1.0, 1000.0), 'read_only': True}),
    'auto_start': (True, 'start streaming at start-up (else wait for ~/start)', {'read_only': True}),
    'initial_position': (0.0, 'hold position (m) before the first motion', {'read_only': True}),
    'joints': (['cart'], 'the streamed joints: [cart] or [cart, hoist] (the reference then carries a column '
                         'per joint, float64_array [cart, hoist]); fixed at start-up',
               {'additional_constraints': '[cart] or [cart, hoist]', 'read_only': True}),
    'initial_hoist_position': (CraneParams.L1, 'with a hoist: its hold position (m, the upper cable\'s length) '
                                               'before the first motion', {'read_only': True}),
    'start_tolerance': (1e-6, 'largest distance (m) between a trajectory\'s first position and the hold '
                        'position; farther is a jump and the trajectory is refused', float_range(0.0, 1.0)),
    'busy_wait': (1e-4, 'the last part (s) of each tick period spent spinning instead of sleeping, for '
                  'wake-up precision at the cost of CPU', float_range(0.0, 1e-3)),
    'sched_priority': (50, 'SCHED_FIFO priority of the loop thread, 1..99 (as ros2_control\'s controller '
                       'manager; without the privilege a warning and normal scheduling), the executor thread one '
                       'below, the middleware\'s receive threads two below; 0 = normal scheduling',
                       {**int_range(0, 99), 'read_only': True}),
    'timing_log': ('', 'file to write every tick lateness to at shutdown, JSON {rate_hz, first_tick_ns (ROS '
                   'time of the first tick), lateness_us: [...]}, ticks of later ~/start runs appended; '
                   'empty = off',
                   {'read_only': True}),
    'network.delay': (0.0, 'impairment: fixed delay (s) of every message', float_range(0.0, 10.0)),
    'network.jitter': (0.0, 'impairment: standard deviation (s) of the random delay', float_range(0.0, 10.0)),
    'network.distribution': ('normal', f'impairment: jitter distribution, one of {", ".join(DISTRIBUTIONS)} '
                             '(normal/uniform zero-mean, exponential one-sided)',
                             {'additional_constraints': f'one of {", ".join(DISTRIBUTIONS)}'}),
    'network.loss': (0.0, 'impairment: probability that a message is lost', float_range(0.0, 1.0)),
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
                         'the crane (without swing)', float_range(0.001, 10.0)),
    'operator.max_velocity': (0.3, 'operator mode: the cart\'s velocity limit (m/s)', float_range(1e-6, 100.0)),
    'operator.max_acceleration': (0.5, 'operator mode: the cart\'s acceleration limit (m/s^2)',
                                  float_range(1e-6, 1000.0)),
    'operator.max_jerk': (5.0, 'operator mode: the cart\'s jerk limit (m/s^3)', float_range(1e-6, 1e6)),
    'operator.max_hoist_velocity': (0.2, 'operator mode: the hoist\'s velocity limit (m/s)',
                                    float_range(1e-6, 100.0)),
    'operator.max_hoist_acceleration': (0.5, 'operator mode: the hoist\'s acceleration limit (m/s^2)',
                                        float_range(1e-6, 1000.0)),
    'operator.max_hoist_jerk': (5.0, 'operator mode: the hoist\'s jerk limit (m/s^3)', float_range(1e-6, 1e6)),
    'operator.hoist_range': ([0.1, 3.0], 'operator mode: the shortest and longest rope (m) the hoist may reach',
                             {'additional_constraints': '[shortest, longest], 0 < shortest < longest'}),
    **{name: (getattr(CraneParams, name), f'crane model of the operator shaper and of a ~/stop: '
                                          f'{PARAMETER_DESCRIPTIONS[name]}', float_range(0.0, 1e4))
       for name in PARAMETER_NAMES},
}


class StreamerNode(Node):
    """The ``crane_streamer`` node."""

    def __init__(self, **kwargs):
        super().__init__(STREAMER_NODE, **kwargs)
        p = declare(self, PARAMETERS)
        self._joints = check_joints(p['joints'])  # ValueError: see main()
        self._msg = reference_message(p['output'], joint=list(self._joints))  # ParameterError: unknown output
        self._mode = p['mode']
        self._operator: OperatorStream | None = None  # the operator mode's stream while in that mode
        self._stop_at_rest = False  # a ~/stop waits for the crane to come to rest
        self._stopper = None  # ~/stop's NVF solvers during a motion (a dispatch.SolverCache), built in the background
        config = self._config_of(p)  # ParameterError on a bad override
        self._impairment = config.impairment
        self._ticker = Ticker(round(1e9 / p['rate']))
        self._period_ns = self._ticker.period
        self._busy_wait_ns = round(p['busy_wait'] * 1e9)
        self._timing_log = p['timing_log']
        self._diagnostics = DiagnosticsPublisher(self)
        Guard(self, PARAMETERS, self._config_of, self._apply, self._diagnostics)
        self._model = config.model
        self._publisher = self.create_publisher(type(self._msg), REFERENCE_TOPIC, REFERENCE_QOS)
        self._state_msg = stream_state_message(self._joints)
        self._state_pub = self.create_publisher(StreamState, STREAM_STATE_TOPIC, STREAM_STATE_QOS)
        self._state_every = max(1, round(p['rate'] / p['state_rate']))

        # Shared with the loop thread (the core is thread-safe); the loop owns the ticker.
        # _running wakes the loop; the core's state decides what trajectories it takes.
        hold = p['initial_position'] if len(self._joints) == 1 else (p['initial_position'],
                                                                     p['initial_hoist_position'])
        self._stream = ReferenceStream(self._period_ns, hold, p['start_tolerance'], stopped=not p['auto_start'])
        self._operator_config = config.operator
        if self._mode == 'operator':
            self._operator = self._operator_of(config, hold)
        self._running = threading.Event()
        self._created_ns = self.get_clock().now().nanoseconds
        self._lateness = Lateness(keep_all=bool(self._timing_log))
        self._first_tick_ns = None
        self.ticks = self.sent = self.dropped = self.reordered = self.skipped = 0
        self._counted = (0, 0)  # dropped, reordered before the current link
        self.accepted = self.refused = 0
        self._ticks_window = 0
        self._window_start = time.monotonic()

        self.create_subscription(JointTrajectory, TRAJECTORY_TOPIC, self._on_trajectory, TRAJECTORY_QOS)
        self.create_subscription(Twist, CMD_VEL_TOPIC, self._on_cmd_vel, CMD_VEL_QOS)
        self.commands = 0
        self.create_service(Trigger, START_SERVICE, self._on_start)
        self.create_service(Trigger, STOP_SERVICE, self._on_stop)
        self.create_timer(1.0, self._report)
        if p['auto_start']:
            self._running.set()
        self._loop_thread = LoopThread(self, self._loop, 'reference-loop', p['sched_priority'])
        self._stopper_build = threading.Thread(target=self._build_stopper, name='stop-solver', daemon=True)
        self._stopper_build.start()
        self.get_logger().info(f'streaming {p["output"]} on {self.resolve_topic_name(REFERENCE_TOPIC)} at '
                               f'{p["rate"]:g} Hz, {", ".join(self._joints)} held at {self._hold_text()} m'
                               + ('' if p['auto_start'] else ' (waiting for ~/start)'))

    # -- parameters -------------------------------------------------------

    def _config_of(self, values: dict) -> '_Config':
        """The parameters checked together; a mode or operator setting changes only at rest."""
        impairment = Impairment(delay=values['network.delay'], jitter=values['network.jitter'],
                                distribution=values['network.distribution'], loss=values['network.loss'],
                                reorder=values['network.reorder'], seed=values['network.seed'])
        model = CraneParams(**{name: values[name] for name in PARAMETER_NAMES})
        check_choice('mode', values['mode'], MODES)
        check_choice('operator_shaper', values['operator_shaper'], OPERATOR_SHAPERS)
        shortest, longest = (list(values['operator.hoist_range']) + [0.0, 0.0])[:2]
        if len(values['operator.hoist_range']) != 2 or not 0.0 < shortest < longest:
            raise ParameterError('operator.hoist_range must be [shortest, longest] with 0 < shortest < longest (m)')
        limits = (AxisLimits(values['operator.max_velocity'], values['operator.max_acceleration'],
                             values['operator.max_jerk']),
                  AxisLimits(values['operator.max_hoist_velocity'], values['operator.max_hoist_acceleration'],
                             values['operator.max_hoist_jerk']))
        operator = (values['operator_shaper'], values['cmd_timeout'], limits, (shortest, longest), model)
        if hasattr(self, '_stream'):  # a change (not the start-up values)
            changed = values['mode'] != self._mode or (self._mode == 'operator' and operator != self._operator_config)
            if changed and not self._at_rest():
                raise ParameterError('mode and the operator settings change only with the crane at rest (no '
                                     'motion streaming, the operator\'s command played out)')
        return _Config(impairment, model, values['mode'], operator)

    def _operator_of(self, config: '_Config', hold) -> OperatorStream:
        shaper, timeout, limits, hoist_range, model = config.operator
        start = hold if isinstance(hold, tuple) else (hold,)
        return OperatorStream(self._period_ns * 1e-9, start, limits[:len(start)], shaper, model, timeout,
                              hoist_range)

    def _at_rest(self) -> bool:
        if self._operator is not None:
            return self._operator.at_rest
        return not self._stream.streaming and not self._stream.queued

    def _apply(self, config: '_Config', values, changes):
        self._stream.start_tolerance = values['start_tolerance']
        self._busy_wait_ns = round(values['busy_wait'] * 1e9)
        self._model = config.model
        if config.impairment != self._impairment:
            self._impairment = config.impairment  # the loop picks it up at its next tick
            self.get_logger().info(f'network impairment: {config.impairment}')
        if config.mode != self._mode or (config.mode == 'operator' and config.operator != self._operator_config):
            if self._operator is not None:  # (at rest: the stream holds where the operator left the axes)
                position = self._operator.position
                self._stream.hold_at(position if len(position) > 1 else position[0])
            self._operator = self._operator_of(config, self._stream.hold) if config.mode == 'operator' else None
            self.get_logger().info(f'mode {config.mode}' + (f': following {self.resolve_topic_name(CMD_VEL_TOPIC)}, '
                                                            f'shaper {config.operator[0]}' if self._operator else ''))
        self._mode, self._operator_config = config.mode, config.operator

    # -- operator mode and stops (executor thread) ------------------------------

    def _on_cmd_vel(self, msg: Twist):
        operator = self._operator
        self.commands += 1
        if operator is None:
            return
        if self._stop_at_rest or not self._running.is_set():  # stopping or stopped: commands wait for ~/start
            return
        # the hoist's position is the rope's length: + up (linear.z) shortens it
        operator.command(msg.linear.x, -msg.linear.z)

    def _build_stopper(self):
        """Build the NVF solvers a ~/stop during a motion plans with, in the background at low priority."""
        import os

        from crane_planner.planning.continuation import MotionState, problem_start
        from crane_planner.planning.dispatch import PlanOptions, SolverCache, VariationalRequest
        try:
            os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), 10)  # this thread only (Linux)
        except (AttributeError, OSError):
            pass
        cache = SolverCache()
        hoist = HOIST_JOINT in self._joints
        model = self._model
        state = MotionState((0.0, 0.1, 0.0), hoist=(model.L1, 0.0, 0.0) if hoist else None)
        start, model = problem_start(state, model)
        try:
            cache(VariationalRequest('plan', 'nvf', (0.1, 0.0) if hoist else 0.1, 1.5, model, PlanOptions(), start,
                                     True))
        except Exception as exc:  # the solvers are built on first use then
            self.get_logger().warn(f'building the stop solver failed: {exc}')
        self._stopper = cache

    def _stop_motion(self) -> str:
        """Hand the streaming motion over to an NVF stop from its state; what is done (ValueError: why not)."""
        from crane_planner.planning.dispatch import PlanOptions, SolverCache
        from crane_planner.serving import transitions
        from crane_planner.serving.moves import axis_samples
        from crane_planner.streaming.knots import knot_times
        motion = self._stream.last_motion
        if motion is None or not self._stream.streaming:
            raise ValueError('no motion is streaming')
        running = transitions.Running.of_interps(self._joints, motion.interps, motion.origin_ns)
        handover = self.get_clock().now().nanoseconds + round(STOP_LEAD * 1e9)
        if handover >= running.end_ns:
            raise ValueError('the motion ends before a stop could take over')
        state = transitions.handover_state(running, handover, None, self._model)
        plan = transitions.stop(self._stopper or SolverCache(), running, handover, state, 'nvf', self._model,
                                PlanOptions())
        times = knot_times(plan)
        samples = axis_samples(plan, times)
        starts = transitions.joint_starts(plan, state)
        columns = [np.column_stack([s0 + s.position for s, s0 in zip(samples, starts)]),
                   np.column_stack([s.velocity for s in samples]), np.column_stack([s.acceleration for s in samples])]
        if len(self._joints) == 1:
            columns = [c[:, 0] for c in columns]
        self._stream.accept(times, *columns, handover, self.get_clock().now().nanoseconds)
        where = state.cart[0] + plan.displacement
        return f'stopping without swing at {where:.6g} m in {plan.duration:.3g} s (nvf), then stopped'

    # -- trajectories (executor thread) -------------------------------------

    def _on_trajectory(self, msg: JointTrajectory, info: dict):
        sampled = self._stream.last_tick  # first: a handover takes over at the tick after it
        now_ns = self.get_clock().now().nanoseconds
        start_ns = stamp_ns(msg.header.stamp)
        try:
            if info.get('source_timestamp', now_ns) < self._created_ns:
                raise ValueError('published before this streamer started (a latched old plan is not replayed)')
            if self._operator is not None:
                raise ValueError('the streamer is in operator mode (it follows cmd_vel); set mode to trajectory '
                                 'at rest to stream trajectories')
            if self._stop_at_rest:
                raise ValueError('the streamer is stopping (~/stop)')
            motion = self._stream.accept(*self._arrays(msg), start_ns, now_ns, sampled)
        except ValueError as exc:
            self.refused += 1
            self.get_logger().error(f'trajectory refused: {exc}')
            self._diagnostics.report(TRAJECTORY_TASK, ERROR, f'trajectory refused: {exc}', error=str(exc),
                                     hold_position=self._hold_text(), points=len(msg.points),
                                     start_stamp=start_ns)
            return
        self.accepted += 1
        self.get_logger().info(f'trajectory accepted: {motion.summary}')
        self._diagnostics.report(TRAJECTORY_TASK, OK, f'trajectory accepted: {motion.summary}',
                                 hold_position=self._hold_text(), points=len(msg.points),
                                 start_stamp=start_ns, late_start=motion.late, error='')

    def _arrays(self, msg: JointTrajectory) -> tuple:
        """(t, position, velocity, acceleration) of the streamed joints, a column each with several; a joint
        the trajectory leaves out (the hoist of a cart-only plan) holds where it is."""
        t, p, v, a = joint_trajectory_to_arrays(msg, self._joints[0])
        if len(self._joints) == 1:
            return t, p, v, a
        columns = [(p, v, a)]
        for joint, hold in zip(self._joints[1:], self._stream.hold[1:]):
            if joint in msg.joint_names:
                columns.append(joint_trajectory_to_arrays(msg, joint)[1:])
            else:
                columns.append((np.full(t.size, hold), np.zeros(t.size), np.zeros(t.size)))
        return (t, *(np.column_stack(c) for c in zip(*columns)))

    def _hold_text(self) -> str:
        return position_text(self._stream.hold)

    # -- services ------------------------------------------------------------

    def _on_start(self, request, response):
        response.success = True
        if self._stop_at_rest:
            response.success = False
            response.message = 'stopping (~/stop): start again once stopped'
        elif self._running.is_set():
            response.message = 'already streaming'
        else:
            if self._operator is not None:  # a stick held before the stop does not move the crane now
                self._operator.stop()
            self._stream.resume()
            self._running.set()
            response.message = f'streaming, hold {self._hold_text()} m'
        self.get_logger().info(response.message)
        return response

    def _on_stop(self, request, response):
        """Stop without swing: at rest at once; in operator mode the command zeroed; during a motion an
        NVF stop from its state. The stream stops (refusing trajectories until ~/start) once at rest."""
        response.success = True
        if not self._running.is_set():
            response.message = 'already stopped'
        elif self._stop_at_rest:
            response.message = 'already stopping'
        elif self._operator is not None and not self._operator.at_rest:
            self._operator.stop()
            self._stop_at_rest = True
            response.message = (f'stopping: the command set to zero, braked and shaped (at rest within '
                                f'{self._operator.delay():.3g} s of the braking), then stopped')
        elif self._operator is None and self._stream.streaming:
            try:
                response.message = self._stop_motion()
                self._stop_at_rest = True
            except ValueError as exc:  # no stop without swing: hold where the stream is (a hard stop)
                self._halt()
                response.message = f'stopped during a motion, holding {self._hold_text()} m: no stop without ' \
                                   f'swing could be planned ({exc})'
                self.get_logger().warn(response.message)
        else:
            self._halt()
            response.message = 'stopped'
        self.get_logger().info(response.message)
        return response

    def _halt(self):
        """Stop streaming now (the loop holds nothing: it waits for ~/start)."""
        self._stop_at_rest = False
        self._running.clear()
        self._stream.stop()

    # -- the loop (its own thread) -----------------------------------------

    def _loop(self):
        while not self._loop_thread.stopping.is_set():
            if not self._running.wait(0.1):
                continue
            self._run()

    def _run(self):
        """Stream until stopped; ticks count from a fresh epoch."""
        ticker, stream = self._ticker, self._stream
        ros_now, epoch = self.get_clock().now().nanoseconds, ticker.restart()
        epoch_ros = ros_now + (epoch - time.monotonic_ns())  # ROS time of tick 0
        if not stream.start(epoch_ros, lambda: ticker.tick):
            return  # stopped meanwhile
        if self._first_tick_ns is None:  # where the timing log starts
            self._first_tick_ns = epoch_ros
        impairment = line = None
        msg, publisher, lateness, sample = self._msg, self._publisher, self._lateness, stream.sample
        # stream.running, not _running: a ~/stop and ~/start between two ticks still restart the epoch
        while stream.running and not self._loop_thread.stopping.is_set():
            if self._impairment is not impairment:
                impairment = self._impairment
                if line is not None:  # flush what was in flight on the old link
                    self._deliver(line, math.inf)
                self._counted = (self.dropped, self.reordered)  # the new link counts from 0
                line = DelayLine(impairment) if impairment.active else None
            k, deadline = ticker.tick, ticker.deadline
            now = self._wait(deadline, line)
            lateness.add(now - deadline)
            self.ticks += 1
            operator = self._operator
            if operator is None:
                position, velocity, acceleration = sample(k)
            else:
                position, velocity, acceleration = operator.sample()
            if self._stop_at_rest and self._at_rest():  # a ~/stop's motion has ended: stop here
                self._stop_at_rest = False
                self._running.clear()
                if operator is not None:
                    stream.hold_at(operator.position if len(operator.position) > 1 else operator.position[0])
                stream.stop()
            stamp = epoch_ros + k * ticker.period
            if k % self._state_every == 0:
                self._publish_state(stamp, position, velocity, acceleration)
            if line is None:
                fill_reference(msg, stamp, position, velocity, acceleration)
                if not self._publish(msg, publisher):
                    return
            else:
                line.send(now * 1e-9, (stamp, position, velocity, acceleration))
                self._deliver(line, now * 1e-9)
            self.skipped += ticker.advance(now)
        if line is not None:
            self._deliver(line, math.inf)

    def _publish_state(self, stamp: int, position: float, velocity: float, acceleration: float):
        stream = self._stream
        motion = stream.last_motion
        operator = self._operator
        streaming = stream.streaming if operator is None else not operator.at_rest
        fill_stream_state(self._state_msg, stamp, streaming, position, velocity, acceleration,
                          motion.start_ns if motion else 0, motion.duration if motion else 0.0, operator is not None,
                          motion.origin_ns if motion else 0)
        try:
            self._state_pub.publish(self._state_msg)
        except Exception:  # the context is shut down (SIGINT): the reference's publish ends the loop
            pass

    def _wait(self, deadline: int, line: DelayLine | None) -> int:
        """Sleep until the tick's deadline, delivering delayed messages that fall due meanwhile."""
        while line is not None and len(line):
            due = round(line.next_due() * 1e9)
            if due >= deadline:
                break
            self._deliver(line, sleep_until(due, self._busy_wait_ns) * 1e-9)
        return sleep_until(deadline, self._busy_wait_ns)

    def _deliver(self, line: DelayLine, now_s: float):
        msg, publisher = self._msg, self._publisher
        for stamp, position, velocity, acceleration in line.deliver(now_s):
            fill_reference(msg, stamp, position, velocity, acceleration)
            self._publish(msg, publisher)
        self.dropped, self.reordered = self._counted[0] + line.lost, self._counted[1] + line.reordered

    def _publish(self, msg, publisher) -> bool:
        try:
            publisher.publish(msg)
        except Exception:  # the context is shut down (SIGINT): end quietly
            self._loop_thread.stopping.set()
            return False
        self.sent += 1
        return True

    # -- diagnostics (executor thread) --------------------------------------

    def _report(self):
        now = time.monotonic()
        ticks, elapsed = self.ticks, now - self._window_start
        rate = (ticks - self._ticks_window) / elapsed if elapsed > 0 else 0.0
        self._ticks_window, self._window_start = ticks, now
        summary = lateness_summary_us(self._lateness.take())
        running = self._running.is_set()
        moving = self._stream.streaming if self._operator is None else not self._operator.at_rest
        state = ('streaming' if moving else 'holding') if running else 'stopped'
        if self._operator is not None and running:
            state = f'operator, {state}'
        error = self._loop_thread.error
        level = ERROR if error else WARN if self.skipped else OK
        message = f'the loop stopped: {error}' if error else f'{state} at {rate:.1f} Hz'
        imp = self._impairment
        self._diagnostics.report(
            STREAM_TASK, level, message, state=state, rate_hz=rate,
            target_rate_hz=1e9 / self._period_ns, **summary, ticks=self.ticks, sent=self.sent, dropped=self.dropped,
            reordered=self.reordered, skipped=self.skipped, hold_position=self._hold_text(),
            trajectories_accepted=self.accepted, trajectories_refused=self.refused, mode=self._mode,
            commands=self.commands,
            network_delay=imp.delay, network_jitter=imp.jitter, network_distribution=imp.distribution,
            network_loss=imp.loss, network_reorder=imp.reorder)

    def destroy_node(self):
        self._loop_thread.stop()
        # CasADi must not be building in that thread while the interpreter exits: a SIGSEGV (a streamer
        # stopped within seconds of its start, as test_workspace does, died so about once in ten)
        if self._stopper_build.is_alive():
            self.get_logger().info('waiting for the stop solver to be built')
            self._stopper_build.join()
        if self._timing_log and self._lateness.all is not None:
            with open(self._timing_log, 'w') as f:
                json.dump({'rate_hz': 1e9 / self._period_ns, 'first_tick_ns': self._first_tick_ns,
                           'lateness_us': [x * 1e-3 for x in self._lateness.all]}, f)
        super().destroy_node()


def main(args=None):
    return run(StreamerNode, SingleThreadedExecutor, args)
