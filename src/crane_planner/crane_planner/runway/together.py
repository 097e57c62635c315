"""Several cranes' moves on one runway planned together offline, as their planners would serve them: first
published, first served.

A ``Scenario`` names the cranes (where each one's ``crane_base`` lies in ``runway``, where its cart and
bridge start, its model and shape) and the moves (crane, method, goal per travel axis, duration, the start
asked for). ``plan_together`` takes the moves in order of their asked start (ties by crane name, then by
order in the scenario), plans each from where its crane stands then (a move asked before its crane's
previous motion ends starts when it ends), predicts its occupancy (``prediction.plan_occupancy``) and
schedules it around the other cranes' occupancies so far (``schedule.schedule``: each crane's timeline,
standing where it starts until its first move, standing where a move ends until its next); a move no delay
keeps clear (or any conflict under ``policy`` 'refuse') is refused, naming the crane, and its crane stays.

What the moves then take is compared with each crane alone on the runway (``alone``: the same moves, none
delayed). Pure Python, no ROS import.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from crane_msgs_py.crane.params import CraneParams

from ..planning.plan import Plan
from .guard import PLAN_MARGIN
from .occupancy import Closest, Footprint, Occupancy, Shape, closest
from .prediction import plan_occupancy
from .schedule import Conflict, schedule

#: The travel axes a move may name (the hoist is not planned on a shared runway offline).
AXES = ('cart', 'bridge')

#: ``make_plan(method, cart displacement, bridge displacement or None, duration, params) -> Plan``.
MakePlan = Callable[[str, float, float | None, float, CraneParams], Plan]


@dataclass(frozen=True)
class Crane:
    """One crane on the runway: ``offset`` (x, y) of its ``crane_base`` in ``runway`` (m), ``start`` where its
    cart and bridge stand at first (m, in ``crane_base``, by axis), its planning model and its shape."""

    name: str
    offset: tuple[float, float] = (0.0, 0.0)
    start: dict = field(default_factory=lambda: {'cart': 0.0, 'bridge': 0.0})
    params: CraneParams = CraneParams()
    shape: Shape = Shape()

    def at_rest(self, position: dict) -> Footprint:
        """Its footprint at rest with its axes at ``position`` (by axis, ``crane_base``), in ``runway``."""
        return Footprint.at_rest(self.offset[1] + position['bridge'], self.offset[0] + position['cart'])


@dataclass(frozen=True)
class Move:
    """A move of ``crane`` by ``method`` to ``goal`` (m by axis, ``crane_base``; an axis not named stays) in
    ``duration`` s, asked to start at ``start`` s."""

    crane: str
    method: str
    goal: dict
    duration: float
    start: float = 0.0

    def reached(self, origin: dict) -> dict:
        """Where its crane's axes stand once it is made from ``origin`` (m, by axis)."""
        return {axis: self.goal.get(axis, origin[axis]) for axis in AXES}


@dataclass(frozen=True)
class Scenario:
    """Cranes and their moves, ``min_distance`` (m, ``runway_min_distance``) and ``policy`` ('wait' or
    'refuse', ``runway_policy``)."""

    cranes: tuple
    moves: tuple
    min_distance: float = 0.2
    policy: str = 'wait'

    def crane(self, name: str) -> Crane:
        return next(c for c in self.cranes if c.name == name)

    def order(self) -> list[int]:
        """The moves' indices in order of publication: asked start, then crane name, then scenario order."""
        return sorted(range(len(self.moves)), key=lambda i: (self.moves[i].start, self.moves[i].crane, i))


@dataclass(frozen=True)
class Placed:
    """A move as planned among the others: ``index`` in the scenario, where its crane started (``origin``, by
    axis), the start it asked for (``asked``, s: its own, or its crane's previous motion's end), its ``delay``
    (s) and the crane it waited for ('' if none); its ``plan`` and ``occupancy`` (delayed), or ``refused``
    saying why and ``refused_by`` the crane in its way (then both None, its crane staying where it was)."""

    index: int
    move: Move
    origin: dict
    asked: float
    delay: float = 0.0
    waited_for: str = ''
    plan: Plan | None = None
    occupancy: Occupancy | None = None
    refused: str = ''
    refused_by: str = ''

    @property
    def start(self) -> float:
        return self.asked + self.delay

    @property
    def end(self) -> float:
        """When its motion ends (s)."""
        return self.start + self.move.duration


@dataclass(frozen=True)
class Together:
    """The scenario planned (``placed``: in order of publication) and each crane's whole ``timeline``."""

    scenario: Scenario
    placed: list
    timelines: dict

    @property
    def moved(self) -> list:
        """The moves not refused, in order of publication."""
        return [p for p in self.placed if not p.refused]

    def total(self) -> float:
        """The time (s) from the first start asked for to the end of the last motion."""
        return total_time(self.scenario, [(p.move, p.start) for p in self.moved])

    def alone(self) -> float:
        """The same (moves not refused) with each crane alone on the runway: no move delayed."""
        return total_time(self.scenario, sequenced([p.move for p in self.moved]))

    def closest(self, placed: Placed) -> dict:
        """Where ``placed``'s crane comes closest to each other crane over its motion and settle window (until
        its crane's next move): a ``Closest`` by crane name (the other's whole timeline)."""
        mine = self.timelines[placed.move.crane]
        span = own_span(placed, self.placed)
        return {name: closest(window(mine, *span), other, span[1])
                for name, other in self.timelines.items() if name != placed.move.crane}


def total_time(scenario: Scenario, started) -> float:
    """The time (s) from the first start asked for in ``scenario`` to the end of the last of ``started``
    ((move, start) pairs); 0 without any."""
    if not started:
        return 0.0
    return max(start + move.duration for move, start in started) - min(m.start for m in scenario.moves)


def sequenced(moves) -> list:
    """(move, start) of ``moves`` (in order of publication) with no one delayed: each at the start it asks for,
    or when its crane's previous motion ends."""
    ready, out = {}, []
    for move in moves:
        start = max(move.start, ready.get(move.crane, -math.inf))
        ready[move.crane] = start + move.duration
        out.append((move, start))
    return out


def default_planner() -> MakePlan:
    """Plans by ``planning.dispatch.plan`` with the default options, NVF/RVF solvers kept across calls."""
    from ..planning.dispatch import PlanOptions, SolverCache, plan
    cache, options = SolverCache(), PlanOptions()

    def make_plan(method, cart, bridge, duration, params):
        return plan(method, cart, duration, params, options, cache, bridge=bridge)
    return make_plan


def move_plan(make_plan: MakePlan, crane: Crane, move: Move, origin: dict) -> Plan:
    """``move``'s plan from ``origin``: the cart's displacement, the bridge's if it moves."""
    d = {axis: end - origin[axis] for axis, end in move.reached(origin).items()}
    if d['cart'] == 0.0 and d['bridge'] == 0.0:
        raise ValueError(f'its goal is where crane {crane.name!r} stands then: nothing to move')
    return make_plan(move.method, d['cart'], d['bridge'] if d['bridge'] != 0.0 else None, move.duration,
                     crane.params)


def plan_together(scenario: Scenario, make_plan: MakePlan | None = None) -> Together:
    """The scenario's moves planned together (see the module docstring). ``make_plan`` (default
    ``default_planner()``) plans a move; its PlanError (a ValueError) is raised naming the move."""
    make_plan = make_plan or default_planner()
    position = {c.name: dict(c.start) for c in scenario.cranes}
    timelines = {c.name: Occupancy(c.name, -1, 0, np.zeros(1), c.at_rest(c.start), c.shape)
                 for c in scenario.cranes}
    ready: dict[str, float] = {}
    placed = []
    for published, i in enumerate(scenario.order()):
        move = scenario.moves[i]
        crane = scenario.crane(move.crane)
        origin = dict(position[move.crane])
        asked = max(move.start, ready.get(move.crane, -math.inf))
        try:
            plan = move_plan(make_plan, crane, move, origin)
        except ValueError as e:
            raise ValueError(f'move {i + 1} (crane {move.crane!r}, {move.method}): {e}') from None
        mine = plan_occupancy(crane.name, plan, crane.params, origin, crane.offset, seconds_ns(asked), published,
                              crane.shape)
        others = [t for name, t in timelines.items() if name != crane.name]
        try:
            s = schedule(mine, others, scenario.min_distance, scenario.policy, margin=PLAN_MARGIN)
        except Conflict as e:
            placed.append(Placed(i, move, origin, asked, refused=str(e), refused_by=e.crane))
            continue
        occupancy = mine.delayed(s.delay)
        timelines[crane.name] = extended(timelines[crane.name], occupancy)
        position[crane.name] = move.reached(origin)
        ready[crane.name] = asked + s.delay + move.duration
        placed.append(Placed(i, move, origin, asked, s.delay, s.waited_for, plan, occupancy))
    return Together(scenario, placed, timelines)


def seconds_ns(t: float) -> int:
    """``t`` s as ns on the scenario's clock."""
    return round(t * 1e9)


def stamps_of(o: Occupancy) -> np.ndarray:
    """The ROS times (ns) of ``o``'s samples."""
    return o.start_ns + np.round(o.t * 1e9).astype(np.int64)


def extended(timeline: Occupancy, then: Occupancy) -> Occupancy:
    """``timeline`` until ``then`` starts, then ``then``: one crane's occupancy over all its moves."""
    old, new = stamps_of(timeline), stamps_of(then)
    keep = old < then.start_ns
    if not keep.any():
        return then
    stamps = np.concatenate((old[keep], new))
    girder = np.concatenate((timeline.footprint.girder[keep], then.footprint.girder))
    masses = np.concatenate((timeline.footprint.masses[keep], then.footprint.masses))
    return Occupancy(then.crane, then.published_ns, int(stamps[0]), (stamps - stamps[0]) * 1e-9,
                     Footprint(girder, masses), then.shape)


def window(o: Occupancy, start_ns: int, end_ns: int) -> Occupancy:
    """``o`` from ``start_ns`` to ``end_ns`` (its samples between, both ends interpolated)."""
    stamps = stamps_of(o)
    inside = stamps[(stamps > start_ns) & (stamps < end_ns)]
    stamps = np.concatenate(([start_ns], inside, [end_ns])) if end_ns > start_ns else np.array([start_ns])
    return Occupancy(o.crane, o.published_ns, start_ns, (stamps - start_ns) * 1e-9, o.at(stamps), o.shape)


def own_span(placed: Placed, everything) -> tuple[int, int]:
    """From ``placed``'s start to the end of its occupancy or its crane's next start, whichever comes first
    (ns)."""
    start, end = placed.occupancy.start_ns, placed.occupancy.end_ns
    later = [p.occupancy.start_ns for p in everything if p.move.crane == placed.move.crane and not p.refused
             and p.occupancy.start_ns > start]
    return start, min([end, *later])


def nearest_of(closests: dict) -> Closest | None:
    """The nearest of ``closests`` (by crane), None if there is none."""
    return min(closests.values(), key=lambda c: c.distance, default=None)
