"""A goal during a motion takes the motion over: its handover planned from the state at the handover, sent
until the streamer takes it, then followed; and the handover's warm-up.

A shaper's goal is handed over on arrival (``admission.arrive``, on the
goals' thread); a variational one in its first step on the
``runner.GoalRunner``; a handover the streamer refused (late) is planned
again further ahead (``handover.HandoverPolicy``). Once the streamer takes
it, the goal in motion is taken over (``goals.Goals.take_over``) and the
motion is the new goal's on the axes' timeline. A motion that ended before
its handover could be planned leaves the goal to be planned where the
motion ended (``swinging.start``). Pure Python, no ROS import.
"""
from __future__ import annotations

import math
from typing import Any, Callable

from crane_msgs_py.messages.names import CART_JOINT

from ..planning.methods import Family, family_of, method_spec, methods_of
from . import swinging, transitions
from .context import Serving
from .execution import Execution
from .following import end, follow, unsent
from .goals import Goal
from .handover import HandoverPolicy, HandoverResult, NotSent, Sent, arrival_lead
from .moves import Move, MoveError, check_move, check_rests_keep_out
from .preview import Planned
from .replanning import plan_from_running, retargeting, trajectory_from
from .runner import Steps
from .runway_step import publish_motion
from .swinging import until_held
from .transitions import Running, Trajectory


class MotionEnded(MoveError):
    """The motion a goal was to take over ended before its handover could be planned (a host too busy to
    plan it in the time left): the goal is then planned from rest, where the motion ended."""

    def __init__(self):
        super().__init__('goal', 'the running motion ended while this goal was planned')


def take_over(serving: Serving, goal: Goal, move: Move, settle: float, feedback, canceled) -> Steps:
    """A goal during a motion: plan from the state at the handover, send, and once the streamer has
    taken it over (its stream_state), end the preempted goal and follow this one."""
    take = goal.take_over
    on_arrival = take.sent is not None
    serving.log.info('execute_move: a goal during a motion: handed over on arrival' if on_arrival else
                     'execute_move: a goal during a motion: planning the handover')
    reported = []

    def send(lead_scale: float, first: bool):  # (the first from the goal's arrival, as if planned then)
        return send_handover(serving, goal, move, take.running, settle, lead_scale,
                             take.arrived_ns if first else None)

    def planned(result: HandoverResult):
        solved = serving.timer()
        planning = Planned(result.checked, result.plan, result.trajectory, result.values, solved - take.arrived_t)
        serving.report(result.values, planning, take.arrived_t, solved)
        reported.append(planning)
        feedback(progress=0.0, time_remaining=result.plan.duration, swing=math.nan)

    policy = HandoverPolicy(send, serving.sleep, serving.timer, warn=serving.log.warn,
                            silence=serving.config().stream_timeout)
    try:
        if take.error is not None:  # a refusal, or a bug's (for the node)
            raise take.error
        result = policy.run(take.sent, planned, canceled)
    except NotSent:  # (nothing of it streams: a running motion goes on as it was)
        return unsent(serving, goal, reported[0] if reported else None)
    except MotionEnded:
        return (yield from after_the_motion(serving, goal, move, settle, feedback, canceled))
    except ValueError as exc:
        serving.report({'service': 'execute_move', 'method': '', **getattr(exc, 'values', {})}, None,
                       take.arrived_t, take.arrived_t, error=str(exc))
        return end(serving, goal, 'abort', str(exc))
    if result is None:
        return end(serving, goal, 'abort', f'the streamer took none of {policy.attempts} handovers (see its '
                                           '/diagnostics); the running motion goes on', reported[0])
    checked, plan = result.checked, result.plan
    running = transitions.taken_over(take.running, result.trajectory.running(result.handover_ns, plan),
                                     goal.execution.motion_start_ns)
    serving.timeline.send(running, together=lambda: serving.goals.take_over(goal, result.handover_ns, running)
                          or True)
    if serving.runway.on:  # (its occupancy from the swing at the handover: a shaper's change was planned without)
        state = result.state if family_of(checked.method) is not Family.SHAPER else lambda: transitions.handover_state(
            take.running, result.handover_ns, serving.view.measured, serving.config().params)
        publish_motion(serving, goal, plan, state, result.handover_ns, settle)
    cart = checked.axes[CART_JOINT]
    what = (f'{checked.method}: from {cart.start:g} m (taking over the motion) -> {cart.goal:g} m in '
            f'{plan.duration:.4g} s')
    return (yield from follow(serving, goal, reported[0], feedback, canceled, settle, what))


def after_the_motion(serving: Serving, goal: Goal, move: Move, settle: float, feedback, canceled) -> Steps:
    """A goal whose running motion ended before its handover could be planned: planned where the streamer
    holds (from rest, or from the swing: ``swinging.start``), once its stream_state says it holds there
    (nothing accepted is lost)."""
    take = goal.take_over
    serving.log.warn('execute_move: the motion this goal was to take over ended before its handover could be '
                     'planned: planning it from where the motion ended')
    why = yield from until_held(serving, goal, take.running.end_ns, canceled, 'the motion it was to take over')
    if why is not None:
        return why
    return (yield from swinging.start(serving, goal, move, settle, feedback, canceled, take.arrived_t))


def send_handover(serving: Serving, goal: Goal, move: Move, running: Running, settle: float,
                  lead_scale: float = 1.0, arrived_ns: int | None = None) -> Sent:
    """Plan ``goal``'s handover of ``running`` and send it; ValueError says why it cannot be planned,
    NotSent that the goal gave way or was canceled meanwhile."""
    result = preempting(serving, move, running, lead_scale, arrived_ns)
    config = serving.config()
    execution = Execution(result.plan.duration, settle, result.handover_ns, config.params.L1, config.params.L2,
                          stream_timeout=config.stream_timeout)
    if not serving.goals.send(goal, execution):  # (before it is sent: the first stream_state of it finds it)
        raise NotSent()
    serving.publish(result.trajectory)  # at once: the handover is due in milliseconds
    return Sent(result, execution)


def preempting(serving: Serving, move: Move, running: Running, lead_scale: float = 1.0,
               arrived_ns: int | None = None, rehearse: bool = False) -> HandoverResult:
    """The handover of a goal arriving during ``running``, ``lead_scale`` times the configured lead from
    now, or from ``arrived_ns`` if given (``handover.arrival_lead``); ``rehearse``: see ``plan_handover``."""
    config = serving.config()
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
        end_at = dict(zip(running.joints, (float(i.position[-1]) for i in running.interps)))
        checked = check_move(move, config.bounds, end_at, config.params.L1)
        if checked.duration is None:
            raise MoveError('duration', 'a goal during a motion needs a duration (> 0 s): the fastest plan is '
                                        'planned from rest only')
        check_rests_keep_out(checked, config.params, config.keep_out)
        shaper = method_spec(checked.method).family is Family.SHAPER
        asked = (config.shaper_handover_lead if shaper else config.handover_lead) * lead_scale
        lead = arrival_lead(asked, arrived_ns, serving.clock())

        try:
            done = plan_from_running(serving, running, lead, retargeting(serving, running, checked),
                                     swing=not shaper, rehearse=rehearse,
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
                  handover_lead=(handover - serving.clock()) * 1e-9)
    return HandoverResult(checked, plan, trajectory_from(serving, plan, state, running.joints, handover), values,
                          handover, done.lead / asked, state)


def warm_handover(serving: Serving, rehearse: Callable[[Trajectory], Any]) -> None:
    """Plan a shaper's handover of the running motion as ``admission.arrive`` would (back to where the motion
    started) and ``rehearse`` its trajectory (the node serializes it as publishing would), sending
    nothing: a real goal's handover is a short run of Python that, left untouched for a while beside the
    1 kHz nodes, runs several times slower (cold caches, not page faults). Not while a handover is being
    planned (on the goals' thread, at its priority, it would take the core from an NVF/RVF handover's
    solver process, whose lead is tight). A bug's exception is raised after the rehearsal is counted."""
    if serving.handing_over.locked():
        return
    t0, running = serving.timer(), serving.view.in_motion()
    if running is None or not running.origin_ns or running.hoist_moves:  # (a shaper cannot retarget then)
        return
    config = serving.config()
    method = next((m for m in (running.method, config.method) if family_of(m) is Family.SHAPER),
                  methods_of(Family.SHAPER)[0])
    move = Move(method, goal=(float(running.interps[0].position[0]),), duration=running.duration)
    try:
        rehearse(preempting(serving, move, running, rehearse=True).trajectory)
    except ValueError:  # (a stop's remainder too short for the shaper, the motion ended meanwhile, ...)
        pass
    finally:
        serving.goals.count_warmup(running, serving.timer() - t0)
