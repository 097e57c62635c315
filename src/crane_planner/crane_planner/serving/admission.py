"""A goal's admission: registered on arrival (a shaper's during a motion handed over at once), and its
execution begun where the axes are held or by taking the running motion over.

``arrive`` runs on the goals' thread, before the action server accepts the
goal; ``execute`` is the goal's steps on the ``runner.GoalRunner``: a
settle window that is not finite and >= 0 is refused, a goal that arrived
during a motion takes it over (``takeover.take_over``), any other starts
where the axes are held (``swinging.start``: from rest, or from the load's
swing). Pure Python, no ROS import.
"""
from __future__ import annotations

import math

from ..planning.methods import Family, family_of
from .context import Serving
from .following import DEFAULT_SETTLE, end
from .goals import Goal, TakeOver
from .moves import Move
from .runner import Steps
from .swinging import start
from .takeover import send_handover, take_over


def arrive(serving: Serving, key, move: Move, settle: float) -> Goal:
    """A goal arrived (registered under ``key`` until accepted); a shaper's during a motion is handed
    over at once (``takeover.send_handover``): before the server accepts it, and before its steps run.
    A variational one (its lead, ``handover_lead``, is tens of milliseconds) plans in its steps: the goals'
    thread never waits on a solver process, so a cancel or another goal is not held up behind it."""
    goal, forgotten = serving.goals.arrive(key)
    for other in forgotten:
        serving.log.error(f'execute_move: a goal was never accepted by the action server (it was '
                          f'{other.history[-1].value}); forgotten')
    running = None
    try:
        arrived_t, running = serving.timer(), serving.view.in_motion()
        if running is not None and math.isfinite(settle) and settle >= 0.0:  # (else execute refuses it)
            goal.take_over = TakeOver(running, goal.arrived_ns, arrived_t)
            config = serving.config()
            shaper = family_of(move.method or config.method) is not Family.VARIATIONAL
            # not when planning would wait: for the running motion's start on the streamer (origin) or
            # behind a stop or settle being planned (handing_over)
            if shaper and running.origin_ns and not serving.handing_over.locked():
                sent = send_handover(serving, goal, move, running, settle or DEFAULT_SETTLE)
                goal.take_over = TakeOver(running, goal.arrived_ns, arrived_t, sent)
    except Exception as exc:  # raised again by take_over: a refusal (ValueError) or a bug's
        goal.take_over = TakeOver(running, goal.arrived_ns, serving.timer(), error=exc)
    return goal


def execute(serving: Serving, goal: Goal, move: Move, settle: float, feedback, canceled) -> Steps:
    """``goal``'s steps from its plan to its result. ``feedback(progress=, time_remaining=, swing=)``;
    ``canceled()``: whether the server has a cancel of it."""
    return _steps(serving, goal, move, settle, feedback, canceled, serving.timer())


def _steps(serving: Serving, goal: Goal, move: Move, settle: float, feedback, canceled, t0: float) -> Steps:
    """``execute``'s steps; ``t0``: when it was asked (timer), what a plan's time counts from."""
    if not (math.isfinite(settle) and settle >= 0.0):
        return end(serving, goal, 'abort', f'settle: must be finite and >= 0 s (0 = {DEFAULT_SETTLE:g} s), '
                                           f'got {settle}')
    settle = settle or DEFAULT_SETTLE
    if goal.take_over is not None:  # a new goal during a motion: it takes over (preemption)
        return (yield from take_over(serving, goal, move, settle, feedback, canceled))
    return (yield from start(serving, goal, move, settle, feedback, canceled, t0))
