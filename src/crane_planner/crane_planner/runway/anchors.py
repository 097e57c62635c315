"""The anchors' rule on the same moves: keeping a fixed, speed-dependent distance instead of planning around the
others' occupancies (the baseline ``crane-plan runway`` and the runway benchmark compare with).

Today's anti-collision products stop a crane when another comes within its stop radius: the minimum distance
plus its braking distance at its current speed (they grow with speed to cover it). Offline, on the moves
``together.plan_together`` planned (the same plans, occupancies and order of publication), that rule reads:
a move starts when asked (or when its crane's previous motion ends) unless, at some instant of its occupancy,
it would come closer to another crane than ``min_distance`` plus both cranes' braking distances along the
runway from their speeds and accelerations then (``crane_msgs_py.crane.braking``: each crane braking as hard
as its move accelerates, and no softer than ``deceleration`` and ``jerk``); then it waits until the other
has finished the motion it is making then (or, standing then, its next one) and is checked again. Not
knowing where the other will be, it cannot start sooner. A crane that stands for good (no motion of its own
after that instant) is asked only the min distance, as if the moving one crept the last of its way at no
cost (generous to the rule); one in the way even so refuses the move. The distance is
``occupancy.separation``, swing included, as generous to the rule as to the planners. Pure Python, no ROS
import.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from crane_msgs_py.crane.braking import stopping_distance

from .occupancy import Occupancy, separation
from .together import Together, extended, seconds_ns, stamps_of, total_time

#: The braking of a bridge by default (the streamer's ``fault_deceleration`` m/s^2 and ``fault_jerk`` m/s^3).
DECELERATION, JERK = 0.5, 5.0


@dataclass(frozen=True)
class Timed:
    """A move started by the rule: its ``start`` (s), or ``refused`` naming the crane in its way."""

    index: int
    start: float
    end: float
    refused: str = ''


@dataclass(frozen=True)
class AnchorsRule:
    """The moves ``together`` placed (not refused there), started by the anchors' rule, in order of
    publication, and the time (s) from the first start asked for to the end of the last motion."""

    timed: list
    total: float


@dataclass(frozen=True)
class _Motion:
    """One crane's move as the rule started it: its span (ns) and its bridge's braking distance (m) at its
    occupancy's samples ``t`` (s from its start)."""

    start_ns: int
    end_ns: int
    t: np.ndarray
    braking: np.ndarray

    def at(self, stamps_ns: np.ndarray) -> np.ndarray:
        """The braking distance (m) at ROS times ``stamps_ns``: 0 outside the motion."""
        inside = (stamps_ns >= self.start_ns) & (stamps_ns <= self.end_ns)
        return np.where(inside, np.interp((stamps_ns - self.start_ns) * 1e-9, self.t, self.braking), 0.0)


def braking_distances(plan, t: np.ndarray, deceleration: float, jerk: float) -> np.ndarray:
    """The distance (m) the bridge of ``plan`` needs to stop from its speed and acceleration at ``t`` (s; 0
    after the motion), braking within the larger of ``deceleration`` and the plan's own peak acceleration, and
    of ``jerk`` and its own peak jerk: what a drive that knows its state and its limits stops in."""
    out = np.zeros(len(t))
    if 'bridge' not in getattr(plan, 'axes', {}):
        return out
    _, peak_a, peak_j = plan.axes['bridge'].peaks()
    d, j = max(deceleration, peak_a), max(jerk, peak_j)
    moving = t < plan.duration
    s = plan.evaluate_axis('bridge', t[moving])
    out[moving] = [abs(stopping_distance(v, a, d, j)) for v, a in zip(s.velocity, s.acceleration)]
    return out


def anchors_rule(together: Together, deceleration: float = DECELERATION, jerk: float = JERK) -> AnchorsRule:
    """The anchors' rule (see the module docstring) on ``together``'s moves."""
    scenario = together.scenario
    moved = together.moved
    braking = {p.index: braking_distances(p.plan, p.occupancy.t, deceleration, jerk) for p in moved}
    timelines = {c.name: Occupancy(c.name, -1, 0, np.zeros(1), c.at_rest(c.start), c.shape)
                 for c in scenario.cranes}
    motions: dict[str, list[_Motion]] = {c.name: [] for c in scenario.cranes}
    ready: dict[str, float] = {}
    timed = []
    for p in moved:
        crane, duration = p.move.crane, p.move.duration
        start = max(p.move.start, ready.get(crane, -math.inf))
        refused = ''
        while True:
            mine = p.occupancy.delayed(start - p.start)
            me = _Motion(mine.start_ns, mine.start_ns + seconds_ns(duration), mine.t, braking[p.index])
            wait = _first_wait(mine, me, timelines, motions, scenario.min_distance)
            if wait is None:
                break
            until, other = wait
            if until is None or until <= start:
                refused = other
                break
            start = until
        if refused:
            timed.append(Timed(p.index, start, start + duration, refused))
            continue
        timelines[crane] = extended(timelines[crane], mine)
        motions[crane].append(me)
        ready[crane] = start + duration
        timed.append(Timed(p.index, start, start + duration))
    started = [(scenario.moves[m.index], m.start) for m in timed if not m.refused]
    return AnchorsRule(timed, total_time(scenario, started))


def _first_wait(mine: Occupancy, me: _Motion, timelines: dict, motions: dict, min_distance: float):
    """None if ``mine`` keeps the rule's distance from every other crane; else (when it may start instead (s),
    None if never; the crane in its way)."""
    for name, other in timelines.items():
        if name == mine.crane:
            continue
        end = max(mine.end_ns, other.end_ns)
        stamps = np.concatenate((stamps_of(mine), stamps_of(other), [end]))
        stamps = np.unique(stamps[(stamps >= mine.start_ns) & (stamps <= end)])
        theirs = sum((m.at(stamps) for m in motions[name]), np.zeros(len(stamps)))
        last = max((m.end_ns for m in motions[name]), default=0)
        need = min_distance + np.where(stamps > last, 0.0, me.at(stamps)) + theirs
        bad = np.flatnonzero(separation(mine.at(stamps), mine.shape, other.at(stamps), other.shape) < need)
        if len(bad) == 0:
            continue
        at = stamps[bad[0]]
        finishing = [m.end_ns for m in motions[name] if m.end_ns > at]
        return (min(finishing) * 1e-9 if finishing else None), name
    return None
