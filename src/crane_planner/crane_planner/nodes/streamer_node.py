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
"""
from __future__ import annotations

import json
import math
import threading
import time

import numpy as np
from crane_interfaces.msg import StreamState
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
from crane_msgs_py.params import CraneParams
from crane_msgs_py.qos import REFERENCE_QOS, STREAM_STATE_QOS, TRAJECTORY_QOS
from crane_msgs_py.realtime import Lateness, Ticker, lateness_summary_us, sleep_until
from crane_msgs_py.runner import LoopThread, run
from crane_planner.streaming.impairment import DISTRIBUTIONS, DelayLine, Impairment
from crane_planner.streaming.reference_stream import ReferenceStream, position_text

STREAM_TASK = 'stream'
TRAJECTORY_TASK = 'trajectory'


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
                       'manager; without the privilege a warning and normal scheduling); 0 = normal scheduling',
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
}


class StreamerNode(Node):
    """The ``crane_streamer`` node."""

    def __init__(self, **kwargs):
        super().__init__(STREAMER_NODE, **kwargs)
        p = declare(self, PARAMETERS)
        self._joints = check_joints(p['joints'])  # ValueError: see main()
        self._msg = reference_message(p['output'], joint=list(self._joints))  # ParameterError: unknown output
        self._impairment = self._impairment_of(p)  # ParameterError on a bad override
        self._ticker = Ticker(round(1e9 / p['rate']))
        self._period_ns = self._ticker.period
        self._busy_wait_ns = round(p['busy_wait'] * 1e9)
        self._timing_log = p['timing_log']
        self._diagnostics = DiagnosticsPublisher(self)
        Guard(self, PARAMETERS, self._impairment_of, self._apply, self._diagnostics)
        self._publisher = self.create_publisher(type(self._msg), REFERENCE_TOPIC, REFERENCE_QOS)
        self._state_msg = stream_state_message(self._joints)
        self._state_pub = self.create_publisher(StreamState, STREAM_STATE_TOPIC, STREAM_STATE_QOS)
        self._state_every = max(1, round(p['rate'] / p['state_rate']))

        # Shared with the loop thread (the core is thread-safe); the loop owns the ticker.
        # _running wakes the loop; the core's state decides what trajectories it takes.
        hold = p['initial_position'] if len(self._joints) == 1 else (p['initial_position'],
                                                                     p['initial_hoist_position'])
        self._stream = ReferenceStream(self._period_ns, hold, p['start_tolerance'], stopped=not p['auto_start'])
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
        self.create_service(Trigger, START_SERVICE, self._on_start)
        self.create_service(Trigger, STOP_SERVICE, self._on_stop)
        self.create_timer(1.0, self._report)
        if p['auto_start']:
            self._running.set()
        self._loop_thread = LoopThread(self, self._loop, 'reference-loop', p['sched_priority'])
        self.get_logger().info(f'streaming {p["output"]} on {self.resolve_topic_name(REFERENCE_TOPIC)} at '
                               f'{p["rate"]:g} Hz, {", ".join(self._joints)} held at {self._hold_text()} m'
                               + ('' if p['auto_start'] else ' (waiting for ~/start)'))

    # -- parameters -------------------------------------------------------

    @staticmethod
    def _impairment_of(values: dict) -> Impairment:
        return Impairment(delay=values['network.delay'], jitter=values['network.jitter'],
                          distribution=values['network.distribution'], loss=values['network.loss'],
                          reorder=values['network.reorder'], seed=values['network.seed'])

    def _apply(self, impairment: Impairment, values, changes):
        self._stream.start_tolerance = values['start_tolerance']
        self._busy_wait_ns = round(values['busy_wait'] * 1e9)
        if impairment != self._impairment:
            self._impairment = impairment  # the loop picks it up at its next tick
            self.get_logger().info(f'network impairment: {impairment}')

    # -- trajectories (executor thread) -------------------------------------

    def _on_trajectory(self, msg: JointTrajectory, info: dict):
        now_ns = self.get_clock().now().nanoseconds
        start_ns = stamp_ns(msg.header.stamp)
        try:
            if info.get('source_timestamp', now_ns) < self._created_ns:
                raise ValueError('published before this streamer started (a latched old plan is not replayed)')
            motion = self._stream.accept(*self._arrays(msg), start_ns, now_ns)
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
        if self._running.is_set():
            response.message = 'already streaming'
        else:
            self._stream.resume()
            self._running.set()
            response.message = f'streaming, hold {self._hold_text()} m'
        self.get_logger().info(response.message)
        return response

    def _on_stop(self, request, response):
        response.success = True
        if not self._running.is_set():
            response.message = 'already stopped'
        else:
            self._running.clear()
            if self._stream.stop() is not None:  # dropped where it was
                self.get_logger().warn(f'stopped during a motion; holding {self._hold_text()} m')
            response.message = 'stopped'
        self.get_logger().info(response.message)
        return response

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
            position, velocity, acceleration = sample(k)
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
        fill_stream_state(self._state_msg, stamp, stream.streaming, position, velocity, acceleration,
                          motion.start_ns if motion else 0, motion.duration if motion else 0.0)
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
        state = ('streaming' if self._stream.streaming else 'holding') if running else 'stopped'
        error = self._loop_thread.error
        level = ERROR if error else WARN if self.skipped else OK
        message = f'the loop stopped: {error}' if error else f'{state} at {rate:.1f} Hz'
        imp = self._impairment
        self._diagnostics.report(
            STREAM_TASK, level, message, state=state, rate_hz=rate,
            target_rate_hz=1e9 / self._period_ns, **summary, ticks=self.ticks, sent=self.sent, dropped=self.dropped,
            reordered=self.reordered, skipped=self.skipped, hold_position=self._hold_text(),
            trajectories_accepted=self.accepted, trajectories_refused=self.refused,
            network_delay=imp.delay, network_jitter=imp.jitter, network_distribution=imp.distribution,
            network_loss=imp.loss, network_reorder=imp.reorder)

    def destroy_node(self):
        self._loop_thread.stop()
        if self._timing_log and self._lateness.all is not None:
            with open(self._timing_log, 'w') as f:
                json.dump({'rate_hz': 1e9 / self._period_ns, 'first_tick_ns': self._first_tick_ns,
                           'lateness_us': [x * 1e-3 for x in self._lateness.all]}, f)
        super().destroy_node()


def main(args=None):
    return run(StreamerNode, SingleThreadedExecutor, args)
