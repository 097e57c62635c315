"""A goal started from rest: planned, held until ``publish_lead`` before its start, sent, followed.

While it is held a cancel or a newer goal ends it with nothing streamed;
once sent, its motion is the axes' timeline's and its ``execution.Execution``
follows it (``following.follow``). On a shared runway its motion is claimed
when it is held (its occupancy published) and checked again while it is held
(``runway_step``: first published, first served): started later, or refused
naming the crane. Its steps run on the ``runner.GoalRunner``. Pure Python, no
ROS import.
"""
from __future__ import annotations

import math

from crane_msgs_py.messages.names import CART_JOINT

from ..planning.mass_path import predict_mass_path
from .context import Serving
from .execution import Execution
from .following import FEEDBACK_PERIOD, end, follow, unsent
from .goals import Goal, GoalState
from .handover import send_at, streamed_origin
from .moves import Move, model_at_rope, origin_of
from .preview import Planned, placed, plan_move
from .runner import Steps
from .runway_step import RunwayConflict


def from_rest(serving: Serving, goal: Goal, move: Move, settle: float, feedback, canceled, t0: float) -> Steps:
    """A goal with the crane at rest: plan, hold for its lead, send, follow. ``t0``: its arrival (timer)."""
    try:
        planned = plan_move(serving, move, 'execute_move', execute=True, settle=settle)
    except ValueError as exc:
        serving.report({'service': 'execute_move', 'method': '', **getattr(exc, 'values', {})}, None, t0, t0,
                       error=str(exc))
        return end(serving, goal, 'abort', str(exc))
    serving.report(planned.values, planned, t0, serving.timer())
    checked, plan, config = planned.checked, planned.plan, serving.config()
    feedback(progress=0.0, time_remaining=plan.duration, swing=math.nan)  # planned: the caller knows at once
    serving.goals.hold(goal)
    placement = planned.placement and serving.runway.claim(goal, planned.placement)  # (its occupancy published)
    # hold the trajectory until publish_lead before its start: a cancel before then streams nothing
    due = send_at(checked.start_ns, config.publish_lead)
    while serving.clock() < due and goal.state is GoalState.HELD and not canceled():
        if placement is not None:  # first published, first served: placed again after one published before it
            try:
                again = serving.runway.recheck(goal, placement)
            except RunwayConflict as exc:
                serving.report(planned.values, None, t0, serving.timer(), error=str(exc))
                return end(serving, goal, 'abort', str(exc), planned)
            if again is not None:
                placement, planned = again, _later(serving, planned, again)
                checked, due = planned.checked, send_at(planned.checked.start_ns, config.publish_lead)
        yield min(FEEDBACK_PERIOD, max(0.0, (due - serving.clock()) * 1e-9))
    now = serving.clock()
    origin = streamed_origin(checked.start_ns, now)
    execution = Execution(plan.duration, settle, origin or now, config.params.L1, config.params.L2,
                          stream_timeout=config.stream_timeout)
    running = planned.trajectory.running(origin, plan)
    if not serving.timeline.send(running, together=lambda: serving.goals.send(goal, execution, running, canceled)):
        return unsent(serving, goal, planned)
    serving.publish(planned.trajectory)
    serving.runway.sent(goal)
    if config.keep_out and serving.draw is not None:  # the load's path as planned, every tenth prediction step
        path = predict_mass_path(plan, model_at_rope(checked, config.params), origin_of(checked), settle)
        serving.draw(path.m2[::10], plan.duration + settle + 1.0)
    if checked.start_ns and not origin:
        serving.log.warn(f'execute_move: its start_time had passed {(now - checked.start_ns) * 1e-9:.3f} s '
                         'before its trajectory was sent: the streamer streams it from its next tick')
    cart = checked.axes[CART_JOINT]
    what = f'{checked.method}: {cart.start:g} -> {cart.goal:g} m in {plan.duration:.4g} s'
    return (yield from follow(serving, goal, planned, feedback, canceled, settle, what))


def _later(serving: Serving, planned: Planned, placement) -> Planned:
    """``planned`` moved to its new runway ``placement``, said in the log."""
    planned = placed(planned, placement)
    serving.log.warn(f'execute_move: another crane published first: starting {placement.runway_delay:.2f} s later '
                     f'than asked, after crane {placement.waited_for!r} (runway_policy wait)')
    return planned
