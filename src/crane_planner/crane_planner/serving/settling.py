"""Motion brought to rest without swing: a goal's motion stopped on a cancel, and a settle (``~/settle``).

A stop (``stop_motion``) is planned from the state the goal's motion will
be in ``STOP_LEAD`` s from now (``stops.plan_stop``), sent, and followed by
the goal from then on; a settle (``settle``) damps the swing measured now
by a short motion ending where the cart is held. Both are written on the
axes' timeline as the streamer streams them. Pure Python, no ROS import.
"""
from __future__ import annotations

from dataclasses import dataclass

from crane_msgs_py.messages.names import CART_JOINT, STREAM_STATE_TOPIC

from ..planning.mass_path import DEFAULT_SETTLE
from ..planning.plan import Plan
from ..streaming.reference_stream import position_text
from . import transitions
from .context import Serving
from .execution import Execution
from .goals import Goal
from .handover import Verdict, taken
from .moves import MoveError
from .replanning import plan_from_running, trajectory_from
from .runway_step import publish_motion
from .stops import STOP_LEAD, plan_stop
from .transitions import Running


@dataclass(frozen=True)
class Settled:
    """A settle sent: what it says, the swing's amplitude it damps (m), its plan and when its motion ends
    (ROS time, ns)."""

    message: str
    swing: float
    plan: Plan
    end_ns: int = 0


def stop_motion(serving: Serving, goal: Goal, settle: float) -> str:
    """Stop ``goal``'s motion without swing (a cancel during it): send the stop, follow it from now on.
    Returns where the axes stop (m, as text); ValueError says why no stop could be planned."""
    config, running = serving.config(), goal.running

    def make(handover_ns, state):
        return plan_stop(serving.planner.variational, running, handover_ns, config.params, config.options,
                         state=state).plan

    done = plan_from_running(serving, running, STOP_LEAD, make, kind=('stop', running.method, running.joints))
    if done is None:  # the motion ended meanwhile: it is at rest already
        return where(interp.position[-1] for interp in running.interps)
    plan, handover, state = done.plan, done.handover_ns, done.state
    trajectory = trajectory_from(serving, plan, state, running.joints, handover)
    stop = trajectory.running(handover, plan)
    execution = Execution(plan.duration, settle, handover, config.params.L1, config.params.L2,
                          stream_timeout=config.stream_timeout)
    serving.timeline.send(stop, together=lambda: serving.goals.stopping(goal, stop, execution) or True)
    serving.publish(trajectory)
    publish_motion(serving, goal, plan, state, handover, settle)  # (on a runway)
    # a stop ending after the motion would have (one near its end) is streamed with its change delayed to
    # the tick at or after its stamp: what a next handover must continue
    if taken(goal.execution, handover, config.stream_timeout, serving.sleep, serving.timer) is Verdict.TAKEN:
        streamed = transitions.taken_over(running, stop, goal.execution.motion_start_ns)
        serving.timeline.replace(stop, streamed, together=lambda: serving.goals.own(goal, streamed))
    at = where(interp.position[-1] for interp in stop.interps)
    serving.log.info(f'execute_move: canceled during its motion: stopping at {at} m in '
                     f'{plan.duration:.4g} s ({plan.method})')
    return at


def settle(serving: Serving) -> Settled:
    """``~/settle``: damp the swing measured now by a short motion ending where the cart is held, sent;
    MoveError says why not."""
    config = serving.config()
    if serving.view.in_motion() is not None:
        raise MoveError('settle', 'a motion is streaming: settle once it has ended')
    hold = serving.view.hold()
    if hold is None:
        raise MoveError('settle', f'no streamer heard on {STREAM_STATE_TOPIC}: nothing would stream the '
                                  'motion')
    measured, now = serving.view.measured, serving.clock()
    if measured is None or now - measured.stamp_ns > transitions.MEASUREMENT_AGE * 1e9:
        raise MoveError('settle', f'no joint_states within {transitions.MEASUREMENT_AGE:g} s: the swing to '
                                  'damp is not measured')
    holding = Running.held(hold, config.joints, now)

    def make(handover_ns, state):
        return transitions.settle(serving.planner.variational, state, config.params, config.options,
                                  config.settle_method)

    done = plan_from_running(serving, holding, config.handover_lead, make,
                             kind=('settle', config.settle_method, holding.joints))
    trajectory = trajectory_from(serving, done.plan, done.state, holding.joints, done.handover_ns)
    running = trajectory.running(done.handover_ns, done.plan)
    serving.timeline.send(running)
    serving.publish(trajectory)
    publish_motion(serving, object(), done.plan, done.state, done.handover_ns, DEFAULT_SETTLE)  # (on a runway)
    swing = transitions.swing_of(done.state, config.params)
    return Settled(f'settling a swing of about {1e3 * swing:.1f} mm: a {done.plan.duration:.3g} s '
                   f'{done.plan.method} motion ending where the cart is held ({hold[CART_JOINT]:.6g} m)', swing,
                   done.plan, running.end_ns)


def where(positions) -> str:
    """Where the axes stop (m) for messages: one joint's position, or several in parentheses."""
    values = tuple(float(x) for x in positions)
    return position_text(values[0] if len(values) == 1 else values)
