"""A goal sent while the load swings: planned from the measured swing, never as if the load hung still.

The crane is near enough linear that a motion planned from rest carries the swing it starts with to its end:
a goal sent after a fault's braking, a push or a plan of the wrong model would end with that swing and call
it done. So a goal sent while the load swings more than ``SWINGING`` of ``residual_tolerance`` (the swing
measured by the newest joint_states, predicted to now: ``swing_now``) is not planned from rest:

- NVF and RVF plan from the swing predicted to the goal's start, as a goal during a motion does
  (``transitions.retarget`` from the held axes, ``replanning.plan_from_running``'s timing): their motion
  damps it on its way. Such a goal starts ``handover_lead`` from now (or at its ``start_time``), goes
  straight to its goal (no ``via``) and needs a duration (the fastest plan is from rest).
- A shaper cannot damp a swing it did not cause: its goal first damps it by a settle motion
  (``settling.settle`` with ``settle_method``) that ends where the axes are held, then is planned from
  rest once the streamer holds after it. So does an NVF/RVF goal whose plan from the swing the solver did
  not make within its budget (a fast move from a large swing on a busy host): nothing accepted is lost.

``start`` dispatches a goal that starts with the crane held. Pure Python, no ROS import.
"""
from __future__ import annotations

import math

from crane_msgs_py.crane.errors import PlanError
from crane_msgs_py.messages.names import CART_JOINT

from ..planning.methods import Family, family_of
from . import transitions
from .context import Serving
from .crane_view import DISCOVERY_WAIT, HOLDING
from .execution import Execution
from .following import FEEDBACK_PERIOD, end, follow, unsent
from .goals import Goal, GoalState
from .handover import send_at
from .moves import Move, MoveError, check_move, check_rests_keep_out
from .preview import Planned, check_executable
from .replanning import plan_from_running, retargeting, trajectory_from
from .runner import Steps
from .runway_step import publish_motion
from .settling import settle as damp
from .starting import from_rest
from .transitions import Running

#: A goal is planned from the swing once it exceeds this share of residual_tolerance: a swing carried to the
#: goal's end beside the goal's own residual must leave room under the tolerance.
SWINGING = 0.5


def swing_now(serving: Serving) -> float | None:
    """The load's swing (m, the first mode's amplitude: ``transitions.swing_of``) with the axes held, from
    the newest joint_states if one is recent (``transitions.MEASUREMENT_AGE``) and the streamer is heard
    (waiting a moment for one just restarted, as a goal from rest does); None if not measured."""
    heard = serving.view.wait_heard(DISCOVERY_WAIT)
    config, hold, measured = serving.config(), None if heard is None else heard.hold, serving.view.measured
    now = serving.clock()
    if hold is None or measured is None or now - measured.stamp_ns > transitions.MEASUREMENT_AGE * 1e9:
        return None
    now = max(now, measured.stamp_ns)
    holding = Running.held(hold, config.joints, now)
    return transitions.swing_of(transitions.handover_state(holding, now, measured, config.params), config.params)


def start(serving: Serving, goal: Goal, move: Move, settle: float, feedback, canceled, t0: float,
          damped: bool = False) -> Steps:
    """A goal with the crane held: from rest (``starting.from_rest``), or, the load swinging, from its swing
    (variational) or after a settle damped it (a shaper; ``damped``: that was done, plan from rest now)."""
    swing = None if damped else swing_now(serving)
    if swing is None or swing <= SWINGING * serving.config().residual_tolerance:
        return (yield from from_rest(serving, goal, move, settle, feedback, canceled, t0))
    if family_of(move.method or serving.config().method) is Family.SHAPER:
        return (yield from damped_first(serving, goal, move, settle, feedback, canceled, t0, swing))
    return (yield from from_swing(serving, goal, move, settle, feedback, canceled, t0, swing))


def from_swing(serving: Serving, goal: Goal, move: Move, settle: float, feedback, canceled, t0: float,
               swing: float) -> Steps:
    """An NVF/RVF goal planned from the swing predicted to its start, held until ``publish_lead`` before it,
    sent, followed. A start further ahead than the swing is predicted (``transitions.HANDOVER_PREDICTION``)
    is waited for until it is within that."""
    config = serving.config()
    values = {'service': 'execute_move', 'method': move.method or config.method,
              'goal': move.goal[0] if move.goal else math.nan, 'duration': move.duration,
              'start_swing': swing}
    while (move.start_ns - serving.clock() > transitions.HANDOVER_PREDICTION * 1e9
           and goal.state is GoalState.ARRIVED and not canceled()):
        yield FEEDBACK_PERIOD
    if goal.state is not GoalState.ARRIVED or canceled():
        return unsent(serving, goal, None)
    try:
        planned = _planned(serving, move, swing, values)
    except MoveError as exc:  # the move refused (a field of it, a keep-out box, the timing)
        serving.report({**values, **getattr(exc, 'values', {})}, None, t0, t0, error=str(exc))
        return end(serving, goal, 'abort', str(exc))
    except PlanError as exc:  # the solver's: no plan within its budget from this state
        serving.log.warn(f'execute_move: the load swings {1e3 * swing:.1f} mm and no plan from the swing was made '
                         f'({exc}): damping it first, then planning from rest')
        return (yield from damped_first(serving, goal, move, settle, feedback, canceled, t0, swing))
    except ValueError as exc:
        serving.report({**values, **getattr(exc, 'values', {})}, None, t0, t0, error=str(exc))
        return end(serving, goal, 'abort', str(exc))
    serving.report(planned.values, planned, t0, serving.timer())
    plan, checked = planned.plan, planned.checked
    feedback(progress=0.0, time_remaining=plan.duration, swing=swing)
    serving.goals.hold(goal)
    due = send_at(checked.start_ns, config.publish_lead)  # a cancel before then streams nothing
    while serving.clock() < due and goal.state is GoalState.HELD and not canceled():
        yield min(FEEDBACK_PERIOD, max(0.0, (due - serving.clock()) * 1e-9))
    execution = Execution(plan.duration, settle, checked.start_ns, config.params.L1, config.params.L2,
                          stream_timeout=config.stream_timeout)
    running = planned.trajectory.running(checked.start_ns, plan)
    if not serving.timeline.send(running, together=lambda: serving.goals.send(goal, execution, running, canceled)):
        return unsent(serving, goal, planned)
    serving.publish(planned.trajectory)
    publish_motion(serving, goal, plan, planned.state, checked.start_ns, settle)  # (on a runway)
    cart = checked.axes[CART_JOINT]
    what = (f'{checked.method}: {cart.start:g} -> {cart.goal:g} m in {plan.duration:.4g} s, from a swing of '
            f'{1e3 * swing:.1f} mm')
    serving.log.info(f'execute_move: the load swings {1e3 * swing:.1f} mm: {what}')
    return (yield from follow(serving, goal, planned, feedback, canceled, settle, what))


def _planned(serving: Serving, move: Move, swing: float, values: dict) -> Planned:
    """``move`` planned from the swing at its start: its ``start_time`` if that is more than ``handover_lead``
    ahead, else ``handover_lead`` from now (planned again further ahead if planning took longer); MoveError
    says why it cannot be."""
    config, heard = serving.config(), serving.view.heard()
    hold = None if heard is None else heard.hold
    swinging = (f'the load swings {1e3 * swing:.1f} mm (over {SWINGING:g} of residual_tolerance '
                f'{1e3 * config.residual_tolerance:g} mm)')
    checked = check_move(move, config.bounds, hold, config.params.L1)
    check_executable(checked, hold, heard is not None and heard.operator, serving.view.foreign_motion())
    if checked.vias:
        raise MoveError('via', f'{swinging}: a goal through via points is planned from a load at rest: leave via '
                               'empty, or call ~/settle first')
    if checked.duration is None:
        raise MoveError('duration', f'{swinging}: the fastest plan is planned from a load at rest: give a '
                                    'duration, or call ~/settle first')
    check_rests_keep_out(checked, config.params, config.keep_out)
    now = serving.clock()
    holding = Running.held(hold, checked.joints, now)
    make = retargeting(serving, holding, checked)
    if checked.start_ns > now + round(config.handover_lead * 1e9):  # at its start_time exactly
        with serving.handing_over:
            state = transitions.handover_state(holding, checked.start_ns, serving.view.measured, config.params)
            plan, handover = make(checked.start_ns, state), checked.start_ns
    else:
        done = plan_from_running(serving, holding, config.handover_lead, make,
                                 kind=('goal', checked.method, holding.joints))
        plan, handover, state = done.plan, done.handover_ns, done.state
    checked = checked.starting({name: s.position for name, s in state.axes.items()}, handover)
    cart = checked.axes[CART_JOINT]
    values = {**values, 'method': checked.method, 'start': cart.start, 'goal': cart.goal,
              'duration': plan.duration, 'displacement': checked.displacement}
    return Planned(checked, plan, trajectory_from(serving, plan, state, holding.joints, handover), values,
                   state=state)


def damped_first(serving: Serving, goal: Goal, move: Move, settle: float, feedback, canceled, t0: float,
                 swing: float) -> Steps:
    """A goal while the load swings that cannot plan from the swing (a shaper; an NVF/RVF plan the solver did not
    make in time from that state): a settle motion damps the swing, then it is planned from rest."""
    method = move.method or serving.config().method
    try:
        settled = damp(serving)
    except ValueError as exc:
        return end(serving, goal, 'abort', f'the load swings {1e3 * swing:.1f} mm, which {method} cannot damp, '
                                           f'and damping it first failed: {exc}')
    serving.log.info(f'execute_move: the load swings {1e3 * swing:.1f} mm, which {method} cannot damp: '
                     f'{settled.message}, then the goal')
    feedback(progress=0.0, time_remaining=settled.plan.duration, swing=swing)
    why = yield from until_held(serving, goal, settled.end_ns, canceled, 'the settle before it')
    if why is not None:
        return why
    return (yield from start(serving, goal, move, settle, feedback, canceled, t0, damped=True))


def until_held(serving: Serving, goal: Goal, end_ns: int, canceled, what: str) -> Steps:
    """Steps until the streamer says it holds after ``end_ns`` (a motion ``what`` names has ended there): None,
    or the goal's ``Outcome`` if it was canceled or gave way meanwhile, or no stream_state came."""
    stream_timeout = serving.config().stream_timeout
    heard_t, last = serving.timer(), None
    while True:
        heard = serving.view.heard()
        if heard is not None and heard.state == HOLDING and heard.stamp_ns >= end_ns:
            return None
        if goal.state is GoalState.PREEMPTED:
            return unsent(serving, goal, None)
        if canceled():
            return end(serving, goal, 'cancel', 'canceled before its motion started: nothing was streamed')
        if heard is not None and heard.stamp_ns != last:
            heard_t, last = serving.timer(), heard.stamp_ns
        elif serving.timer() - heard_t >= stream_timeout:
            return end(serving, goal, 'abort', f'{what} ended, and no stream_state said the streamer holds after '
                                               f'it within {stream_timeout:g} s')
        yield 0.005
