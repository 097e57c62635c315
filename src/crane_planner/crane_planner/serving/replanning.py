"""A motion planned from the state a running motion will be in: a goal's handover, a stop, a settle.

One at a time (``Serving.handing_over``; a rehearsal beside them), once
the running motion's origin is known, with ``handover.plan_handover``'s
timing; the swing at the handover predicted from the newest joint_states.
Pure Python, no ROS import.
"""
from __future__ import annotations

import contextlib

from crane_msgs_py.messages.names import HOIST_JOINT

from ..planning.continuation import problem_start
from ..planning.plan import Plan
from . import transitions
from .context import Serving
from .handover import plan_handover
from .moves import CheckedMove, MoveError, axis_samples, keep_out_clearance
from .preview import knots_of
from .transitions import Running, Trajectory


def plan_from_running(serving: Serving, running: Running, lead: float, make_plan, swing: bool = True,
                      rehearse: bool = False, kind=None):
    """``handover.plan_handover`` of ``running`` once its origin is known, one at a time (``rehearse``:
    beside them); the swing there predicted from the newest joint_states (``swing``: not needed by a
    shaper's change). ``kind``: what ``planning_times`` keeps its planning time under, and may lengthen
    its first lead by; None for a shaper's change, whose short lead is on purpose."""
    if not serving.view.origin(running):
        raise MoveError('goal', 'the running motion has not started on the streamer yet (no stream_state '
                                'of it): a goal during it is accepted once it streams')
    params = serving.config().params

    def state_at(handover_ns):
        return transitions.handover_state(running, handover_ns, serving.view.measured, params, swing)

    with contextlib.nullcontext() if rehearse else serving.handing_over:
        return plan_handover(serving.clock, running, lead, make_plan, state_at, rehearse, serving.timer,
                             serving.log.warn, times=None if kind is None else serving.planning_times, kind=kind)


def trajectory_from(serving: Serving, plan: Plan, state, joints, handover_ns: int) -> Trajectory:
    """``plan``'s trajectory from ``state`` (the running motion's at ``handover_ns``)."""
    starts = transitions.joint_starts(plan, state)
    return Trajectory(tuple(joints), axis_samples(plan, knots_of(plan, serving.config())), tuple(starts),
                      handover_ns)


def retargeting(serving: Serving, running: Running, checked: CheckedMove):
    """The ``make_plan`` of a handover of ``running`` to ``checked``'s goal in its duration
    (``transitions.retarget``), kept out of the keep-out boxes from the state at the handover."""
    config = serving.config()

    def make(handover_ns, state):
        plan = transitions.retarget(serving.planner.variational, running, handover_ns, state, checked.method,
                                    checked.goals, checked.duration, config.params, config.options)
        if config.keep_out:  # from the state at the handover: its swing, the servo's lag
            start, model = problem_start(state, config.params)
            origin = {name: s.position for name, s in state.axes.items() if name != HOIST_JOINT}
            keep_out_clearance(plan, origin, model, config.keep_out, start)
        return plan
    return make
