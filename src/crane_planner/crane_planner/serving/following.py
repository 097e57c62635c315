"""A goal's motion followed to its result: done, taken over by a newer goal, or stopped on a cancel.

``follow`` is a goal's last steps on the ``runner.GoalRunner``: each one
publishes the feedback of its ``execution.Execution`` (every ``FEEDBACK_PERIOD``) and
looks at the goal's state; a cancel during the motion stops it
(``settling.stop_motion``) and follows the stop. Its result is an
``Outcome``: success means the axes are at the goal and the load is quiet
(its residual at most ``residual_tolerance``); a load left swinging more
aborts it, the residual in its message. Pure Python, no ROS import.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from crane_msgs_py.messages.names import STILL_SWINGING

from .context import Serving
from .execution import CORRECTED, DONE, FAILED, MOVING, WAITING
from .goals import Goal, GoalState
from .preview import Planned
from .runner import Steps
from .settling import stop_motion

#: Settle window (s) of a goal that gives none (``settle`` 0).
DEFAULT_SETTLE = 2.0
#: Feedback period (s): 20 Hz, above the contract's 10 Hz.
FEEDBACK_PERIOD = 0.05


@dataclass(frozen=True)
class Outcome:
    """A goal's result: how it ends (``succeed``, ``abort``, ``cancel``), why, the residual swing (m), its
    plan (None if none was made), the handover warm-ups during its motion (count, s) and the largest correction
    the streamer's sway feedback added to its motion (m; 0: none)."""

    how: str
    message: str
    residual_swing: float = math.nan
    plan: Planned | None = None
    warmups: int = 0
    warmup_s: float = 0.0
    correction: float = 0.0

    @property
    def success(self) -> bool:
        return self.how == 'succeed'

    def status(self) -> dict:
        """Its values on /diagnostics."""
        return dict(outcome=self.how, residual_swing=self.residual_swing, error='' if self.success else self.message,
                    feedback_correction=self.correction,
                    handover_warmups=self.warmups,
                    handover_warmup_ms=1e3 * self.warmup_s / self.warmups if self.warmups else 0.0)


def end(serving: Serving, goal: Goal, how: str, message: str, planned: Planned | None = None,
        residual: float = math.nan) -> Outcome:
    """``goal`` ended as ``how`` says (its state ``ENDED``), with its outcome; on a runway its motion's
    claim released (a hold is published once the streamer holds)."""
    serving.goals.end(goal)
    serving.runway.release(goal)
    correction = goal.execution.correction if goal.execution is not None else 0.0
    return Outcome(how, message, residual, planned, goal.warmups, goal.warmup_s, correction)


def unsent(serving: Serving, goal: Goal, planned: Planned | None) -> Outcome:
    """The outcome of a goal of which nothing streamed: it gave way to a newer one, or was canceled."""
    if goal.state in (GoalState.PREEMPTED, GoalState.TAKEN_OVER):
        return end(serving, goal, 'abort', 'preempted by a newer goal before its motion started: nothing '
                                           'was streamed', planned)
    return end(serving, goal, 'cancel', 'canceled before its motion started: nothing was streamed', planned)


def follow(serving: Serving, goal: Goal, planned: Planned, feedback, canceled, settle: float, what: str) -> Steps:
    """Follow the goal's motion to its result: done, taken over by a newer goal, or stopped on a cancel."""
    serving.goals.follow(goal)
    stopped = None  # (where the stop ends, m) once a cancel has stopped the motion
    while True:
        execution = goal.execution
        phase = execution.phase(serving.clock())
        if goal.running is not None:  # a pending motion's origin, kept once this goal has ended too
            serving.view.origin(goal.running, wait=0.0)
        feedback(progress=execution.progress, time_remaining=execution.time_remaining, swing=execution.swing)
        if goal.state is GoalState.TAKEN_OVER:
            return end(serving, goal, 'abort', f'preempted by a newer goal after '
                                               f'{execution.progress * execution.duration:.3f} s of its motion '
                                               f'({what})', planned)
        if canceled() and stopped is None:
            if phase in (WAITING, MOVING) and goal.running is not None:
                try:
                    stopped = stop_motion(serving, goal, settle)
                except ValueError as exc:
                    return end(serving, goal, 'cancel', f'canceled, but no stop could be planned ({exc}): the '
                                                        'motion runs to its end', planned)
                continue
            return end(serving, goal, 'cancel', 'canceled after its motion had ended', planned, execution.residual)
        if phase in (DONE, FAILED):
            break
        yield FEEDBACK_PERIOD
    if phase == FAILED:
        serving.timeline.clear(goal.running)  # the streamer did not take it: nothing is in motion
        return end(serving, goal, 'abort', execution.failure, planned)
    residual = ('no joint_states: residual not measured' if math.isnan(execution.residual)
                else f'residual swing {1e3 * execution.residual:.3f} mm')
    if execution.correction > CORRECTED:  # the streamer's sway feedback corrected the motion
        residual += (f' once settled at the goal, the sway feedback having moved the axes up to '
                     f'{1e3 * execution.correction:.2f} mm off the plan')
    start = execution.window_start_ns
    cut = ('' if execution.window_end_ns == start + round(settle * 1e9) else
           f' (observed {(execution.window_end_ns - start) * 1e-9:.3g} s: the next motion started)')
    if stopped is not None:
        return end(serving, goal, 'cancel', f'canceled: stopped at {stopped} m in {execution.duration:.4g} s '
                                            f'without swing ({what}); {residual}{cut}', planned, execution.residual)
    tolerance = serving.config().residual_tolerance
    if execution.residual > tolerance:  # (NaN, not measured, is not over it: nothing says the load swings)
        return end(serving, goal, 'abort', f'{what}; {residual}, over residual_tolerance {1e3 * tolerance:g} mm: '
                                           f'{STILL_SWINGING}{cut}', planned, execution.residual)
    return end(serving, goal, 'succeed', f'{what}; {residual}{cut}', planned, execution.residual)
