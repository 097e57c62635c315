"""The runway guard: each tick, whether this crane's stopping envelope reaches another crane's, and what to do.

A crane's stopping envelope (``Reach``) is the span of y (along the runway)
that any part of it (girder, masses, the load's half-size) may cover before it
stands still if it started its planned stop now: its girder's strip and its
masses' y, widened towards its motion by the jerk-limited braking distance
(``crane_msgs_py.crane.braking``: the stop's deceleration and jerk) and on the
load's side by the load's offset from below the girder (the swing a
swing-free stop brings back in, no further). Every crane publishes its own on
``/runway/state``; the guard compares this crane's with each other's, the gap
between the two spans (the girders span the runway, so y is what separates
them):

- ``STOP``: the gap would fall under ``runway_min_distance`` (and
  ``STOP_MARGIN``): stop now (the
  streamer's planned stop, swing-free), and refuse motions towards that crane
  until the way is clear: the gap back over ``WARNING_FACTOR`` times the
  minimum (the level stays ``STOP`` until then; without that margin a crane
  stopped at the minimum would creep on towards the other, stop after stop);
- ``WARNING`` under ``WARNING_FACTOR`` times the minimum, ``INFO`` under
  ``INFO_FACTOR`` times: said on ``/diagnostics``, nothing done;
- ``LOST``: a crane within reach (its last gap under ``reach``) not heard for
  ``runway_timeout``: treated as ``STOP`` until it is heard again.

Two cranes that both follow what their planners published (``planned``: each
girder where its own occupancy puts it now) are kept apart by those plans,
which were placed against each other in time: one following another into the
space it leaves comes, by design, within its stopping envelope of where the
other still is. Between two such cranes the levels are judged on their
footprints now (the same spans without the travel), so the guard stops
neither while both keep to their plans and still stops a crane before it
touches the minimum; as soon as either deviates (an operator, a stop, a
fault, a goal its planner did not place) it says so and the envelopes count
again.

Levels as the anti-collision anchors use them (warning and stop radii around
the braking distance). ``envelope`` takes the stopping distance as its caller's
stop travels it (the streamer's operator mode knows it exactly, its planned
stop bounds it); ``reach`` is the envelope of the fastest jerk-limited stop.
Pure Python, no ROS import, a few microseconds a tick.
"""
from __future__ import annotations

import enum
import math
from dataclasses import dataclass

from crane_msgs_py.crane.braking import stopping_distance

from .occupancy import Shape

#: Gaps (in units of runway_min_distance) under which the guard says ``WARNING`` and ``INFO``.
WARNING_FACTOR = 2.0
INFO_FACTOR = 4.0
#: How far (m) the guard's live estimate of a crane's footprint may be off where it matters: the masses placed by
#: joint_states some tens of milliseconds old while a braking load swings ahead of its trolley (two cranes over
#: ROS, one following the other into the space it leaves: 7-9 mm at the closest). Planners keep their plans this
#: much further than runway_min_distance from the others' (``schedule.schedule``'s ``margin``), so that the guard
#: stops no crane that keeps to its plan.
PLAN_MARGIN = 0.02
#: How far (m) before the minimum distance the guard stops: what a swing-free stop leaves of swing on either
#: crane (a few tenths of a millimetre) and one tick's travel, so that a crane stopped for another rests at the
#: minimum or beyond, not a fraction of a millimetre within it.
STOP_MARGIN = 0.002


class Level(enum.IntEnum):
    """How close another crane's stopping envelope comes to this one's; ordered by severity."""

    CLEAR = 0
    INFO = 1
    WARNING = 2
    STOP = 3
    LOST = 4


@dataclass(frozen=True)
class Reach:
    """A crane's stopping envelope along y in ``runway`` (m): ``low <= y <= high``."""

    low: float
    high: float

    def gap(self, other: 'Reach') -> float:
        """The distance (m) between the two spans; negative when they overlap."""
        return max(other.low - self.high, self.low - other.high)


def envelope(girder: float, masses_y, shape: Shape, travel: float) -> Reach:
    """The stopping envelope (see the module docstring) of a crane whose girder is at ``girder`` (m, y in
    ``runway``) with its masses at ``masses_y``, whose stop travels ``travel`` (m, signed along y) before it
    stands still."""
    g, h = shape.girder_half_width, shape.load_half_size
    low, high = girder - g, girder + g
    for y in masses_y:
        if y - h < low:
            low = y - h
        if y + h > high:
            high = y + h
    return Reach(low + travel, high) if travel < 0.0 else Reach(low, high + travel)


def reach(girder: float, velocity: float, acceleration: float, masses_y, shape: Shape, deceleration: float,
          jerk: float) -> Reach:
    """The stopping envelope of a crane whose girder is at ``girder`` (m, y in ``runway``) moving at
    ``velocity`` (m/s) and ``acceleration`` (m/s^2) along y, its masses at ``masses_y``, stopped as fast as
    ``deceleration`` (m/s^2) and ``jerk`` (m/s^3) allow (``crane_msgs_py.crane.braking``)."""
    d = stopping_distance(velocity, acceleration, deceleration, jerk) if (velocity or acceleration) else 0.0
    return envelope(girder, masses_y, shape, d)


@dataclass
class Neighbour:
    """What the guard knows of another crane: its last envelope and footprint, whether it follows its
    published plan, when it was heard (ns, receipt on this crane's clock), its level and gap, and whether a stop
    for it still holds (``held``: until the way is clear)."""

    crane: str
    reach: Reach
    heard_ns: int
    footprint: Reach | None = None
    planned: bool = False
    level: Level = Level.CLEAR
    gap: float = math.inf
    held: bool = False


@dataclass(frozen=True)
class Verdict:
    """The guard's decision at one tick: the worst ``level`` over the neighbours, the crane it is for ('' if
    none), that crane's gap (m), and the directions (+1, -1 along y) motions are refused in."""

    level: Level
    crane: str
    gap: float
    blocked: frozenset

    def refuses(self, direction: float) -> bool:
        """Whether a motion along y with this sign is refused (towards a crane stopped for, or lost)."""
        return direction != 0.0 and math.copysign(1.0, direction) in self.blocked


#: The directions refused, by a bit mask (1: +y, 2: -y): made once, the guard hands them out every tick.
_BLOCKED = (frozenset(), frozenset({1.0}), frozenset({-1.0}), frozenset({1.0, -1.0}))


class Guard:
    """The guard (see the module docstring).

    Args:
        min_distance: ``runway_min_distance`` (m).
        timeout: ``runway_timeout`` (s).
        reach: the gap (m) within which a silent neighbour stops this crane (``within_reach``).
    """

    def __init__(self, min_distance: float, timeout: float, reach: float):
        self.min_distance, self.timeout_ns, self.reach = float(min_distance), round(timeout * 1e9), float(reach)
        self.neighbours: dict[str, Neighbour] = {}
        self._verdict = Verdict(Level.CLEAR, '', math.inf, _BLOCKED[0])

    def heard(self, crane: str, envelope: Reach, now_ns: int, footprint: Reach | None = None,
              planned: bool = False) -> None:
        """Another crane's state, received now: its envelope, its footprint and whether it follows its plan."""
        known = self.neighbours.get(crane)
        if known is None:
            self.neighbours[crane] = Neighbour(crane, envelope, now_ns, footprint, planned)
        else:
            known.reach, known.heard_ns, known.footprint, known.planned = envelope, now_ns, footprint, planned

    def check(self, mine: Reach, now_ns: int, footprint: Reach | None = None, planned: bool = False) -> Verdict:
        """This tick's verdict for this crane's envelope ``mine`` (and ``footprint``, with ``planned``: it follows
        its published plan); the last one again if nothing changed."""
        worst, blocked = None, 0
        low, high, middle = mine.low, mine.high, mine.low + mine.high
        timeout = self.timeout_ns
        for n in self.neighbours.values():
            other = n.reach
            gap = max(other.low - high, low - other.high)
            if now_ns - n.heard_ns > timeout and gap < self.reach:
                n.gap, level = gap, Level.LOST
            else:
                if planned and n.planned and footprint is not None and n.footprint is not None:
                    gap = max(n.footprint.low - footprint.high, footprint.low - n.footprint.high)
                n.gap = gap
                level = self._level(n, gap)
            n.level = level
            if level >= Level.STOP:
                blocked |= 1 if other.low + other.high > middle else 2
            if worst is None or level > worst.level or (level == worst.level and n.gap < worst.gap):
                worst = n
        return self._decided(worst, blocked)

    def _level(self, n: Neighbour, gap: float) -> Level:
        stop = self.min_distance
        if gap < stop + STOP_MARGIN or (n.held and gap < WARNING_FACTOR * stop):
            n.held = True
            return Level.STOP
        n.held = False
        return Level.WARNING if gap < WARNING_FACTOR * stop else Level.INFO if gap < INFO_FACTOR * stop else Level.CLEAR

    def _decided(self, worst: Neighbour | None, blocked: int) -> Verdict:
        last = self._verdict
        if worst is None or worst.level is Level.CLEAR:
            gap = math.inf if worst is None else worst.gap
            if last.level is Level.CLEAR and last.gap == gap:
                return last
            verdict = Verdict(Level.CLEAR, '', gap, _BLOCKED[0])
        else:
            verdict = Verdict(worst.level, worst.crane, worst.gap, _BLOCKED[blocked])
        self._verdict = verdict
        return verdict


def within_reach(min_distance: float, max_velocity: float, timeout: float, deceleration: float,
                 jerk: float, lag: float = 0.0) -> float:
    """The gap (m) within which a neighbour gone silent stops this crane: the minimum distance and, for each of
    the two cranes, how far it may travel at ``max_velocity`` in ``timeout`` and then stop: ``lag`` (s) at that
    velocity before braking (a shaper's delay, a stop's lead) and the braking within ``deceleration`` and
    ``jerk``."""
    one = max_velocity * (timeout + lag) + stopping_distance(max_velocity, 0.0, deceleration, jerk)
    return min_distance + 2.0 * one
