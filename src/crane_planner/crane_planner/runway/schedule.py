"""Planning around the other cranes in time: the least delay of a goal that keeps its occupancy
``min_distance`` from every other crane's at every instant (``runway_policy: wait``), or the crane that
forbids it (``refuse``, or no delay helps).

First published, first served: the occupancies already published are fixed; the goal being planned moves
around them. A delay is tried in steps of ``DELAY_STEP`` from 0 up to when every other occupancy has ended and
a ``DELAY_STEP`` more: past that the others stand still, so a later start changes nothing. The distance is
checked at the samples of both occupancies (each held linear between its samples), with a margin added to the
distance required for what lies between (``required``). Pure numpy, no ROS import.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from .occupancy import Closest, Occupancy, closest

#: The resolution (s) of the delay a goal is given.
DELAY_STEP = 0.05


@dataclass(frozen=True)
class Scheduled:
    """A goal's place among the others: its ``delay`` (s, from the start it asked for; 0 if it conflicts with
    none), the crane it waits for ('' if none: the one still in its way a step sooner, which set the delay), and
    where it then comes closest to another (None: no other)."""

    delay: float
    waited_for: str
    closest: Closest | None


class Conflict(Exception):
    """No start keeps the goal ``min_distance`` from ``crane``: where it comes closest at the best start."""

    def __init__(self, crane: str, closest: Closest, message: str):
        super().__init__(message)
        self.crane, self.closest = crane, closest


def required(mine: Occupancy, other: Occupancy, min_distance: float) -> float:
    """The distance (m) the samples must keep for the paths to keep ``min_distance`` between them: the gaps
    along y are linear between the union of both crane's samples, so least at one, but each path lies up to an
    eighth of its largest bend off its straight lines (``Occupancy.largest_bend``), and two masses moving
    straight may pass closest between samples, closer by at most (s_a + s_b)^2 / (8 d), s their largest steps
    (``Occupancy.largest_step``), d the distance."""
    steps, bends = mine.largest_step() + other.largest_step(), mine.largest_bend() + other.largest_bend()
    return min_distance + bends / 8.0 + steps ** 2 / (8.0 * max(min_distance, 0.01))


def nearest(mine: Occupancy, others) -> Closest | None:
    """Where ``mine`` comes closest to any of ``others`` (None: no other)."""
    found = [closest(mine, other) for other in others]
    return min(found, key=lambda c: c.distance) if found else None


def conflicts(mine: Occupancy, others, min_distance: float, margin: float = 0.0) -> list[Closest]:
    """The others ``mine`` comes within ``min_distance`` and ``margin`` of (each where closest), nearest first."""
    return _conflicts(mine, _within_reach(mine, others, min_distance + margin))


def _extent(o: Occupancy) -> tuple[float, float]:
    """The span of y (m) ``o``'s girder strip and load discs cover at any time."""
    f, g, h = o.footprint, o.shape.girder_half_width, o.shape.load_half_size
    ys = f.masses[:, :, 1]
    return min(float(f.girder.min()) - g, float(ys.min()) - h), max(float(f.girder.max()) + g, float(ys.max()) + h)


def _within_reach(mine: Occupancy, others, min_distance: float) -> list[tuple[Occupancy, float]]:
    """(other, the distance the samples must keep from it) for each of ``others`` that ``mine`` could come
    within that distance of at some delay: every distance ``separation`` takes is at least the gap between
    the two cranes' spans of y over all time, which no delay changes."""
    lo, hi = _extent(mine)
    near = []
    for other in others:
        need = required(mine, other, min_distance)
        olo, ohi = _extent(other)
        if max(olo - hi, lo - ohi) < need:
            near.append((other, need))
    return near


def _conflicts(mine: Occupancy, near) -> list[Closest]:
    found = [c for other, need in near if (c := closest(mine, other)).distance < need]
    return sorted(found, key=lambda c: c.distance)


def _blocker(mine: Occupancy, near, first: str) -> str:
    """The crane of ``near`` (other, distance) ``mine`` comes within its distance of ('' if none): crane
    ``first`` looked at first (the one in the way at the delay before), the rest only while none is."""
    for other, need in sorted(near, key=lambda n: n[0].crane != first):
        if closest(mine, other).distance < need:
            return other.crane
    return ''


def schedule(mine: Occupancy, others, min_distance: float, policy: str = 'wait',
             max_delay: float | None = None, margin: float = 0.0) -> Scheduled:
    """``mine``'s least delay among ``others`` (see the module docstring) that keeps ``min_distance`` and
    ``margin`` (m: the planner's, ``guard.PLAN_MARGIN``) from each; ``policy`` 'refuse' tries no delay.
    Raises ``Conflict`` naming the crane in the way when no delay up to ``max_delay`` (s; default: until the
    others stand still) keeps them apart."""
    others = [o for o in others if o.crane != mine.crane]
    near = _within_reach(mine, others, min_distance + margin)
    found = _conflicts(mine, near)
    if not found:
        return Scheduled(0.0, '', nearest(mine, others))
    first = found[0]
    if policy == 'refuse':
        raise Conflict(first.crane, first, _message(first, min_distance, margin, 'refused'))
    last_end = max(o.end_ns for o in others)
    horizon = max(0.0, (last_end - mine.start_ns) * 1e-9) + DELAY_STEP
    if max_delay is not None:
        horizon = min(horizon, max_delay)
    steps = int(math.ceil(horizon / DELAY_STEP - 1e-9))
    blocker = first.crane
    for k in range(1, steps + 1):
        moved = mine.delayed(k * DELAY_STEP)
        still = _blocker(moved, near, blocker)
        if not still:  # (waited for: the crane in the way a step sooner, which set the delay)
            return Scheduled(k * DELAY_STEP, blocker, nearest(moved, others))
        blocker = still
    worst = _conflicts(moved, near)[0] if steps else first
    raise Conflict(worst.crane, worst, _message(worst, min_distance, margin, 'no start within '
                                                f'{horizon:.2f} s keeps it clear'))


def _message(c: Closest, min_distance: float, margin: float, why: str) -> str:
    kept = f'runway_min_distance {min_distance:g} m' + (f' and a margin of {margin:g} m' if margin else '')
    return f'the move would come within {max(c.distance, 0.0):.3f} m of crane {c.crane!r} ({kept}): {why}'
