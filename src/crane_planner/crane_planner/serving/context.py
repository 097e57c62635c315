"""What every part of serving a request shares: the planner, the clocks, the outputs, the goals, the timeline.

The parts (``preview``, ``admission``, ``starting``, ``takeover``,
``following``, ``settling``, and ``runway_step`` on a shared runway) are functions of this record and of records
they pass on (``preview.Planned``, ``handover.HandoverResult``,
``following.Outcome``); ``service.MoveService`` builds it. Every time comes
from the clocks in it (ROS time ``clock``, ``timer`` and ``sleep`` for
waits), so the whole runs on a fake clock in the tests. Pure Python, no ROS
import.
"""
from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field
from typing import Any, Callable

from .config import Config
from .crane_view import CraneView
from .goals import Goals
from .handover import PlanningTimes
from .runway_step import RunwayStep
from .timeline import Timeline
from .transitions import Trajectory


@dataclass
class Serving:
    """The shared state and outputs of the planner's requests (``service.MoveService`` says what each is)."""

    planner: Any
    config: Callable[[], Config]
    clock: Callable[[], int]
    publish: Callable[[Trajectory], Any]
    report: Callable[..., Any]
    log: Any
    sleep: Callable[[float], None] = time.sleep
    timer: Callable[[], float] = time.perf_counter
    draw: Callable[[Any, float], Any] | None = None
    goals: Goals | None = None  # (None: a book of its own on ``clock``)
    timeline: Timeline = field(default_factory=Timeline)
    view: CraneView | None = None  # (None: a view of its own over the goals and the timeline)
    handing_over: threading.Lock = field(default_factory=threading.Lock)  # one handover (goal, stop, settle) at a time
    planning_times: PlanningTimes = field(default_factory=PlanningTimes)  # of NVF/RVF handovers, by kind
    runway: RunwayStep | None = None  # (None: no runway, nothing published)

    def __post_init__(self):
        if self.goals is None:
            self.goals = Goals(self.clock)
        if self.view is None:
            self.view = CraneView(self.clock, self.goals, self.timeline, sleep=self.sleep, monotonic=self.timer)
        if self.runway is None:
            self.runway = RunwayStep(self.config, self.clock)
