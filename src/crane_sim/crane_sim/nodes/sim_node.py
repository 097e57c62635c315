"""Simulator node: the crane driven by ``reference`` in real time (contract: ROS 2 nodes, sim).

The plant (``crane_sim.simulator.CraneSimulator``: Eqs. 18-19 plus the servo
of Eq. 6) is stepped every ``step`` seconds on its own thread at absolute
deadlines of the monotonic clock and publishes ``joint_states`` every
1/``publish_rate`` of simulated time. Each step the loop takes the references
the middleware received since the last (``reference_reader.ReferenceReader``:
no executor hands 1 kHz messages over), checks, stamps and counts them
(``reference_intake.ReferenceIntake``: non-finite, stale and out-of-order ones
are ignored, latency and gaps measured, unstamped ones put on a grid) and
plays them out by their stamps, ``playout_delay`` behind
(``playout.ReferencePlayout``): the plant's time runs that far behind the
clock, and ``joint_states`` carry plant time, so they line up with the
reference stamps. Between the playouts and the plant sits the axis
controller (``axis_controller.AxisController``): it passes the playouts'
reference on while it tracks, and when the stream is lost (the playouts'
``reference_timeout``) it brakes every axis's reference to rest along the
fault reaction's ramp (``fault_deceleration``, ``fault_jerk``) and holds
until a stream at rest where the axes stand; its state goes to
``axis_status`` (crane_interfaces/AxisStatus) and ``/diagnostics``. The loop
alone touches the simulator, the controller, the sensor and the gusts, so
parameter changes and resets are handed over too; ``~/reset`` and ``~/push``
answer once the loop has applied them and measured the crane as it is then.
``joint_states`` are what a camera would report (``crane_sim.sensor``): each
sample taken at its stamp and published ``sensor_latency`` later, some lost
(``sensor_dropout``), the angles noisy (``noise``); ``crane_markers`` show the
crane as it is. Wind and gusts (``crane_sim.disturbances``) act on both masses.
The executor (an EventsExecutor) serves the parameters, services and timers.
"""
from __future__ import annotations

import math
import threading
import time
from collections import deque

import numpy as np
from crane_interfaces.msg import AxisStatus
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger
from visualization_msgs.msg import MarkerArray

from crane_msgs_py.crane import params as crane_params
from crane_msgs_py.crane.drive import FAULT_STATES, AxisState
from crane_msgs_py.crane.params import PARAMETER_NAMES, CraneParams, model_parameters
from crane_msgs_py.messages.conversions import (
    crane_markers_message,
    fill_crane_markers,
    fill_joint_state,
    joint_state_message,
    read_reference,
    set_stamp,
)
from crane_msgs_py.messages.names import (
    AXIS_STATUS_TOPIC,
    BRIDGE_JOINT,
    DEFAULT_FRAME_ID,
    JOINT_STATES_TOPIC,
    MARKERS_TOPIC,
    OUTPUT_FLOAT64_ARRAY,
    OUTPUT_JOINT_TRAJECTORY,
    PUSH_SERVICE,
    REFERENCE_TOPIC,
    RESET_SERVICE,
    SIM_NODE,
    check_joints,
)
from crane_msgs_py.runtime.diagnostics import ERROR, OK, WARN, DiagnosticsPublisher
from crane_msgs_py.runtime.node_parameters import Guard, declare, float_range, int_range
from crane_msgs_py.runtime.qos import AXIS_STATUS_QOS, JOINT_STATES_QOS, MARKERS_QOS, REFERENCE_EVERY_SAMPLE_QOS
from crane_msgs_py.runtime.realtime import Lateness, Ticker, lateness_summary_us, sleep_until
from crane_msgs_py.runtime.runner import LoopThread, run
from crane_sim.axis_controller import AxisController, FaultConfig, Offer
from crane_sim.disturbances import Disturbances, Gust
from crane_sim.nodes.reference_reader import REFERENCE_TYPES, ReferenceReader
from crane_sim.playout import BACKLOG, ReferencePlayout, StallAllowance
from crane_sim.reference_intake import ReferenceIntake
from crane_sim.sensor import Sensor, SensorSettings
from crane_sim.simulator import INTERPOLATIONS, SOURCES, CraneSimulator, CraneState, SimulationError

#: How long (s) the ~/reset and ~/push services wait for the loop to have applied them and measured the
#: crane as it is then, before answering anyway (a loop stalled by the host).
APPLIED_WAIT = 1.0
SIM_TASK = 'sim'
#: A step this late (ns) is caught up (``SimNode._await_samples``): waiting for samples in polls of
#: CATCH_UP_POLL s while any arrive within CATCH_UP_QUIET s, CATCH_UP_WAIT s at most per step. After a pause of
#: the whole host the processes resume in no set order: a streamer continuing 0.1 s after the sim must still
#: find it waiting (with a quiet of 2 ms the sim ran its steps without samples, the axes holding their
#: velocity for the second its own stall is forgiven, and the cart ran 0.11 m past the goal).
#: A dead stream costs CATCH_UP_QUIET once, not at every step.
CATCH_UP_NS = 5_000_000
CATCH_UP_POLL, CATCH_UP_QUIET, CATCH_UP_WAIT = 2e-4, 0.25, 0.05
_TYPE_NAMES = {'trajectory_msgs/msg/JointTrajectory': OUTPUT_JOINT_TRAJECTORY,
               'std_msgs/msg/Float64MultiArray': OUTPUT_FLOAT64_ARRAY}


PARAMETERS = {
    **model_parameters(lambda description: f'true plant: {description}; may change while running',
                       lambda name: 10.0 if name.startswith('tau') else 1e4),
    'joints': (['cart'], "the actuated joints: [cart], [cart, hoist], [cart, bridge] or [cart, bridge, hoist] "
                         "(a column of the reference each; with the hoist the upper cable's length follows it "
                         'through tau_hoist, from L1 at start-up; with the bridge the suspension point moves along '
                         'y and the load swings in both directions: joint_states then carry phi1, phi2 after '
                         'theta1, theta2); fixed at start-up',
               {'additional_constraints': 'cart, then any of bridge, hoist in this order', 'read_only': True}),
    'step': (1e-3, 'integration step (s), also the real-time loop period; fixed at start-up',
             {**float_range(1e-4, 0.1), 'read_only': True}),
    'publish_rate': (50.0, 'joint_states rate (Hz) in simulated time; fixed at start-up',
                     {**float_range(0.1, 1000.0), 'read_only': True}),
    'reference_source': ('acceleration', "'acceleration': the reference's acceleration; 'position': "
                         'second differences of received positions (a controller that only gets positions)',
                         {'additional_constraints': f'one of {", ".join(SOURCES)}'}),
    'interpolation': ('zoh', "between references: 'zoh' holds the newest, 'linear' ramps to it over a step",
                      {'additional_constraints': f'one of {", ".join(INTERPOLATIONS)}'}),
    'reference_type': ('auto', f"'auto' (the type of reference's publisher), '{OUTPUT_JOINT_TRAJECTORY}' or "
                       f"'{OUTPUT_FLOAT64_ARRAY}'; fixed at start-up",
                       {'additional_constraints': f'auto, {OUTPUT_JOINT_TRAJECTORY} or {OUTPUT_FLOAT64_ARRAY}',
                        'read_only': True}),
    # A fieldbus drive's watchdog: a stream silent longer is lost, and an axis must not coast on in the meantime.
    # A stall of this process's own loop is not the stream's silence (playout.StallAllowance, BACKLOG)
    'reference_timeout': (0.1, 'the drive\'s watchdog: once the plant has played its newest reference (the '
                          'playout has run dry) each axis holds its velocity, and after this long (s) more the '
                          'stream is lost: the fault reaction brakes every axis to rest (fault_deceleration) and '
                          'holds; a reference arriving more than playout_delay + reference_timeout after its stamp '
                          'is stale and ignored', float_range(1e-3, 10.0)),
    # A drive's quick-stop ramp, steeper than a motion's own limits: with the playout_delay below, a streamer
    # killed at 40 % of an NVF move of 0.6 m in 4 s leaves the cart at rest about 0.11 m past where it was at the
    # kill (0.5 m/s^2 and 5 m/s^3 with a 0.2 s delay: about 0.17 m, more than the 0.15 m allowed)
    'fault_deceleration': (1.0, 'fault reaction to a lost reference stream: every axis (the hoist too) brakes its '
                           'reference from its velocity and acceleration then to rest at this deceleration '
                           '(m/s^2), jerk-limited by fault_jerk, as a drive\'s quick stop, then holds; may change '
                           'while running (the next fault uses it)', float_range(1e-3, 100.0)),
    'fault_jerk': (10.0, 'fault reaction: the jerk limit (m/s^3) of its braking ramp; may change while running',
                   float_range(1e-3, 1e4)),
    'resume_tolerance': (1e-3, 'after a fault the axes resume only from a reference at rest where they '
                         'stand: within this distance (m) of each held position; others are refused and counted '
                         '(refused_after_fault)', float_range(1e-9, 1.0)),
    # Whatever was sent but not yet played when the stream dies still plays: the delay is travel after a kill.
    # Beside two CPU-bound processes on 2 cores the loop ran at most 1 ms late at its real-time priority
    # (sched_priority); at normal scheduling up to 70 ms, and a sample now and then came after its playout time
    'playout_delay': (0.1, 'the plant runs this far (s) behind the clock and applies each reference at its '
                      'stamp (a jitter buffer: every sample arriving within the delay counts for exactly its '
                      'own interval); joint_states are stamped with plant time. Longer absorbs more jitter, but '
                      'what was sent and not yet played when the stream is lost still plays: the axes run that '
                      'much further before the watchdog', float_range(0.0, 1.0)),
    'unstamped_period': (1e-3, 'period (s) of references without stamps (float64_array): each is taken to come '
                         'this long after the previous one, like commands at a fixed rate', float_range(1e-5, 1.0)),
    'frame_id': (DEFAULT_FRAME_ID, 'frame of the crane_markers (x along the rail, z up); fixed at start-up',
                 {'read_only': True}),
    'noise': (0.0, 'standard deviation (rad) of Gaussian noise added to the published swing angles '
                   '(a measurement such as a camera\'s; the simulation itself is exact); may change while running',
              float_range(0.0, 1.0)),
    'sensor_latency': (0.0, 'the sway sensor\'s latency (s): each joint_states sample is published this long after '
                       'it was measured, with the stamp of its measurement and in order, as a camera\'s processing '
                       'would; may change while running (the samples still queued too)', float_range(0.0, 1.0)),
    'sensor_dropout': (0.0, 'probability that a joint_states sample is lost (seeded by seed), as a camera drops '
                       'frames; may change while running', float_range(0.0, 1.0)),
    'seed': (0, 'seed of the measurement noise, the sensor\'s dropout and the gusts (a stream each); fixed at '
                'start-up', {**int_range(0, 2**31 - 1), 'read_only': True}),
    'push_swing': (0.03, '~/push displaces the load this far (m) along x, as the swing is signed (positive: the '
                         'load behind the cart, theta1 > 0), cables in line, and lets go, also during a motion: a '
                         'swing for tests and the demo (the planner\'s ~/settle damps it)', float_range(-1.0, 1.0)),
    'push_swing_y': (0.0, '~/push displaces the load this far (m) along y too, signed alike (positive: the load '
                          'behind the bridge, phi1 < 0); with the bridge only', float_range(-1.0, 1.0)),
    'wind': ([0.0, 0.0], 'a steady horizontal acceleration [ax, ay] (m/s^2) on both masses, as a wind\'s (ay with '
                         'the bridge only); may change while running',
             {'additional_constraints': 'two finite numbers [ax, ay]; ay 0 without the bridge'}),
    'gust': (0.0, 'standard deviation (m/s^2) of a random horizontal acceleration on both masses, in x and with '
                  'the bridge in y (an Ornstein-Uhlenbeck process, seeded by seed); may change while running',
             float_range(0.0, 10.0)),
    'gust_time': (1.0, 'correlation time (s) of the gusts; may change while running', float_range(1e-3, 1e3)),
    # Real-time: the sim stands for the axes' drives, whose control loop no other program delays. At normal
    # scheduling a busy host (one CPU-bound process beside the suite) kept its executor from a core for
    # longer than the playout delay: references came after their playout time, or the receive buffers
    # overflowed and the stream counted as lost mid-motion. Below the streamer's loop, above the planner's
    # goals (their sched_priority and handover_priority)
    'sched_priority': (45, 'SCHED_FIFO priority of the stepping thread, 1..99, the executor thread that '
                       'feeds it one below, the middleware\'s receive threads two below (without the privilege a '
                       'warning and normal scheduling); 0 = normal scheduling: the playout delay absorbs late '
                       'steps, a loop catching up waits for the samples still on their way, and '
                       'references later still are made up (made_up on /diagnostics)',
                       {**int_range(0, 99), 'read_only': True}),
}


class SimNode(Node):
    """The ``crane_sim`` node."""

    def __init__(self, **kwargs):
        super().__init__(SIM_NODE, **kwargs)
        p = declare(self, PARAMETERS)
        self._check(p)  # ParameterError on a bad override, see main()
        self._joints = check_joints(p['joints'])
        # Late steps are caught up, never skipped (a skipped step would drop its references);
        # the playout delay keeps them in time up to a point, the lateness diagnostics show it.
        self._ticker = Ticker(round(p['step'] * 1e9), max_backlog=10**9)
        self._sim = CraneSimulator(CraneParams.of(p), dt=self._ticker.period * 1e-9,
                                   axes=self._joints)
        self._publish_every = max(1, round(1.0 / (p['publish_rate'] * p['step'])))
        self._source, self._interpolation = p['reference_source'], p['interpolation']
        self._diagnostics = DiagnosticsPublisher(self)
        Guard(self, PARAMETERS, self._check, self._apply, self._diagnostics)
        # the loop alone uses these: the executor hands it new settings (_apply)
        self._sensor_settings, self._disturbances = self._sensor_settings_of(p), self._disturbances_of(p)
        self._sensor = Sensor(self._sensor_settings, p['seed'])
        self._gust = Gust(planes=2 if self._sim.spatial else 1, seed=p['seed'])
        self._frame_id = p['frame_id']
        self._markers = crane_markers_message(self._frame_id, bridge=self._sim.spatial)
        self._markers_pub = self.create_publisher(MarkerArray, MARKERS_TOPIC, MARKERS_QOS)
        self._joint_state = joint_state_message(self._sim.joint_names)
        self._joint_states = self.create_publisher(JointState, JOINT_STATES_TOPIC, JOINT_STATES_QOS)
        self._fault_config = self._fault_config_of(p)  # the loop hands it to the controller
        self._controller = AxisController(self._sim.axes, self._axis_positions(), self._fault_config)
        self._axis_status = self.create_publisher(AxisStatus, AXIS_STATUS_TOPIC, AXIS_STATUS_QOS)
        self._plant_clock = (self.get_clock().now().nanoseconds, 0)  # ROS ns of plant time 0, playout delay ns
        self._refused_reported = 0

        # Taken and checked by the loop, not yet played: (stamp ns, then position, acceleration per axis).
        self._inbox: deque = deque()
        self._pending_params: CraneParams | None = None
        self._reset_requested = threading.Event()
        self._push: tuple[float, float] | None = None  # a push for the loop to apply (m, along x and y)
        # Set by the loop once a reset or push it applied is in the next joint_states sample taken (at the regular
        # publish_rate: a camera's frames, none added): the service answers
        # then, so a caller that acts on its answer (a goal sent at once) finds the crane measured as it is
        # (published at once without sensor_latency; with it as soon as a camera would report it).
        self._applied = threading.Event()
        self._applied.set()
        # The loop's counts (out_of_order: a sample a swapped playout could not take) and the intake's,
        # both written by the loop alone; the diagnostics add them up.
        self.counts = dict.fromkeys(('out_of_order', 'timeouts', 'made_up', 'steps', 'skipped', 'published'), 0)
        self.made_up_late = 0.0  # s: the latest a made-up sample came past its playout time
        self._made_up_reported = 0
        self._lateness = Lateness()
        self._window = (time.monotonic(), 0, 0)  # (time, steps, published) at the last report

        self._stream_quiet = False  # a catch-up wait found no sample coming (``_await_samples``)
        self._played_ns: int | None = None  # ROS time of the step the loop runs (``ReferenceIntake.receive``)
        self._reader: ReferenceReader | None = None
        self._reference_type = p['reference_type']
        self._playout_args = self._playout_args_of(p)
        self._intake = ReferenceIntake(*self._intake_args_of(p))
        if self._reference_type == 'auto':
            self._type_timer = self.create_timer(0.2, self._detect_reference_type)
            self._detect_reference_type()
        else:
            self._subscribe(self._reference_type)
        self.create_service(Trigger, RESET_SERVICE, self._on_reset)
        self.create_service(Trigger, PUSH_SERVICE, self._on_push)
        self.create_timer(1.0, self._report)
        self._loop_thread = LoopThread(self, self._loop, 'sim-loop', p['sched_priority'])
        self.get_logger().info(f'simulating {self._sim.params} every {p["step"] * 1e3:g} ms, joint_states at '
                               f'{p["publish_rate"]:g} Hz, reference source {self._source}, {self._interpolation}')

    # -- parameters -------------------------------------------------------

    @staticmethod
    def _check(values: dict) -> CraneParams:
        """The plant of a full set of values; ParameterError names a bad value."""
        for name, choices in (('reference_source', SOURCES), ('interpolation', INTERPOLATIONS),
                              ('reference_type', ('auto', *REFERENCE_TYPES))):
            crane_params.check_choice(name, values[name], choices)
        for name in ('fault_deceleration', 'fault_jerk', 'resume_tolerance'):
            crane_params.check_positive(name, values[name])
        SimNode._sensor_settings_of(values)
        bridge = BRIDGE_JOINT in values['joints']
        SimNode._disturbances_of(values).check_planes(bridge)
        if values['push_swing_y'] != 0.0 and not bridge:
            raise crane_params.ParameterError(f'push_swing_y {values["push_swing_y"]:g} m: a push along y needs the '
                                              'bridge (joints): the crane without one swings in the x-z plane alone')
        return CraneParams.of(values)

    @staticmethod
    def _sensor_settings_of(values: dict) -> SensorSettings:
        return SensorSettings(values['sensor_latency'], values['sensor_dropout'], values['noise'])

    @staticmethod
    def _disturbances_of(values: dict) -> Disturbances:
        return Disturbances(tuple(values['wind']), values['gust'], values['gust_time'])

    @staticmethod
    def _fault_config_of(values: dict) -> FaultConfig:
        return FaultConfig(values['fault_deceleration'], values['fault_jerk'], values['resume_tolerance'],
                           values['reference_timeout'])

    def _axis_positions(self) -> list[float]:
        """Where each axis of the plant stands now (m)."""
        return [self._sim.axis_state(name)[0] for name in self._sim.axes]

    def _playout_args_of(self, values: dict) -> tuple:
        source = 'position' if self._reference_type == OUTPUT_FLOAT64_ARRAY else values['reference_source']
        return (values['playout_delay'], values['reference_timeout'], values['interpolation'], source,
                values['unstamped_period'])

    def _intake_args_of(self, values: dict) -> tuple:
        delay, timeout, _, source, _ = self._playout_args_of(values)
        # stale: too late for its playout, and for making up what the steps without it played (the timeout)
        return delay + timeout, delay, values['unstamped_period'], source == 'position'

    def _apply(self, params: CraneParams, values, changes):
        if {c.name for c in changes} & set(PARAMETER_NAMES):
            self._pending_params = params  # the loop applies it before its next step
        self._source, self._interpolation = values['reference_source'], values['interpolation']
        for name, settings in (('_sensor_settings', self._sensor_settings_of(values)),
                               ('_disturbances', self._disturbances_of(values))):
            if settings != getattr(self, name):
                setattr(self, name, settings)  # the loop applies it before its next step
        playout_args = self._playout_args_of(values)
        if playout_args != self._playout_args:  # the loop swaps its playouts (losing what they hold) on a change
            self._playout_args = playout_args
        self._fault_config = self._fault_config_of(values)  # and hands this to the controller
        self._intake.configure(*self._intake_args_of(values))

    # -- references (executor thread) ----------------------------------------

    def _detect_reference_type(self):
        for info in self.get_publishers_info_by_topic(self.resolve_topic_name(REFERENCE_TOPIC)):
            kind = _TYPE_NAMES.get(info.topic_type)
            if kind is not None:
                self._type_timer.cancel()
                self._subscribe(kind)
                return

    def _subscribe(self, kind: str):
        self._reference_type = kind
        self._reader = ReferenceReader(self, kind, REFERENCE_EVERY_SAMPLE_QOS)  # the loop takes from it
        self.get_logger().info(f'reference type {kind}')
        if kind == OUTPUT_FLOAT64_ARRAY:  # positions only, timed by their arrival
            self._playout_args = (*self._playout_args[:3], 'position', *self._playout_args[4:])  # as _playout_args_of
            self._intake.positions_only = True  # and _intake_args_of
            if self._source == 'acceleration':
                self.get_logger().warn('float64_array references carry positions only: '
                                       'reconstructing the acceleration from them')

    def _take_references(self, now_ns: int) -> None:
        """Check what the reader received since the last step (the intake) and queue the accepted samples."""
        reader = self._reader
        if reader is None:
            return
        joints, intake, inbox, played = self._joints, self._intake, self._inbox, self._played_ns
        for received, content in reader.take(now_ns):
            try:
                if content is None:
                    raise ValueError('not a reference')
                if len(joints) > 1:  # a column per axis: the cart's, then the others' pairs
                    stamp, position, _, acceleration = read_reference(content, joints)
                    others = tuple(zip(position[1:], acceleration[1:]))
                    position, acceleration = position[0], acceleration[0]
                else:
                    stamp, position, _, acceleration = read_reference(content)
                    others = ()
            except ValueError:
                intake.count_malformed()
                continue
            for sample in intake.receive(received, stamp, position, acceleration, others, played):
                inbox.append((bool(stamp), sample))  # (whether its sender stamped it: its gaps are judged)

    def _on_push(self, request, response):
        push = tuple(float(self.get_parameter(name).value) for name in ('push_swing', 'push_swing_y'))
        length = self._sim.L1 + self._sim.params['L2']
        given = f'push_swing {push[0]:g} m' + (f', push_swing_y {push[1]:g} m' if push[1] else '')
        if not math.hypot(*push) < length:
            response.success = False
            response.message = f'{given}: must be less than the cables\' length ({length:g} m)'
            return response
        self._applied.clear()
        self._push = push
        response.success = True
        aside = f'{push[0] * 1e3:g} mm' if not push[1] else f'({push[0] * 1e3:g}, {push[1] * 1e3:g}) mm'
        response.message = f'load pushed {aside} aside and released'
        self._applied.wait(APPLIED_WAIT)
        self.get_logger().info(response.message)
        return response

    def _on_reset(self, request, response):
        self._applied.clear()
        self._reset_requested.set()
        response.success = True
        response.message = 'plant at rest where the cart is; a fault reaction cleared: waiting for a first reference'
        self._applied.wait(APPLIED_WAIT)
        return response

    # -- the loop (its own thread) -------------------------------------------

    def _loop(self):
        sim, ticker, counts, lateness = self._sim, self._ticker, self.counts, self._lateness
        inbox, controller, sensor, gust = self._inbox, self._controller, self._sensor, self._gust
        disturbances = None  # the settings applied last (``_disturbances`` hands new ones over)
        answer = False  # a ~/reset or ~/push applied whose service waits for the next sample taken
        ros_now, epoch = self.get_clock().now().nanoseconds, ticker.restart()
        epoch_ros = ros_now + (epoch - time.monotonic_ns())  # ROS time of step 0
        ros_offset = epoch_ros - epoch  # ROS time (ns) minus monotonic time (ns)
        dt_ns, dt = ticker.period, ticker.period * 1e-9
        playout_args, playouts, timeouts, made_up = None, (), 0, 0  # a playout per axis, in sim.axes order
        seen = 0  # the cart's playout's timeouts handled: one more is a stream lost
        newest = 0  # the newest sample's stamp taken (ROS ns)
        angles = slice(sim.joint_names.index('theta1'), None)  # of the swing's angles in joint_state()
        tracking = AxisState.TRACKING
        self._publish_status(controller.status(), epoch_ros - round(self._playout_args[0] * 1e9))
        while not self._loop_thread.stopping.is_set():
            deadline = ticker.deadline
            now = sleep_until(deadline, 0)
            late_ns = now - deadline
            lateness.add(late_ns)
            t0 = ticker.tick * dt  # nominal time of the step since step 0
            if self._pending_params is not None:
                params, self._pending_params = self._pending_params, None
                sim.set_params(params)
            if self._playout_args is not playout_args:
                playout_args = self._playout_args
                timeouts += playouts[0].timeouts if playouts else 0
                made_up += playouts[0].made_up if playouts else 0
                playouts = tuple(ReferencePlayout(*playout_args) for _ in sim.axes)
                playout, seen = playouts[0], 0  # the cart's: its timeouts are the stream's
                allowance = StallAllowance(BACKLOG)
                self._plant_clock = (epoch_ros, round(playout.delay * 1e9))
            if self._fault_config is not controller.config:
                controller.config = self._fault_config
            if self._sensor_settings is not sensor.settings:
                sensor.settings = self._sensor_settings
            if self._disturbances is not disturbances:
                disturbances = self._disturbances
                gust.configure(disturbances.gust, disturbances.gust_time)
                sim.disturbance = disturbances.wind
            answer = answer or self._push is not None or self._reset_requested.is_set()
            if self._push is not None:
                push, self._push = self._push, None
                try:
                    sim.push(*push)
                except SimulationError as exc:  # the rope shortened since the request was checked
                    self.get_logger().warn(f'push not applied: {exc}')
            if self._reset_requested.is_set():
                self._reset_requested.clear()
                sim.reset(CraneState(y=sim.state.y))
                for one in playouts:
                    one.reset()
                controller.reset(self._axis_positions(), t0)
            self._played_ns = epoch_ros + ticker.tick * dt_ns  # what the intake judges staleness by
            self._take_references(now + ros_offset)
            if late_ns > CATCH_UP_NS and controller.state is tracking:
                self._await_samples(newest, epoch_ros + (ticker.tick + 1) * dt_ns - self._plant_clock[1], ros_offset)
            while inbox:
                stamped, (stamp, *sample) = inbox.popleft()  # (position, acceleration) per axis
                newest = stamp
                offer = Offer.ACCEPT if controller.state is tracking else controller.offer(sample[::2], t0)
                if offer is Offer.REFUSE:  # a fault reaction holds: counted by the controller
                    continue
                if offer is Offer.START:  # a stream from rest where the references are
                    for one in playouts:
                        one.reset()
                try:
                    for k, one in enumerate(playouts):
                        one.push((stamp - epoch_ros) * 1e-9, sample[2 * k], sample[2 * k + 1])
                except SimulationError:  # not after the last one (a playout swapped meanwhile)
                    counts['out_of_order'] += 1
                    continue
                controller.played(((stamp - epoch_ros) * 1e-9, *sample), stamped)  # (a gap mid-motion: lost)
            t1 = t0 + dt
            if gust.sd > 0.0:  # a new gust each step, held over it
                sim.disturbance = disturbances.plus(gust.step(dt))
            if controller.state is tracking:
                stall = allowance(late_ns * 1e-9, now * 1e-9)
                for one in playouts:  # catching up after a stall: its samples may be on their way
                    one.behind(stall)
                tracked = [one.step(t0, t1) for one in playouts]
                lost, seen = playout.timeouts > seen, playout.timeouts
                sim.step(*zip(*controller.step(t0, t1, tracked, lost)))
            else:  # at rest, or the fault reaction: the playouts have nothing to play
                sim.step(*zip(*controller.step(t0, t1)))
            if controller.changes:
                for change in controller.take_changes():
                    status = controller.status(change.new, self._ros_seconds)
                    self._publish_status(status, self._plant_ns(change.time))
                    if change.new in FAULT_STATES or change.old in FAULT_STATES:  # said when it happens, too
                        self.get_logger().warn(f'axes {change.new.value}: {status.message}')
            counts['steps'] += 1
            counts['timeouts'] = timeouts + playout.timeouts
            if playout.made_up + made_up > counts['made_up']:  # (every axis's playout has the same samples)
                counts['made_up'] = made_up + playout.made_up
                self.made_up_late = max(self.made_up_late, playout.made_up_late)
            measured = ticker.tick % self._publish_every == 0  # (every publish period: a camera's frames)
            if measured:  # a sample taken (the sensor: its noise, whether it is lost, when it is reported)
                positions, velocities = sim.joint_state()
                true_angles = positions[angles]
                plant_time = epoch_ros + (ticker.tick + 1) * dt_ns - round(playout.delay * 1e9)
                sensor.measure(t1, plant_time, true_angles, positions[:angles.start], velocities)
                # the crane as it is: the true angles, the live cable lengths (the hoist's now)
                fill_crane_markers(self._markers, plant_time, sim.suspension, *sim.mass_positions(true_angles))
            try:
                for sample in sensor.released(t1):  # (at any step: a latency need not be whole publish periods)
                    axes_positions, velocities = sample.values
                    fill_joint_state(self._joint_state, sample.stamp, [*axes_positions, *sample.angles], velocities)
                    self._joint_states.publish(self._joint_state)
                    counts['published'] += 1
                if measured:
                    self._markers_pub.publish(self._markers)
            except Exception:  # the context is shut down (SIGINT): end quietly
                return
            if answer and measured:  # the reset or push in a sample taken: its service answers
                self._applied.set()
                answer = False
            counts['skipped'] += ticker.advance(time.monotonic_ns())

    def _await_samples(self, newest: int, needed: int, ros_offset: int) -> None:
        """While the loop catches up after a stall, wait for the samples up to ``needed`` (ROS ns: this
        step's playout time) before the step runs without them (each made up later would leave a swing):
        a stall of the host held the streamer too, and the loop, run alone, would outrun what it sends.
        Only while samples keep coming (none for ``CATCH_UP_QUIET`` s: a gap, or a
        lost stream, for the playout to judge: not waited for again until a sample comes, or a loop behind
        a dead stream would wait at every step and never catch up), ``CATCH_UP_WAIT`` s at most. ``newest``:
        the newest stamp the loop has taken."""
        inbox, waited, quiet, count = self._inbox, 0.0, 0.0, len(self._inbox)
        if self._stream_quiet and not inbox:
            return
        self._stream_quiet = False
        while (inbox[-1][1][0] if inbox else newest) < needed and waited < CATCH_UP_WAIT:
            time.sleep(CATCH_UP_POLL)
            self._take_references(time.monotonic_ns() + ros_offset)
            waited += CATCH_UP_POLL
            quiet = 0.0 if len(inbox) != count else quiet + CATCH_UP_POLL
            count = len(inbox)
            if quiet >= CATCH_UP_QUIET:
                self._stream_quiet = True
                break

    # -- the axis controller's reports ----------------------------------------

    def _plant_ns(self, t: float) -> int:
        """ROS time (ns) of plant time ``t`` (s since step 0): the stamp of the references played then."""
        epoch_ros, delay_ns = self._plant_clock
        return epoch_ros + round(t * 1e9) - delay_ns

    def _ros_seconds(self, t: float) -> float:
        return self._plant_ns(t) * 1e-9

    def _publish_status(self, status, stamp_ns: int):
        """``axis_status`` with the controller's ``status`` (an ``axis_controller.Status``), stamped
        ``stamp_ns``; a fresh message each time: the loop and the executor both publish."""
        msg = AxisStatus(state=status.state.value, joint_names=list(self._sim.axes),
                         position=[float(p) for p in status.positions], message=status.message)
        set_stamp(msg.header.stamp, stamp_ns)
        msg.header.frame_id = self._frame_id
        try:
            self._axis_status.publish(msg)
        except Exception:  # the context is shut down (SIGINT): nothing to report to
            pass

    # -- diagnostics (executor thread) ----------------------------------------

    def _report(self):
        counts = dict(self._intake.counts)
        for key, n in self.counts.items():
            counts[key] = counts.get(key, 0) + n
        now = time.monotonic()
        t0, steps0, published0 = self._window
        self._window = (now, counts['steps'], counts['published'])
        elapsed = now - t0
        ignored = sum(counts[k] for k in ('nonfinite', 'stale', 'out_of_order', 'malformed'))
        latency = np.asarray(self._intake.take_latencies(), dtype=float) * 1e-6
        p50, p99 = np.percentile(latency, [50, 99]) if latency.size else (math.nan, math.nan)
        state = self._sim.state
        error = self._loop_thread.error
        controller = self._controller
        axes = controller.status(clock=self._ros_seconds)
        faulted = axes.state in FAULT_STATES
        level = ERROR if error else WARN if counts['skipped'] or faulted else OK
        message = (f'the loop stopped: {error}' if error else
                   f'stepping at {(counts["steps"] - steps0) / elapsed:.1f} Hz, {ignored} references ignored')
        if faulted and not error:
            message = f'{axes.message}; {message}'
        self._report_refusals(controller)
        self._report_made_up(counts['made_up'])
        self._publish_status(axes, self.get_clock().now().nanoseconds - self._plant_clock[1])
        self._diagnostics.report(
            SIM_TASK, level, message, **self._axes_values(controller, axes),
            step_rate_hz=(counts['steps'] - steps0) / elapsed,
            joint_states_rate_hz=(counts['published'] - published0) / elapsed,
            **lateness_summary_us(self._lateness.take()), **counts, ignored=ignored,
            reference_latency_p50_ms=p50, reference_latency_p99_ms=p99,
            reference_interval_ms=self._intake.sender_period_ns * 1e-6, made_up_late_ms=self.made_up_late * 1e3,
            reference_type=self._reference_type, reference_source=self._source,
            playout_delay=self._playout_args[0],
            interpolation=self._interpolation, y=state.y, theta1=state.theta1, theta2=state.theta2,
            load_excursion=self._sim.load_excursion, **self._sim.params,
            sensor_dropped=self._sensor.dropped, sensor_pending=self._sensor.pending,
            disturbance_x=self._sim.disturbance[0], disturbance_y=self._sim.disturbance[1],
            **({'hoist_L1': self._sim.L1} if self._sim.hoist else {}))

    def _axes_values(self, controller: AxisController, axes) -> dict:
        """The axis controller's key values: its state, each axis's reference (held, or now), refusals; during a
        fault reaction when the stream was lost (ROS time, ns: plant time, as joint_states') and each axis's
        braking."""
        values = {'axis_state': axes.state.value, 'refused_after_fault': controller.refused,
                  **{f'{name}_reference': p for name, p in zip(controller.axes, axes.positions)}}
        fault = controller.fault
        if axes.state in FAULT_STATES and fault is not None:
            values['fault_stamp_ns'] = self._plant_ns(fault.lost_at)  # (an integer: 9 digits of seconds are not)
            for name, origin, braking, stop in zip(controller.axes, fault.origins, fault.brakings, fault.stops):
                values.update({f'{name}_braking_from': origin, f'{name}_braking_velocity': braking.v0,
                               f'{name}_braking_acceleration': braking.a0, f'{name}_stop': stop})
            values.update(fault_deceleration=fault.brakings[0].D, fault_jerk=fault.brakings[0].J)
        return values

    def _report_refusals(self, controller: AxisController):
        """A warning (at most once a report) when references were refused since the last: how far the newest
        is from where the axes hold, or that it moves there."""
        refused, refusal = controller.refused, controller.last_refusal
        if refused <= self._refused_reported or refusal is None:
            return
        new, self._refused_reported = refused - self._refused_reported, refused
        where = 'hold' if refusal.state is AxisState.FAULT_HOLD else 'will stop (still braking)'
        offsets = ', '.join(f'{name} {d * 1e3:+.3f} mm' for name, d in zip(controller.axes, refusal.offsets))
        newest = (f'is where the axes hold ({offsets}) but moving' if refusal.moving else
                  f'is off where the axes {where} by {offsets} '
                  f'(resume_tolerance {controller.config.resume_tolerance * 1e3:g} mm)')
        self.get_logger().warn(
            f'{new} reference(s) refused after the reference stream was lost: the newest {newest}; '
            'a stream resumes only at rest where the axes stand (or after ~/reset)')

    def _report_made_up(self, made_up: int):
        """A warning (at most once a report) when references came after the steps that needed them had run:
        the reference was made up, the swing it caused was not."""
        if made_up <= self._made_up_reported:
            return
        new, self._made_up_reported = made_up - self._made_up_reported, made_up
        self.get_logger().warn(
            f'{new} time(s) references came after their playout time (up to {self.made_up_late * 1e3:.0f} ms past '
            f'it, playout_delay {self._playout_args[0] * 1e3:g} ms): the reference was made up at once, the swing '
            'those steps caused stays; a host this busy needs a longer playout_delay')

    def destroy_node(self):
        self._loop_thread.stop()
        if self._reader is not None:
            self._reader.destroy()
        super().destroy_node()


def main(args=None):
    return run(SimNode, EventsExecutor, args)
