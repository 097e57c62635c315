"""Planner node: ``nav_msgs/srv/GetPlan`` services for every method (contract: ROS 2 nodes, planner).

``~/plan`` (the ``method`` parameter) and ``~/plan/<method>`` compute and
answer with a ``nav_msgs/Path``; they move nothing. ``~/execute`` and
``~/execute/<method>`` plan the same way and also latch the plan on
``trajectory`` for the streamer. ``~/fastest[/<method>]`` and
``~/execute_fastest[/<method>]`` do the same for the shortest duration within
the axis limits (the goal stamp is ignored; the last pose carries the end time). Every request gets one status on
``/diagnostics``. Requests run concurrently (MultiThreadedExecutor, one
reentrant group); NVF/RVF solves run in the planning facade's worker
processes (``solver_processes``), each bounded by ``max_solve_time``, so
none waits behind another.
"""
from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass

from nav_msgs.srv import GetPlan
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.executors import MultiThreadedExecutor
from rclpy.node import Node
from trajectory_msgs.msg import JointTrajectory

from crane_msgs_py.client import PLAN_TASK
from crane_msgs_py.conversions import samples_to_joint_trajectory, samples_to_path, stamp_ns
from crane_msgs_py.diagnostics import ERROR, OK, WARN, DiagnosticsPublisher
from crane_msgs_py.names import DEFAULT_FRAME_ID, PLANNER_NODE, PLANNER_SERVICES, TRAJECTORY_TOPIC, planner_service
from crane_msgs_py.node_parameters import Guard, declare, float_range, int_range
from crane_msgs_py.params import (
    PARAMETER_DESCRIPTIONS,
    PARAMETER_NAMES,
    CraneParams,
    ParameterError,
    check_choice,
    check_nonnegative,
    check_positive,
)
from crane_msgs_py.qos import TRAJECTORY_QOS
from crane_msgs_py.realtime import fix_mmap_threshold
from crane_msgs_py.runner import run
from crane_planner.planning import (
    METHODS,
    ROBUST_PARAMETERS,
    VARIATIONAL_METHODS,
    PlanError,
    PlanOptions,
    check_request,
)
from crane_planner.planning.dispatch import VariationalRequest
from crane_planner.planning.plan import time_grid
from crane_planner.planning.profiles import BASES
from crane_planner.serving import Planner
from crane_planner.streaming.knots import knot_times

#: name -> (default, description, range descriptor fields). Ranges are the
#: outer bounds rclpy enforces; the exact domain (e.g. > 0) is checked by the
#: node, which names the reason and reports it on /diagnostics.
PARAMETERS = {
    'L1': (CraneParams.L1, PARAMETER_DESCRIPTIONS['L1'], float_range(0.0, 100.0)),
    'L2': (CraneParams.L2, PARAMETER_DESCRIPTIONS['L2'], float_range(0.0, 100.0)),
    'm1': (CraneParams.m1, PARAMETER_DESCRIPTIONS['m1'], float_range(0.0, 1e5)),
    'm2': (CraneParams.m2, PARAMETER_DESCRIPTIONS['m2'], float_range(0.0, 1e5)),
    'g': (CraneParams.g, PARAMETER_DESCRIPTIONS['g'], float_range(0.0, 100.0)),
    'tau': (CraneParams.tau, PARAMETER_DESCRIPTIONS['tau'], float_range(0.0, 10.0)),
    'c1': (CraneParams.c1, PARAMETER_DESCRIPTIONS['c1'], float_range(0.0, 1e3)),
    'c2': (CraneParams.c2, PARAMETER_DESCRIPTIONS['c2'], float_range(0.0, 1e3)),
    'method': ('rvf', f'method of ~/plan: one of {", ".join(METHODS)}',
               {'additional_constraints': f'one of {", ".join(METHODS)}'}),
    'robust_parameters': (['L1'], f'parameters RVF is made insensitive to, among {", ".join(ROBUST_PARAMETERS)}',
                          {'additional_constraints': f'distinct names among {", ".join(ROBUST_PARAMETERS)}'}),
    'shaper_frequencies': ([], 'shaper design frequencies (rad/s), one per mode; empty = the linearized '
                               "model's modal frequencies", {'additional_constraints': 'each > 0'}),
    'shaper_damping': (-1.0, "shaper design damping ratio, >= 0 and < 1; -1 = the model's modal damping "
                             'ratios (0 when c1 = c2 = 0; 0 with shaper_frequencies set)',
                       float_range(-1.0, 1.0)),
    'intervals': (0, 'collocation intervals of NVF/RVF, 4..2000; 0 = the solver default',
                  int_range(0, 2000)),
    'sample_period': (0.0, 'knot spacing of returned plans (s); 0 = knots where the plan needs them '
                           '(its breakpoints, and as few more as keep the streamer\'s quintic Hermite '
                           'interpolation within 1 um); the last knot is exactly at the end',
                      float_range(0.0, 1.0)),
    'frame_id': (DEFAULT_FRAME_ID, 'frame of returned paths and trajectories', {}),
    'max_duration': (60.0, 'longest motion served (s), > 0', float_range(0.0, 3600.0)),
    'max_displacement': (10.0, 'largest |goal - start| served (m), > 0',
                         float_range(0.0, 1e4)),
    'max_velocity': (0.0, 'axis limit |v| of the reference (m/s); 0 = no limit',
                     float_range(0.0, 1e3)),
    'max_acceleration': (0.0, 'axis limit |a| of the reference (m/s^2); 0 = no limit',
                         float_range(0.0, 1e4)),
    'max_jerk': (0.0, 'axis limit on the jerk of the reference (m/s^3); 0 = no limit',
                 float_range(0.0, 1e6)),
    'shaper_base': ('quintic', "the motion shapers shape: 'quintic' (the paper's) or 'limits' (the jerk-limited "
                               'time-optimal profile under the axis limits; needs max_velocity or max_acceleration)',
                    {'additional_constraints': f'one of {", ".join(BASES)}'}),
    'max_solve_time': (1.0, 'budget of one NVF/RVF solve (s), > 0: a request not solved within it is '
                            'refused; every request is answered within this + 0.5 s',
                       float_range(0.0, 60.0)),
    'solver_pool_size': (8, 'NVF/RVF solver instances per method in the node process, 1..32, made as '
                            'concurrent requests need them (2-6 MB each; the first of a method builds its NLP, '
                            '~25 MB); they serve every NVF/RVF request when solver_processes is 0, else those '
                            'finding every worker process busy', int_range(1, 32)),
    'solver_processes': (3, 'worker processes solving NVF/RVF side by side, 0..16, started with the node '
                            '(~40 MB each beyond what they share); 0 = solve in threads of the node process '
                            "only, where solves take turns at IPOPT's linear solver (read-only)",
                         dict(int_range(0, 16), read_only=True)),
}


@dataclass(frozen=True)
class Config:
    """One consistent set of the node's parameters, validated; swapped whole on a change."""

    params: CraneParams
    options: PlanOptions
    method: str
    sample_period: float
    frame_id: str
    max_duration: float
    max_displacement: float
    solver_pool_size: int
    solver_processes: int

    @classmethod
    def from_values(cls, v: dict) -> 'Config':
        """From parameter values by name; ParameterError names the bad one."""
        params = CraneParams(**{name: v[name] for name in PARAMETER_NAMES})
        check_choice('method', v['method'], METHODS)
        intervals = int(v['intervals'])
        options = PlanOptions(
            omega=tuple(v['shaper_frequencies']) or None,
            damping=None if v['shaper_damping'] == -1.0 else v['shaper_damping'],
            robust=tuple(v['robust_parameters']), intervals=intervals or None,
            max_velocity=v['max_velocity'] or None, max_acceleration=v['max_acceleration'] or None,
            max_jerk=v['max_jerk'] or None, base=v['shaper_base'],
            max_solve_time=check_positive('max_solve_time', v['max_solve_time']))
        if not v['frame_id']:
            raise ParameterError('frame_id must not be empty')
        return cls(params, options, v['method'], check_nonnegative('sample_period', v['sample_period']),
                   v['frame_id'], check_positive('max_duration', v['max_duration']),
                   check_positive('max_displacement', v['max_displacement']), int(v['solver_pool_size']),
                   int(v['solver_processes']))

    def warmups(self) -> list[VariationalRequest]:
        """Requests that build the NVF/RVF solvers of this configuration.

        A typical move, and with velocity or acceleration limits its fastest
        plan (the free-final-time NLP), so the first of either is answered warm.
        """
        D, duration = min(0.3, self.max_displacement), min(3.0, self.max_duration)
        requests = [VariationalRequest('plan', method, D, duration, self.params, self.options)
                    for method in VARIATIONAL_METHODS]
        if self.options.max_velocity is not None or self.options.max_acceleration is not None:
            requests += [VariationalRequest('fastest', method, D, None, self.params, self.options)
                         for method in VARIATIONAL_METHODS]
        return requests


class PlannerNode(Node):
    """The ``crane_planner`` node."""

    def __init__(self, **kwargs):
        super().__init__(PLANNER_NODE, **kwargs)
        warning = fix_mmap_threshold()  # before any solver allocates: keeps the node's size flat
        if warning:
            self.get_logger().warn(warning)
        values = declare(self, PARAMETERS)
        self._diagnostics = DiagnosticsPublisher(self)
        self._config = Config.from_values(values)  # bad overrides: ParameterError, see main()
        Guard(self, PARAMETERS, Config.from_values, self._apply, self._diagnostics)
        self._planner = Planner(self._config.solver_pool_size, processes=self._config.solver_processes)
        self._planner.warmups = self._config.warmups()
        if self._config.solver_processes:
            # before the services exist, so no request finds no worker; the others start meanwhile
            t0 = time.perf_counter()
            if self._planner.start_processes(ready_within=60.0):
                self.get_logger().info(f'first of {self._config.solver_processes} solver processes ready '
                                       f'in {time.perf_counter() - t0:.2f} s')
            else:
                self.get_logger().error('no solver process started within 60 s; NVF/RVF requests will be refused')
        self._trajectory = self.create_publisher(JointTrajectory, TRAJECTORY_TOPIC, TRAJECTORY_QOS)
        group = ReentrantCallbackGroup()
        for kind in PLANNER_SERVICES:
            self.create_service(GetPlan, planner_service(kind), lambda req, res, k=kind: self._serve(None, req, res, k),
                                callback_group=group)
            for method in METHODS:
                self.create_service(GetPlan, planner_service(kind, method),
                                    lambda req, res, m=method, k=kind: self._serve(m, req, res, k),
                                    callback_group=group)
        self.get_logger().info(f'serving {", ".join(METHODS)} on {self.get_fully_qualified_name()}/plan/<method> '
                               '(preview), .../execute/<method> (plan and send to the streamer), and '
                               '.../fastest/<method>, .../execute_fastest/<method> (shortest within the limits)')
        self._warmup = threading.Thread(target=self._build_solvers, name='solver-warmup', daemon=True)
        self._warmup.start()

    def _apply(self, config: Config, values, changes):
        self._planner.pool_size = config.solver_pool_size
        self._planner.warmups = config.warmups()  # what a replaced worker builds first
        self._config = config  # applies to the next request

    def executor_threads(self) -> int:
        """Enough executor threads for every solver busy at once, plus the shapers' and parameter requests."""
        config = self._config
        return config.solver_processes + config.solver_pool_size * len(VARIATIONAL_METHODS) + 4

    # -- requests ---------------------------------------------------------

    def _build_solvers(self):
        """Build every method once with the start-up configuration, so first requests are warm.

        Reported on /diagnostics (task ``solvers``) when done, with the time each took.
        """
        config = self._config
        times, failed = {}, {}
        t_all = time.perf_counter()
        # every worker up before the node says it is ready: one still building takes a core
        if config.solver_processes and not self._planner.start_processes(120.0, all_of_them=True):
            self.get_logger().warn('not every solver process started within 120 s')
        if config.solver_processes:  # the node's own solvers, for requests finding every worker busy
            try:
                self._planner.warm_threads(config.warmups())
            except Exception as exc:
                self.get_logger().warn(f'building the in-node NVF/RVF solvers failed: {exc}')
        for method in METHODS:
            # long enough for every shaper; the variational solvers at a typical request
            duration = min(3.0 if method in VARIATIONAL_METHODS else 10.0, config.max_duration)
            t0 = time.perf_counter()
            try:
                plan = self._planner.plan(method, min(0.3, config.max_displacement), duration,
                                          config.params, config.options)
            except Exception as exc:  # a warm-up failure only means building on first use
                failed[method] = str(exc)
                self.get_logger().warn(f'{method} warm-up failed: {exc}')
                continue
            times[method] = time.perf_counter() - t0
            build = plan.info.get('build_time_s')
            self.get_logger().info(f'{method} ready in {times[method]:.2f} s'
                                   + (f' (solver built in {build:.2f} s)' if build else ''))
        message = f'{len(times)} of {len(METHODS)} methods ready in {time.perf_counter() - t_all:.2f} s'
        self._diagnostics.report('solvers', WARN if failed else OK, message,
                                 **{f'{m}_s': v for m, v in times.items()},
                                 **{f'{m}_error': e for m, e in failed.items()})

    def _serve(self, method, request, response, kind: str):
        config = self._config
        method = method or config.method
        execute, fastest = kind.startswith('execute'), kind.endswith('fastest')
        t0 = time.perf_counter()
        start = request.start.pose.position.x
        goal = request.goal.pose.position.x
        start_ns = stamp_ns(request.start.header.stamp)
        duration = (stamp_ns(request.goal.header.stamp) - start_ns) * 1e-9
        values = {'method': method, 'service': kind, 'start': start, 'goal': goal,
                  'displacement': goal - start, 'duration': duration}
        try:
            samples, plan = self._plan(config, method, start, goal, None if fastest else duration)
        except ValueError as exc:  # PlanError, ParameterError: the request cannot be served
            return self._refuse(response, str(exc), values, t0)
        except Exception as exc:  # a solver bug must not kill the node or leave the caller waiting
            self.get_logger().error(f'{method}: unexpected {type(exc).__name__} while planning')
            return self._refuse(response, f'internal error: {type(exc).__name__}: {exc}', values, t0)
        solved = time.perf_counter()
        response.plan = samples_to_path(samples, start, start_ns, config.frame_id)
        if execute:
            self._trajectory.publish(samples_to_joint_trajectory(samples, start, start_ns, config.frame_id))
        done = time.perf_counter()
        info = plan.info
        if fastest:
            values['duration'] = plan.duration
        self._diagnostics.report(
            PLAN_TASK, OK, f'{method}: {len(samples.t)} knots' + (f' in {plan.duration:.4f} s' if fastest else '')
            + (', sent for execution' if execute else ''), **values, solve_time=info.get('solve_time_s', solved - t0),
            build_time=info.get('build_time_s', 0.0),
            iterations=info.get('iterations', 0), plan_time=solved - t0, message_time=done - solved,
            knots=len(samples.t), error='')
        # per request at debug level: /diagnostics has them, and an info line costs 0.4 ms
        self.get_logger().debug(f'{values["service"]} {method}: {start:g} -> {goal:g} m in {duration:g} s, '
                                f'{len(samples.t)} knots, planned in {solved - t0:.3f} s')
        return response

    def _plan(self, config: Config, method: str, start: float, goal: float, duration: float | None):
        """(knot samples, plan); ``duration`` None: the fastest within the axis limits."""
        if not (math.isfinite(start) and math.isfinite(goal)):
            raise PlanError(f'start and goal positions must be finite, got start={start}, goal={goal}')
        displacement, _ = check_request(method, goal - start, duration or 1.0)
        if abs(displacement) > config.max_displacement:
            raise PlanError(f'displacement {displacement:g} m exceeds max_displacement '
                            f'{config.max_displacement:g} m')
        if duration is None:
            plan = self._planner.fastest(method, displacement, config.params, config.options)
            duration = plan.duration
            if duration > config.max_duration:
                raise PlanError(f'the fastest {method} plan lasts {duration:g} s, beyond max_duration '
                                f'{config.max_duration:g} s')
        else:
            duration = check_request(method, displacement, duration)[1]
            if duration > config.max_duration:
                raise PlanError(f'duration {duration:g} s exceeds max_duration {config.max_duration:g} s')
            plan = self._planner.plan(method, displacement, duration, config.params, config.options)
        times = knot_times(plan) if config.sample_period == 0.0 else time_grid(duration, config.sample_period)
        return plan.evaluate(times), plan

    def _refuse(self, response, reason: str, values: dict, t0: float):
        response.plan.header.frame_id = self._config.frame_id
        self.get_logger().error(f'{values["service"]} {values["method"]} request refused: {reason}')
        self._diagnostics.report(PLAN_TASK, ERROR, reason, **values, solve_time=0.0,
                                 plan_time=time.perf_counter() - t0, iterations=0, knots=0, error=reason)
        return response

    def destroy_node(self):
        # CasADi must not be building in the warm-up thread while the interpreter exits
        if self._warmup.is_alive():
            self.get_logger().info('waiting for the solver warm-up to finish')
            self._warmup.join()
        self._planner.close()
        super().destroy_node()


def main(args=None):
    return run(PlannerNode, MultiThreadedExecutor, args, num_threads=PlannerNode.executor_threads)
