"""A move checked and planned: a preview (``~/plan_move``), and a goal's plan from rest.

``plan_move`` checks a ``moves.Move`` against the configuration and where
the streamer holds the axes, plans it (keeping out of the keep-out boxes)
and samples its trajectory; a goal's (``execute``) is also refused for what
the streamer would refuse (``check_executable``), after planning, so that a
preview and a goal of the same bad move give the same reason. On a shared
runway, both are then placed among the other cranes (``runway_step``): started
later by the delay that keeps them clear, or refused naming the crane. Pure
Python, no ROS import.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

from crane_msgs_py.messages.names import CART_JOINT, STREAM_STATE_TOPIC

from ..planning.mass_path import DEFAULT_SETTLE
from ..planning.plan import Plan, time_grid
from ..streaming.knots import knot_times
from .config import Config
from .context import Serving
from .crane_view import DISCOVERY_WAIT
from .moves import CheckedMove, Move, MoveError, axis_samples, check_move, check_rests_keep_out, plan_keeping_out
from .runway_step import Placement
from .transitions import Trajectory


@dataclass(frozen=True)
class Planned:
    """A move planned: checked, its plan, its trajectory, its status values (/diagnostics), how long
    its planning took (s; for a handover from the goal's arrival), its place on a shared runway (None: none)
    and the ``continuation.MotionState`` it starts from (None: from rest)."""

    checked: CheckedMove
    plan: Plan
    trajectory: Trajectory
    values: dict
    planning_s: float = 0.0
    placement: Placement | None = None
    state: Any = None


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


def plan_move(serving: Serving, move: Move, service: str, execute: bool = False,
              settle: float = DEFAULT_SETTLE, place: bool = True) -> Planned:
    """The move checked and planned, and (``place``) placed on a shared runway (observed ``settle`` s after it:
    its occupancy's settle window); MoveError/ValueError says why not (its ``values``: the status)."""
    config, t0 = serving.config(), serving.timer()
    values = {'service': service, 'method': move.method or config.method,
              'start': move.start[0] if move.start else math.nan,
              'goal': move.goal[0] if move.goal else math.nan, 'duration': move.duration}
    # a goal waits a moment for a streamer not heard yet (one just restarted is being discovered)
    heard = serving.view.wait_heard(DISCOVERY_WAIT) if execute else serving.view.heard()
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
        plan = plan_keeping_out(serving.planner, checked, config.bounds, config.params, config.options,
                                config.keep_out)
        clearance = plan.info.get('min_clearance', math.inf)
        if execute:  # after planning: a preview and a goal of the same bad move give the same reason
            check_executable(checked, hold, heard is not None and heard.operator, serving.view.foreign_motion())
        placement = serving.runway.place(checked, plan, settle) if place else None  # (None: no runway)
    except ValueError as exc:
        exc.values = values
        raise
    values['duration'] = plan.duration
    trajectory = Trajectory(checked.joints, axis_samples(plan, knots_of(plan, config)), checked.starts,
                            checked.start_ns)
    if math.isfinite(clearance):
        values['min_clearance'] = clearance
    planned = Planned(checked, plan, trajectory, values, serving.timer() - t0)
    return planned if placement is None else placed(planned, placement)


def placed(planned: Planned, placement: Placement) -> Planned:
    """``planned`` started where its runway ``placement`` says (its checked move's start and its trajectory's
    stamp), the delay and the crane it waited for in its status values and its plan's ``info`` (PlanInfo)."""
    start = placement.start_ns
    delay = {'runway_delay': placement.runway_delay, 'runway_waited_for': placement.waited_for}
    planned.plan.info.update(delay)
    return dataclasses.replace(planned, checked=dataclasses.replace(planned.checked, start_ns=start),
                               trajectory=dataclasses.replace(planned.trajectory, stamp_ns=start),
                               values={**planned.values, **delay}, placement=placement)


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
