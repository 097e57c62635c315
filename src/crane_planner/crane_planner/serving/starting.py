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
from .runway_step import Placement, RunwayConflict, claim_window


def from_rest(serving: Serving, goal: Goal, move: Move, settle: float, feedback, canceled, t0: float) -> Steps:
    """A goal with the crane at rest: plan (on a runway: place), hold for its lead, send, follow. ``t0``: its
    arrival (timer)."""
    try:
        planned = plan_move(serving, move, 'execute_move', execute=True, settle=settle, place=False)
        planned = yield from _placed(serving, goal, planned, settle, canceled)
    except ValueError as exc:
        serving.report({'service': 'execute_move', 'method': '', **getattr(exc, 'values', {})}, None, t0, t0,
                       error=str(exc))
        return end(serving, goal, 'abort', str(exc))
    if planned is None:  # canceled or preempted while it waited for a crane that holds
        return unsent(serving, goal, None)
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
                placement, planned = _rechecked(serving, goal, placement, planned)
            except RunwayConflict as exc:
                serving.report(planned.values, None, t0, serving.timer(), error=str(exc))
                return end(serving, goal, 'abort', str(exc), planned)
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


def _placed(serving: Serving, goal: Goal, planned: Planned, settle: float, canceled) -> Steps:
    """``planned`` placed among the other cranes (itself without a runway); ``RunwayConflict`` if no start keeps it
    clear. One refused because of a crane that holds is placed again for a while first: that crane may be
    planning a goal of its own out of the way (two goals sent together), heard once planned and claimed: for up
    to ``max_solve_time`` (the longest a planner plans, the other's taken to be as this one's) and a claim window.
    None if the goal was canceled or preempted meanwhile."""
    until = None
    while True:
        try:
            placement = serving.runway.place(planned.checked, planned.plan, settle)
            return planned if placement is None else placed(planned, placement)
        except RunwayConflict as exc:
            now, config = serving.clock(), serving.config()
            if until is None and exc.holding:  # (placed against a hold: not against that crane's motion)
                until = now + round((config.options.max_solve_time + claim_window(config)) * 1e9)
            if until is None or now >= until:
                exc.values = planned.values
                raise
        if goal.state is not GoalState.ARRIVED or canceled():
            return None
        yield FEEDBACK_PERIOD


def _rechecked(serving: Serving, goal: Goal, placement: Placement, planned: Planned) -> tuple[Placement, Planned]:
    """A claimed goal checked again (``RunwayStep.recheck``): its placement and plan, moved later (said in the
    log) if an occupancy published before it now conflicts; ``RunwayConflict`` if no start keeps it clear."""
    again = serving.runway.recheck(goal, placement)
    if again is None:
        return placement, planned
    serving.log.warn(f'execute_move: another crane published first: starting {again.runway_delay:.2f} s later '
                     f'than asked, after crane {again.waited_for!r} (runway_policy wait)')
    return again, placed(planned, again)
