"""The planner's requests as plain Python: a preview, an executed goal from arrival to result, a settle.

The planner node hands in records (a ``moves.Move``, a ``crane_view.StreamSample``,
a ``transitions.Measurement``) and gets records back (``preview.Planned``,
``following.Outcome``, a ``transitions.Trajectory`` to publish); it keeps the
ROS entities and threads. ``MoveService`` puts the parts together, each a
module of its own over one ``context.Serving``: a preview (``preview``), a
goal's admission (``admission``: a shaper's during a motion handed over on
arrival, on the goals' thread), its start from rest (``starting``: planned,
held until ``publish_lead`` before its start, sent), a take-over of the
running motion (``takeover``), the following to its result
(``following``), a stop on a cancel and a settle (``settling``). An executed
goal's steps run on one worker (``runner.GoalRunner``); each goal's state is
in the book of goals (``goals.Goals``), what the axes stream in the
timeline (``timeline.Timeline``), what the crane does in
``crane_view.CraneView``. Every time comes from the clocks given (ROS time
``clock``, ``timer`` and ``sleep`` for waits), so the whole runs on a fake
clock in the tests. Also the solvers' start-up (``start_processes``,
``build_solvers``, ``report_when_built``). Pure Python, no ROS import.
"""
from __future__ import annotations

import threading
import time
from dataclasses import dataclass
from typing import Any, Callable

from crane_msgs_py.messages.names import BRIDGE_JOINT, HOIST_JOINT

from ..planning.methods import METHODS, Family, method_spec
from ..planning.signals import Swing
from . import admission, settling, takeover, transitions
from .config import Config
from .context import Serving
from .crane_view import HOLDING, StreamSample
from .following import Outcome
from .goals import Goal
from .moves import Move
from .preview import Planned, plan_move, plan_status
from .runner import GoalRunner, RunnerStopped
from .runway_step import RunwayStep
from .settling import Settled
from .transitions import JointReading, Measurement, Running, Trajectory

#: What the node uses: the service, its records and the solvers' start-up (each part is a module of its own).
__all__ = ['Built', 'MoveService', 'Outcome', 'Planned', 'RunnerStopped', 'Settled', 'build_solvers',
           'plan_status', 'report_when_built', 'start_processes']


@dataclass(frozen=True)
class Built:
    """The solvers built at start-up: seconds per method ready, the error per method failed, a summary."""

    times: dict
    failed: dict
    message: str


class MoveService:
    """The planner's requests, served.

    Args:
        planner: the ``serving.Planner``.
        config: the node's current ``Config`` (read at each request: a change applies to the next).
        clock: ROS time now (ns).
        publish: sends a ``Trajectory`` to the streamer.
        report: ``report(values, planned, t0, solved, error='')``: a request's status (/diagnostics): its
            values, the ``Planned`` (None: refused), when its planning began and ended (``timer``), why not.
        log: has ``info``, ``warn`` and ``error`` (a message each).
        sleep, timer: how waits wait (s) and are timed (s, monotonic).
        draw: ``draw(points, lifetime)``: with keep-out boxes set, the load's predicted path of a motion sent
            ((n, 3), m, ``crane_base``), to be shown for ``lifetime`` s (its motion and settle window).
        worker: execute goals on the runner's thread (the node); else each ``execute`` drives the runner
            on its caller's thread (the tests, on a fake clock).
        runway: this crane's side of a shared runway (``runway_step.RunwayStep``: the others' occupancies, its
            own published); None: none, nothing is published.
    """

    def __init__(self, planner, config: Callable[[], Config], clock: Callable[[], int],
                 publish: Callable[[Trajectory], Any], report: Callable[..., Any], log,
                 sleep: Callable[[float], None] = time.sleep, timer: Callable[[], float] = time.perf_counter,
                 draw: Callable[[Any, float], Any] | None = None, worker: bool = False,
                 runway: RunwayStep | None = None):
        self.serving = Serving(planner, config, clock, publish, report, log, sleep, timer, draw, runway=runway)
        self.runway = self.serving.runway
        self.planner, self.config, self.clock, self.log = planner, config, clock, log
        self.goals, self.view, self.timeline = self.serving.goals, self.serving.view, self.serving.timeline
        self.handing_over = self.serving.handing_over  # one handover (goal, stop, settle) planned at a time
        self.planning_times = self.serving.planning_times  # of NVF/RVF handovers, by kind: their first leads
        self.runner = GoalRunner(timer, sleep)
        if worker:
            self.runner.start()

    def close(self) -> None:
        """The runner stopped: a goal still executing ends with ``runner.RunnerStopped``."""
        self.runner.stop()

    # -- inputs ------------------------------------------------------------------------

    def on_stream_state(self, sample: StreamSample) -> None:
        self.view.on_stream_state(sample)
        self.runway.on_stream_state(sample.state, sample.hold)  # (a hold published on a runway)
        for execution in self.goals.executions():
            execution.on_stream_state(sample.stamp_ns, sample.motion_start_ns, sample.motion_duration,
                                      sample.motion_origin_ns, sample.state != HOLDING, sample.correction,
                                      sample.reason)

    def on_axis_status(self, stamp_ns: int, state: str, message: str) -> None:
        """The sim's (the axes') ``axis_status``: a fault reaction fails the goal it happens in."""
        for execution in self.goals.executions():
            execution.on_axis_status(stamp_ns, state, message)

    def on_joint_state(self, measured: Measurement) -> None:
        self.view.on_joint_state(measured)
        rope = measured.joints.get(HOIST_JOINT)
        length = rope.position if rope is not None else None
        swing = measured.swing
        for execution in self.goals.executions():
            execution.on_joint_state(measured.stamp_ns, swing.theta1, swing.theta2, length, swing.phi)

    # -- requests ---------------------------------------------------------------------

    def plan(self, move: Move, service: str, execute: bool = False) -> Planned:
        """The move checked and planned (``preview.plan_move``); MoveError/ValueError says why not."""
        return plan_move(self.serving, move, service, execute)

    def arrive(self, key, move: Move, settle: float) -> Goal:
        """A goal arrived, on the goals' thread (``admission.arrive``)."""
        return admission.arrive(self.serving, key, move, settle)

    def warm_handover(self, rehearse: Callable[[Trajectory], Any]) -> None:
        """A shaper's handover of the running motion rehearsed, nothing sent (``takeover.warm_handover``)."""
        takeover.warm_handover(self.serving, rehearse)

    def execute(self, goal: Goal, move: Move, settle: float, feedback: Callable[..., Any],
                canceled: Callable[[], bool]) -> Outcome:
        """``goal`` from its plan to its result (``admission.execute``), its steps on the runner; the caller
        waits for it. ``feedback(progress=, time_remaining=, swing=)``; ``canceled()``: whether the server has
        a cancel of it."""
        return self.runner.run(admission.execute(self.serving, goal, move, settle, feedback, canceled))

    def settle(self) -> Settled:
        """``~/settle`` (``settling.settle``); MoveError says why not."""
        return settling.settle(self.serving)


def start_processes(planner, config: Config, log) -> None:
    """The planner's first solver process started (its others start meanwhile), before a request can come."""
    if not config.solver_processes:
        return
    t0 = time.perf_counter()
    if planner.start_processes(ready_within=60.0):
        log.info(f'first of {config.solver_processes} solver processes ready in {time.perf_counter() - t0:.2f} s')
    else:
        log.error('no solver process started within 60 s; NVF/RVF requests will be refused')


#: Longest wait (s) for the workers to build a parameter change's solvers before nothing is reported.
REBUILD_WAIT = 600.0


def report_when_built(planner, report: Callable[[str], None]) -> None:
    """After a parameter change that changes the NLPs to build: ``report(message)`` once every worker has built
    them in the background (``Planner.wait_built``), saying how long that took. Returns at once."""
    t0 = time.perf_counter()

    def wait():
        if planner.wait_built(REBUILD_WAIT):
            report(f'solvers rebuilt for the new parameters in {time.perf_counter() - t0:.2f} s')

    threading.Thread(target=wait, name='solvers-rebuilt', daemon=True).start()


def build_solvers(planner, config: Config, log) -> Built:
    """Build every method once with ``config``, so first requests are warm. With solver processes, every one
    is started first (one still building takes a core), and what they lack of the configuration's warm-ups
    is built in them in the background (never in this process, whose threads answer the cheap requests)."""
    times, failed = {}, {}
    t_all = time.perf_counter()
    if config.solver_processes and not planner.start_processes(120.0, all_of_them=True):
        log.warn('not every solver process started within 120 s')
    if config.solver_processes:
        try:
            planner.warm_threads(config.warmups())
        except Exception as exc:
            log.warn(f'building the NVF/RVF solvers failed: {exc}')
    for method in METHODS:
        # long enough for every shaper; the variational solvers at a typical request
        duration = min(3.0 if method_spec(method).family is Family.VARIATIONAL else 10.0, config.max_duration)
        t0 = time.perf_counter()
        try:
            plan = planner.plan(method, min(0.3, config.max_displacement), duration, config.params, config.options)
        except Exception as exc:  # a warm-up failure only means building on first use
            failed[method] = str(exc)
            log.warn(f'{method} warm-up failed: {exc}')
            continue
        times[method] = time.perf_counter() - t0
        build = plan.info.get('build_time_s')
        log.info(f'{method} ready in {times[method]:.2f} s' + (f' (solver built in {build:.2f} s)' if build else ''))
    # the handover's predictor (a CasADi function built on first use)
    rest = [config.params.L1 if name == HOIST_JOINT else 0.0 for name in config.joints]
    holding = Running.holding(config.joints, rest, 0)
    measured = Measurement(0, {name: JointReading(p) for name, p in zip(config.joints, rest)},
                           Swing.rest(BRIDGE_JOINT in config.joints))
    transitions.handover_state(holding, 10_000_000, measured, config.params)
    return Built(times, failed, f'{len(times)} of {len(METHODS)} methods ready in {time.perf_counter() - t_all:.2f} s')
