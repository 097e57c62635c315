"""The planner's requests as plain Python: a preview, an executed goal from arrival to result, a settle.

The planner node hands in records (a ``moves.Move``, a ``crane_view.StreamSample``,
a ``transitions.Measurement``) and gets records back (``Planned``, ``Outcome``,
a ``transitions.Trajectory`` to publish); it keeps the ROS entities and
threads. An executed goal (``execute``): planned, held until
``publish_lead`` before its start, sent, followed (``execution.Execution``)
to its result; a goal during a motion takes the motion over
(``handover.HandoverPolicy``; a shaper's is planned and sent on arrival,
``arrive``, on the goals' thread); a cancel during the motion stops it
(``stops.plan_stop``). Each goal's state is in the book of goals
(``goals.Goals``), what the crane does in ``crane_view.CraneView``. Every
time comes from the clocks given (ROS time ``clock``, ``timer`` and
``sleep`` for waits), so the whole runs on a fake clock in the tests. Pure
Python, no ROS import.
"""
from __future__ import annotations

import contextlib
import math
import threading
import time
from dataclasses import dataclass
from typing import Any, Callable

from crane_msgs_py.messages.names import BRIDGE_JOINT, CART_JOINT, HOIST_JOINT, STREAM_STATE_TOPIC

from ..planning.continuation import problem_start, swing_names
from ..planning.mass_path import predict_mass_path
from ..planning.methods import METHODS, SHAPER_METHODS, VARIATIONAL_METHODS
from ..planning.plan import Plan, time_grid
from ..streaming.knots import knot_times
from ..streaming.reference_stream import position_text
from . import transitions
from .config import Config
from .crane_view import DISCOVERY_WAIT, HOLDING, CraneView, StreamSample
from .execution import DONE, FAILED, MOVING, WAITING, Execution
from .goals import Goal, Goals, GoalState, TakeOver
from .handover import (
    HandoverPolicy,
    HandoverResult,
    NotSent,
    PlanningTimes,
    Sent,
    Verdict,
    arrival_lead,
    plan_handover,
    send_at,
    streamed_origin,
    taken,
)
from .moves import (
    CheckedMove,
    Move,
    MoveError,
    axis_samples,
    check_move,
    check_rests_keep_out,
    keep_out_clearance,
    model_at_rope,
    origin_of,
    plan_keeping_out,
)
from .stops import STOP_LEAD, plan_stop
from .transitions import JointReading, Measurement, Running, Trajectory

#: Settle window (s) of a goal that gives none (``settle`` 0).
DEFAULT_SETTLE = 2.0
#: Feedback period (s): 20 Hz, above the contract's 10 Hz.
FEEDBACK_PERIOD = 0.05


class MotionEnded(MoveError):
    """The motion a goal was to take over ended before its handover could be planned (a host too busy to
    plan it in the time left): the goal is then planned from rest, where the motion ended."""

    def __init__(self):
        super().__init__('goal', 'the running motion ended while this goal was planned')


@dataclass(frozen=True)
class Planned:
    """A move planned: checked, its plan, its trajectory, its status values (/diagnostics) and how long
    its planning took (s; for a handover from the goal's arrival)."""

    checked: CheckedMove
    plan: Plan
    trajectory: Trajectory
    values: dict
    planning_s: float = 0.0


@dataclass(frozen=True)
class Outcome:
    """A goal's result: how it ends (``succeed``, ``abort``, ``cancel``), why, the residual swing (m), its
    plan (None if none was made) and the handover warm-ups during its motion (count, s)."""

    how: str
    message: str
    residual_swing: float = math.nan
    plan: Planned | None = None
    warmups: int = 0
    warmup_s: float = 0.0

    @property
    def success(self) -> bool:
        return self.how == 'succeed'

    def status(self) -> dict:
        """Its values on /diagnostics."""
        return dict(outcome=self.how, residual_swing=self.residual_swing, error='' if self.success else self.message,
                    handover_warmups=self.warmups,
                    handover_warmup_ms=1e3 * self.warmup_s / self.warmups if self.warmups else 0.0)


def plan_status(values: dict, planned: Planned | None, t0: float, solved: float, now: float,
                error: str = '') -> tuple[str, dict]:
    """A request's status on /diagnostics, (message, values): the plan's facts, or why it was refused
    (``planned`` None); planned from ``t0`` to ``solved``, reported at ``now`` (s, one timer)."""
    if error:
        return error, dict(values, solve_time=0.0, plan_time=now - t0, iterations=0, knots=0, error=error)
    plan, knots = planned.plan, planned.trajectory.knots
    info = plan.info
    return f'{values["method"]}: {knots} knots in {plan.duration:.4f} s', dict(
        values, solve_time=info.get('solve_time_s', solved - t0), build_time=info.get('build_time_s', 0.0),
        iterations=info.get('iterations', 0), plan_time=solved - t0, message_time=now - solved, knots=knots,
        error='')


@dataclass(frozen=True)
class Settled:
    """A settle sent: what it says, the swing's amplitude it damps (m) and its plan."""

    message: str
    swing: float
    plan: Plan


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
    """

    def __init__(self, planner, config: Callable[[], Config], clock: Callable[[], int],
                 publish: Callable[[Trajectory], Any], report: Callable[..., Any], log,
                 sleep: Callable[[float], None] = time.sleep, timer: Callable[[], float] = time.perf_counter,
                 draw: Callable[[Any, float], Any] | None = None):
        self.planner, self.config, self.clock = planner, config, clock
        self._publish, self._report, self.log, self._draw = publish, report, log, draw
        self._sleep, self._timer = sleep, timer
        self.goals = Goals(clock)
        self.view = CraneView(clock, self.goals, sleep=sleep, monotonic=timer)
        self.handing_over = threading.Lock()  # one handover (goal, stop, settle) planned at a time
        self.planning_times = PlanningTimes()  # of NVF/RVF handovers, by kind: their first leads

    # -- inputs ------------------------------------------------------------------------

    def on_stream_state(self, sample: StreamSample) -> None:
        self.view.on_stream_state(sample)
        for execution in self.goals.executions():
            execution.on_stream_state(sample.stamp_ns, sample.motion_start_ns, sample.motion_duration,
                                      sample.motion_origin_ns, sample.state != HOLDING)

    def on_axis_status(self, stamp_ns: int, state: str, message: str) -> None:
        """The sim's (the axes') ``axis_status``: a fault reaction fails the goal it happens in."""
        for execution in self.goals.executions():
            execution.on_axis_status(stamp_ns, state, message)

    def on_joint_state(self, measured: Measurement) -> None:
        self.view.on_joint_state(measured)
        rope = measured.joints.get(HOIST_JOINT)
        length = rope.position if rope is not None else None
        swing = measured.swing  # (theta1, theta2[, phi1, phi2], rates)
        phi = swing[2:4] if len(swing) == 8 else None
        for execution in self.goals.executions():
            execution.on_joint_state(measured.stamp_ns, swing[0], swing[1], length, phi)

    # -- planning (a preview, and each goal) ---------------------------------------------

    def plan(self, move: Move, service: str, execute: bool = False) -> Planned:
        """The move checked and planned; MoveError/ValueError says why not (its ``values``: the status)."""
        config, t0 = self.config(), self._timer()
        values = {'service': service, 'method': move.method or config.method,
                  'start': move.start[0] if move.start else math.nan,
                  'goal': move.goal[0] if move.goal else math.nan, 'duration': move.duration}
        # a goal waits a moment for a streamer not heard yet (one just restarted is being discovered)
        heard = self.view.wait_heard(DISCOVERY_WAIT) if execute else self.view.heard()
        hold = None if heard is None else heard.hold
        try:
            checked = check_move(move, config.bounds, hold, config.params.L1)
            cart = checked.axes[CART_JOINT]
            values.update(method=checked.method, start=cart.start, goal=cart.goal,
                          displacement=checked.displacement)
            for name, axis_move in checked.axes.items():  # the other axes' as <name>_start, <name>_goal
                if name != CART_JOINT:
                    values.update({f'{name}_start': axis_move.start, f'{name}_goal': axis_move.goal})
            check_rests_keep_out(checked, config.params, config.keep_out)
            plan = plan_keeping_out(self.planner, checked, config.bounds, config.params, config.options,
                                    config.keep_out)
            clearance = plan.info.get('min_clearance', math.inf)
            if execute:  # after planning: a preview and a goal of the same bad move give the same reason
                check_executable(checked, hold, heard is not None and heard.operator, self.view.foreign_motion())
        except ValueError as exc:
            exc.values = values
            raise
        values['duration'] = plan.duration
        trajectory = Trajectory(checked.joints, axis_samples(plan, knots_of(plan, config)), checked.starts,
                                checked.start_ns)
        if math.isfinite(clearance):
            values['min_clearance'] = clearance
        return Planned(checked, plan, trajectory, values, self._timer() - t0)

    # -- a goal's arrival (the goals' thread) ----------------------------------------------

    def arrive(self, key, move: Move, settle: float) -> Goal:
        """A goal arrived (registered under ``key`` until accepted); a shaper's during a motion is handed
        over at once (``_send_handover``): before the server accepts it, and before the executor runs
        ``execute``. A variational one (its lead is 42 ms) plans in ``execute``: the goals' thread never
        waits on a solver process, so a cancel or another goal is not held up behind it."""
        goal, forgotten = self.goals.arrive(key)
        for other in forgotten:
            self.log.error(f'execute_move: a goal was never accepted by the action server (it was '
                           f'{other.history[-1].value}); forgotten')
        running = None
        try:
            arrived_t, running = self._timer(), self.view.in_motion()
            if running is not None and math.isfinite(settle) and settle >= 0.0:  # (else execute refuses it)
                goal.take_over = TakeOver(running, goal.arrived_ns, arrived_t)
                config = self.config()
                shaper = (move.method or config.method) not in VARIATIONAL_METHODS
                # not when planning would wait: for the running motion's start on the streamer (origin) or
                # behind a stop or settle being planned (handing_over)
                if shaper and running.origin_ns and not self.handing_over.locked():
                    sent = self._send_handover(goal, move, running, settle or DEFAULT_SETTLE)
                    goal.take_over = TakeOver(running, goal.arrived_ns, arrived_t, sent)
        except Exception as exc:  # raised again by _take_over: a refusal (ValueError) or a bug's
            goal.take_over = TakeOver(running, goal.arrived_ns, self._timer(), error=exc)
        return goal

    def warm_handover(self, rehearse: Callable[[Trajectory], Any]) -> None:
        """Plan a shaper's handover of the running motion as ``arrive`` would (back to where the motion
        started) and ``rehearse`` its trajectory (the node serializes it as publishing would), sending
        nothing: a real goal's handover is a short run of Python that, left untouched for a while beside the
        1 kHz nodes, runs several times slower (cold caches, not page faults). Not while a handover is being
        planned (on the goals' thread, at its priority, it would take the core from an NVF/RVF handover's
        solver process, whose lead is tight). A bug's exception is raised after the rehearsal is counted."""
        if self.handing_over.locked():
            return
        t0, running = self._timer(), self.view.in_motion()
        if running is None or not running.origin_ns or running.hoist_moves:  # (a shaper cannot retarget then)
            return
        config = self.config()
        method = next((m for m in (running.method, config.method) if m in SHAPER_METHODS), SHAPER_METHODS[0])
        move = Move(method, goal=(float(running.interps[0].position[0]),), duration=running.duration)
        try:
            rehearse(self._preempting(move, running, rehearse=True).trajectory)
        except ValueError:  # (a stop's remainder too short for the shaper, the motion ended meanwhile, ...)
            pass
        finally:
            self.goals.count_warmup(running, self._timer() - t0)

    # -- a goal executed (the executor's threads) -------------------------------------------

    def execute(self, goal: Goal, move: Move, settle: float, feedback: Callable[..., Any],
                canceled: Callable[[], bool]) -> Outcome:
        """``goal`` from its plan to its result. ``feedback(progress=, time_remaining=, swing=)``; ``canceled()``:
        whether the server has a cancel of it."""
        t0 = self._timer()
        if not (math.isfinite(settle) and settle >= 0.0):
            return self._end(goal, 'abort', f'settle: must be finite and >= 0 s (0 = {DEFAULT_SETTLE:g} s), '
                                            f'got {settle}')
        settle = settle or DEFAULT_SETTLE
        if goal.take_over is not None:  # a new goal during a motion: it takes over (preemption)
            return self._take_over(goal, move, settle, feedback, canceled)
        return self._from_rest(goal, move, settle, feedback, canceled, t0)

    def _from_rest(self, goal: Goal, move: Move, settle: float, feedback, canceled, t0: float) -> Outcome:
        """A goal with the crane at rest: plan, hold for its lead, send, follow. ``t0``: its arrival (timer)."""
        try:
            planned = self.plan(move, 'execute_move', execute=True)
        except ValueError as exc:
            self._report({'service': 'execute_move', 'method': '', **getattr(exc, 'values', {})}, None, t0, t0,
                          error=str(exc))
            return self._end(goal, 'abort', str(exc))
        self._report(planned.values, planned, t0, self._timer())
        checked, plan, config = planned.checked, planned.plan, self.config()
        feedback(progress=0.0, time_remaining=plan.duration, swing=math.nan)  # planned: the caller knows at once
        self.goals.hold(goal)
        # hold the trajectory until publish_lead before its start: a cancel before then streams nothing
        due = send_at(checked.start_ns, config.publish_lead)
        while self.clock() < due and goal.state is GoalState.HELD and not canceled():
            self._sleep(min(FEEDBACK_PERIOD, max(0.0, (due - self.clock()) * 1e-9)))
        now = self.clock()
        origin = streamed_origin(checked.start_ns, now)
        execution = Execution(plan.duration, settle, origin or now, config.params.L1, config.params.L2,
                              stream_timeout=config.stream_timeout)
        if not self.goals.send(goal, execution, planned.trajectory.running(origin, plan), canceled):
            if goal.state in (GoalState.PREEMPTED, GoalState.TAKEN_OVER):
                return self._end(goal, 'abort', 'preempted by a newer goal before its motion started: nothing '
                                                 'was streamed', planned)
            return self._end(goal, 'cancel', 'canceled before its motion started: nothing was streamed', planned)
        self._publish(planned.trajectory)
        if config.keep_out and self._draw is not None:  # the route: the load's path as planned, every 50 ms
            path = predict_mass_path(plan, model_at_rope(checked, config.params), origin_of(checked), settle)
            self._draw(path.m2[::10], plan.duration + settle + 1.0)
        if checked.start_ns and not origin:
            self.log.warn(f'execute_move: its start_time had passed {(now - checked.start_ns) * 1e-9:.3f} s '
                          'before its trajectory was sent: the streamer streams it from its next tick')
        cart = checked.axes[CART_JOINT]
        what = f'{checked.method}: {cart.start:g} -> {cart.goal:g} m in {plan.duration:.4g} s'
        return self._follow(goal, planned, feedback, canceled, settle, what)

    def _take_over(self, goal: Goal, move: Move, settle: float, feedback, canceled) -> Outcome:
        """A goal during a motion: plan from the state at the handover, send, and once the streamer has
        taken it over (its stream_state), end the preempted goal and follow this one."""
        take_over = goal.take_over
        on_arrival = take_over.sent is not None
        self.log.info('execute_move: a goal during a motion: handed over on arrival' if on_arrival else
                      'execute_move: a goal during a motion: planning the handover')
        reported = []

        def send(lead_scale: float, first: bool):  # (the first from the goal's arrival, as if planned then)
            return self._send_handover(goal, move, take_over.running, settle, lead_scale,
                                       take_over.arrived_ns if first else None)

        def planned(result: HandoverResult):
            solved = self._timer()
            planning = Planned(result.checked, result.plan, result.trajectory, result.values,
                               solved - take_over.arrived_t)
            self._report(result.values, planning, take_over.arrived_t, solved)
            reported.append(planning)
            feedback(progress=0.0, time_remaining=result.plan.duration, swing=math.nan)

        policy = HandoverPolicy(send, self._sleep, self._timer, warn=self.log.warn,
                                silence=self.config().stream_timeout)
        try:
            if take_over.error is not None:  # a refusal, or a bug's (for the node)
                raise take_over.error
            result = policy.run(take_over.sent, planned, canceled)
        except NotSent:  # (nothing of it streams: a running motion goes on as it was)
            if goal.state in (GoalState.PREEMPTED, GoalState.TAKEN_OVER):
                return self._end(goal, 'abort', 'preempted by a newer goal before its motion started: nothing '
                                                 'was streamed', reported[0] if reported else None)
            return self._end(goal, 'cancel', 'canceled before its motion started: nothing was streamed',
                             reported[0] if reported else None)
        except MotionEnded:
            return self._after_the_motion(goal, move, settle, feedback, canceled)
        except ValueError as exc:
            self._report({'service': 'execute_move', 'method': '', **getattr(exc, 'values', {})}, None,
                         take_over.arrived_t, take_over.arrived_t, error=str(exc))
            return self._end(goal, 'abort', str(exc))
        if result is None:
            return self._end(goal, 'abort', f'the streamer took none of {policy.attempts} handovers (see its '
                                            '/diagnostics); the running motion goes on', reported[0])
        checked, plan = result.checked, result.plan
        self.goals.take_over(goal, result.handover_ns, transitions.taken_over(
            take_over.running, result.trajectory.running(result.handover_ns, plan), goal.execution.motion_start_ns))
        cart = checked.axes[CART_JOINT]
        what = (f'{checked.method}: from {cart.start:g} m (taking over the motion) -> {cart.goal:g} m in '
                f'{plan.duration:.4g} s')
        return self._follow(goal, reported[0], feedback, canceled, settle, what)

    def _after_the_motion(self, goal: Goal, move: Move, settle: float, feedback, canceled) -> Outcome:
        """A goal whose running motion ended before its handover could be planned: planned from rest where the
        streamer holds, once its stream_state says it holds there (nothing accepted is lost)."""
        take_over = goal.take_over
        self.log.warn('execute_move: the motion this goal was to take over ended before its handover could be '
                      'planned: planning it from where the motion ended')
        stream_timeout = self.config().stream_timeout
        heard_t = self._timer()
        last = None
        while True:
            heard = self.view.heard()
            if heard is not None and heard.state == HOLDING and heard.stamp_ns >= take_over.running.end_ns:
                break
            if canceled():
                return self._end(goal, 'cancel', 'canceled before its motion started: nothing was streamed')
            if heard is not None and heard.stamp_ns != last:
                heard_t, last = self._timer(), heard.stamp_ns
            elif self._timer() - heard_t >= stream_timeout:
                return self._end(goal, 'abort', f'the motion it was to take over ended, and no stream_state said '
                                                f'the streamer holds after it within {stream_timeout:g} s')
            self._sleep(0.005)
        return self._from_rest(goal, move, settle, feedback, canceled, take_over.arrived_t)

    def _send_handover(self, goal: Goal, move: Move, running: Running, settle: float, lead_scale: float = 1.0,
                       arrived_ns: int | None = None) -> Sent:
        """Plan ``goal``'s handover of ``running`` and send it; ValueError says why it cannot be planned,
        NotSent that the goal gave way or was canceled meanwhile."""
        result = self._preempting(move, running, lead_scale, arrived_ns)
        config = self.config()
        execution = Execution(result.plan.duration, settle, result.handover_ns, config.params.L1, config.params.L2,
                              stream_timeout=config.stream_timeout)
        if not self.goals.send(goal, execution):  # (before it is sent: the first stream_state of it finds it)
            raise NotSent()
        self._publish(result.trajectory)  # at once: the handover is due in milliseconds
        return Sent(result, execution)

    def _follow(self, goal: Goal, planned: Planned, feedback, canceled, settle: float, what: str) -> Outcome:
        """Follow the goal's motion to its result: done, taken over by a newer goal, or stopped on a cancel."""
        self.goals.follow(goal)
        stopped = None  # (where the stop ends, m) once a cancel has stopped the motion
        while True:
            execution = goal.execution
            phase = execution.phase(self.clock())
            if goal.running is not None:  # a pending motion's origin, kept once this goal has ended too
                self.view.origin(goal.running, wait=0.0)
            feedback(progress=execution.progress, time_remaining=execution.time_remaining, swing=execution.swing)
            if goal.state is GoalState.TAKEN_OVER:
                return self._end(goal, 'abort', f'preempted by a newer goal after '
                                                f'{execution.progress * execution.duration:.3f} s of its motion '
                                                f'({what})', planned)
            if canceled() and stopped is None:
                if phase in (WAITING, MOVING) and goal.running is not None:
                    try:
                        stopped = self._stop(goal, settle)
                    except ValueError as exc:
                        return self._end(goal, 'cancel', f'canceled, but no stop could be planned ({exc}): the '
                                                         'motion runs to its end', planned)
                    continue
                return self._end(goal, 'cancel', 'canceled after its motion had ended', planned, execution.residual)
            if phase in (DONE, FAILED):
                break
            self._sleep(FEEDBACK_PERIOD)
        if phase == FAILED:
            self.goals.clear(goal.running)  # the streamer did not take it: nothing is in motion
            return self._end(goal, 'abort', execution.failure, planned)
        residual = ('no joint_states: residual not measured' if math.isnan(execution.residual)
                    else f'residual swing {1e3 * execution.residual:.3f} mm')
        cut = ('' if execution.window_end_ns == execution.end_ns + round(settle * 1e9) else
               f' (observed {(execution.window_end_ns - execution.end_ns) * 1e-9:.3g} s: the next motion started)')
        if stopped is not None:
            return self._end(goal, 'cancel', f'canceled: stopped at {stopped} m in {execution.duration:.4g} s '
                                             f'without swing ({what}); {residual}{cut}', planned, execution.residual)
        return self._end(goal, 'succeed', f'{what}; {residual}{cut}', planned, execution.residual)

    def _end(self, goal: Goal, how: str, message: str, planned: Planned | None = None,
             residual: float = math.nan) -> Outcome:
        self.goals.end(goal)
        return Outcome(how, message, residual, planned, goal.warmups, goal.warmup_s)

    # -- motion from any state: a new goal, a stop, a settle ------------------------------------

    def _handover(self, running: Running, lead: float, make_plan, swing: bool = True, rehearse: bool = False,
                  kind=None):
        """``handover.plan_handover`` of ``running`` once its origin is known, one at a time (``rehearse``:
        beside them); the swing there predicted from the newest joint_states (``swing``: not needed by a
        shaper's change). ``kind``: what ``planning_times`` keeps its planning time under, and may lengthen
        its first lead by; None for a shaper's change, whose short lead is on purpose."""
        if not self.view.origin(running):
            raise MoveError('goal', 'the running motion has not started on the streamer yet (no stream_state '
                                    'of it): a goal during it is accepted once it streams')
        params = self.config().params

        def state_at(handover_ns):
            return transitions.handover_state(running, handover_ns, self.view.measured, params, swing)

        with contextlib.nullcontext() if rehearse else self.handing_over:
            return plan_handover(self.clock, running, lead, make_plan, state_at, rehearse, self._timer,
                                 self.log.warn, times=None if kind is None else self.planning_times, kind=kind)

    def _preempting(self, move: Move, running: Running, lead_scale: float = 1.0, arrived_ns: int | None = None,
                    rehearse: bool = False) -> HandoverResult:
        """The handover of a goal arriving during ``running``, ``lead_scale`` times the configured lead from
        now, or from ``arrived_ns`` if given (``handover.arrival_lead``); ``rehearse``: see ``plan_handover``."""
        config = self.config()
        values = {'service': 'execute_move', 'method': move.method or config.method,
                  'goal': move.goal[0] if move.goal else math.nan, 'duration': move.duration, 'preempts': True}
        try:
            if move.start:
                raise MoveError('start', 'a goal during a motion starts where the motion is when it takes over: '
                                         'leave start empty')
            if move.start_ns:
                raise MoveError('start_time', 'a goal during a motion takes over at once: leave start_time zero')
            if move.via:
                raise MoveError('via', 'a goal during a motion goes straight to its goal from where the motion is: '
                                       'leave via empty, or send it once the crane is at rest')
            end = dict(zip(running.joints, (float(i.position[-1]) for i in running.interps)))
            checked = check_move(move, config.bounds, end, config.params.L1)
            if checked.duration is None:
                raise MoveError('duration', 'a goal during a motion needs a duration (> 0 s): the fastest plan is '
                                            'planned from rest only')
            check_rests_keep_out(checked, config.params, config.keep_out)
            goal = checked.goals
            shaper = checked.method not in VARIATIONAL_METHODS
            asked = (config.shaper_handover_lead if shaper else config.handover_lead) * lead_scale
            lead = arrival_lead(asked, arrived_ns, self.clock())

            def make(handover_ns, state):
                plan = transitions.retarget(self.planner.variational, running, handover_ns, state, checked.method,
                                            goal, checked.duration, config.params, config.options)
                if config.keep_out:  # from the state at the handover: its swing, the servo's lag
                    start, model = problem_start(state, config.params)
                    origin = {name: s.position for name, s in state.axes.items() if name != HOIST_JOINT}
                    keep_out_clearance(plan, origin, model, config.keep_out, start)
                return plan

            try:
                done = self._handover(running, lead, make, swing=not shaper, rehearse=rehearse,
                                      kind=None if shaper else ('goal', checked.method, running.joints))
            except MoveError:
                raise
            except ValueError as exc:
                raise MoveError('duration', str(exc)) from None
            if done is None:
                raise MotionEnded()
        except ValueError as exc:
            exc.values = values
            raise
        plan, handover, state = done.plan, done.handover_ns, done.state
        checked = checked.starting({name: s.position for name, s in state.axes.items()}, handover)
        cart = checked.axes[CART_JOINT]
        values.update(method=checked.method, start=cart.start, goal=cart.goal, duration=plan.duration,
                      handover_lead=(handover - self.clock()) * 1e-9)
        return HandoverResult(checked, plan, self._trajectory(plan, state, running.joints, handover), values,
                              handover, done.lead / asked)

    def _trajectory(self, plan: Plan, state, joints, handover_ns: int) -> Trajectory:
        starts = transitions.joint_starts(plan, state)
        return Trajectory(tuple(joints), axis_samples(plan, knots_of(plan, self.config())), tuple(starts),
                          handover_ns)

    def _stop(self, goal: Goal, settle: float) -> str:
        """Stop ``goal``'s motion without swing (a cancel during it): send the stop, follow it from now on.
        Returns where the axes stop (m, as text); ValueError says why no stop could be planned."""
        config, running = self.config(), goal.running

        def make(handover_ns, state):
            return plan_stop(self.planner.variational, running, handover_ns, config.params, config.options,
                             state=state).plan

        done = self._handover(running, STOP_LEAD, make, kind=('stop', running.method, running.joints))
        if done is None:  # the motion ended meanwhile: it is at rest already
            return _where(interp.position[-1] for interp in running.interps)
        plan, handover, state = done.plan, done.handover_ns, done.state
        trajectory = self._trajectory(plan, state, running.joints, handover)
        stop = trajectory.running(handover, plan)
        self.goals.stopping(goal, stop, Execution(plan.duration, settle, handover, config.params.L1,
                                                  config.params.L2, stream_timeout=config.stream_timeout))
        self._publish(trajectory)
        # a stop ending after the motion would have (one near its end) is streamed with its change delayed to
        # the tick at or after its stamp: what a next handover must continue
        if taken(goal.execution, handover, config.stream_timeout, self._sleep, self._timer) is Verdict.TAKEN:
            self.goals.replace(goal, stop, transitions.taken_over(running, stop, goal.execution.motion_start_ns))
        where = _where(interp.position[-1] for interp in stop.interps)
        self.log.info(f'execute_move: canceled during its motion: stopping at {where} m in '
                      f'{plan.duration:.4g} s ({plan.method})')
        return where

    def settle(self) -> Settled:
        """``~/settle``: damp the swing measured now by a short motion ending where the cart is held, sent;
        MoveError says why not."""
        config = self.config()
        if self.view.in_motion() is not None:
            raise MoveError('settle', 'a motion is streaming: settle once it has ended')
        hold = self.view.hold()
        if hold is None:
            raise MoveError('settle', f'no streamer heard on {STREAM_STATE_TOPIC}: nothing would stream the '
                                      'motion')
        measured, now = self.view.measured, self.clock()
        if measured is None or now - measured.stamp_ns > transitions.MEASUREMENT_AGE * 1e9:
            raise MoveError('settle', f'no joint_states within {transitions.MEASUREMENT_AGE:g} s: the swing to '
                                      'damp is not measured')
        joints = tuple(j for j in config.joints if j in hold)
        holding = Running.holding(joints, [hold[j] for j in joints], now)

        def make(handover_ns, state):
            return transitions.settle(self.planner.variational, state, config.params, config.options,
                                      config.settle_method)

        done = self._handover(holding, config.handover_lead, make, kind=('settle', config.settle_method, joints))
        trajectory = self._trajectory(done.plan, done.state, joints, done.handover_ns)
        self.goals.set_running(trajectory.running(done.handover_ns, done.plan))
        self._publish(trajectory)
        swing = transitions.swing_of(done.state, config.params)
        return Settled(f'settling a swing of about {1e3 * swing:.1f} mm: a {done.plan.duration:.3g} s '
                       f'{done.plan.method} motion ending where the cart is held ({hold[CART_JOINT]:.6g} m)', swing,
                       done.plan)


def knots_of(plan: Plan, config: Config):
    """Where a plan is sampled for its trajectory: where it needs knots, or every ``sample_period``."""
    return knot_times(plan) if config.sample_period == 0.0 else time_grid(plan.duration, config.sample_period)


def check_executable(move: CheckedMove, hold: dict | None, operator: bool = False,
                     foreign: float | None = None) -> None:
    """What the streamer would refuse, refused before anything is sent (``foreign``: seconds left of a motion
    the streamer streams that this planner did not send, ``CraneView.foreign_motion``)."""
    if hold is None:
        raise MoveError('goal', f'no streamer heard on {STREAM_STATE_TOPIC} for {DISCOVERY_WAIT:g} s: nothing '
                                'would stream the motion (is crane_streamer running and started?)')
    if operator:
        raise MoveError('goal', 'the streamer is in operator mode (it follows cmd_vel): set its mode to '
                                'trajectory, at rest, to execute moves')
    if foreign is not None:
        raise MoveError('goal', f'the streamer is streaming a motion this planner did not send (it was started '
                                f'during it): the motion ends in {foreign:.3g} s; send the goal after that')
    for joint, start in zip(move.joints, move.starts):
        if joint not in hold:
            raise MoveError('joint_names', f'the streamer does not stream {joint} (it streams '
                                           f'{", ".join(hold)}): start it with joints {list(move.joints)}')
        if abs(start - hold[joint]) > 1e-6:
            raise MoveError('start', f'{start:.6g} m is not where the streamer holds the {joint} '
                                     f'({hold[joint]:.6g} m); leave start empty to start there')


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
        duration = min(3.0 if method in VARIATIONAL_METHODS else 10.0, config.max_duration)
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
                           (0.0,) * len(swing_names(BRIDGE_JOINT in config.joints)))
    transitions.handover_state(holding, 10_000_000, measured, config.params)
    return Built(times, failed, f'{len(times)} of {len(METHODS)} methods ready in {time.perf_counter() - t_all:.2f} s')


def _where(positions) -> str:
    """Where the axes stop (m) for messages: one joint's position, or several in parentheses."""
    values = tuple(float(x) for x in positions)
    return position_text(values[0] if len(values) == 1 else values)
