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

- ``STOP``: the gap would fall under ``runway_min_distance``: stop now (the
  streamer's planned stop, swing-free), and refuse motions towards that crane
  until the gap is over the minimum again with this crane at rest;
- ``WARNING`` under ``WARNING_FACTOR`` times the minimum, ``INFO`` under
  ``INFO_FACTOR`` times: said on ``/diagnostics``, nothing done;
- ``LOST``: a crane within reach (its last gap under ``reach``) not heard for
  ``runway_timeout``: treated as ``STOP`` until it is heard again.

Levels as the anti-collision anchors use them (warning and stop radii around
the braking distance); pure Python, no ROS import, a few microseconds a tick.
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


def reach(girder: float, velocity: float, acceleration: float, masses_y, shape: Shape, deceleration: float,
          jerk: float) -> Reach:
    """The stopping envelope (see the module docstring) of a crane whose girder is at ``girder`` (m, y in
    ``runway``) moving at ``velocity`` (m/s) and ``acceleration`` (m/s^2) along y, its masses at ``masses_y``,
    stopped within ``deceleration`` (m/s^2) and ``jerk`` (m/s^3)."""
    d = stopping_distance(velocity, acceleration, deceleration, jerk) if (velocity or acceleration) else 0.0
    g = shape.girder_half_width
    low, high = girder - g, girder + g
    h = shape.load_half_size
    for y in masses_y:
        low, high = min(low, y - h), max(high, y + h)
    return Reach(low + min(d, 0.0), high + max(d, 0.0))


@dataclass
class Neighbour:
    """What the guard knows of another crane: its last envelope, when it was heard (ns, receipt on this
    crane's clock) and its level."""

    crane: str
    reach: Reach
    heard_ns: int
    level: Level = Level.CLEAR
    gap: float = math.inf


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

    def heard(self, crane: str, envelope: Reach, now_ns: int) -> None:
        """Another crane's state, received now."""
        known = self.neighbours.get(crane)
        if known is None:
            self.neighbours[crane] = Neighbour(crane, envelope, now_ns)
        else:
            known.reach, known.heard_ns = envelope, now_ns

    def check(self, mine: Reach, now_ns: int) -> Verdict:
        """This tick's verdict for this crane's envelope ``mine``."""
        worst, blocked = None, set()
        for n in self.neighbours.values():
            n.gap = mine.gap(n.reach)
            if now_ns - n.heard_ns > self.timeout_ns and n.gap < self.reach:
                n.level = Level.LOST
            elif n.gap < self.min_distance:
                n.level = Level.STOP
            elif n.gap < WARNING_FACTOR * self.min_distance:
                n.level = Level.WARNING
            elif n.gap < INFO_FACTOR * self.min_distance:
                n.level = Level.INFO
            else:
                n.level = Level.CLEAR
            if n.level >= Level.STOP:
                blocked.add(1.0 if n.reach.low + n.reach.high > mine.low + mine.high else -1.0)
            if worst is None or (n.level, -n.gap) > (worst.level, -worst.gap):
                worst = n
        if worst is None or worst.level is Level.CLEAR:
            return Verdict(Level.CLEAR, '', math.inf if worst is None else worst.gap, frozenset())
        return Verdict(worst.level, worst.crane, worst.gap, frozenset(blocked))


def within_reach(min_distance: float, max_velocity: float, timeout: float, deceleration: float,
                 jerk: float) -> float:
    """The gap (m) within which a neighbour gone silent stops this crane: the minimum distance and, for each of
    the two cranes, how far it may travel at ``max_velocity`` in ``timeout`` and then brake."""
    one = max_velocity * timeout + stopping_distance(max_velocity, 0.0, deceleration, jerk)
    return min_distance + 2.0 * one
