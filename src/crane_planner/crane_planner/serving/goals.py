"""The ExecuteMove goals the planner is executing: an explicit state each, and one book of them under one lock.

A goal's life (as rclpy's ``ServerGoalHandle`` has explicit states, so has
ours, for what the planner does with it):

- ``ARRIVED``: registered in the goal callback, before rclpy accepted it;
  being planned.
- ``HELD``: planned; its trajectory held until ``publish_lead`` before its
  start, so that a cancel before then streams nothing.
- ``SENT``: its trajectory (or handover) went to the streamer; a handover
  the streamer did not take is sent again (``SENT`` again), or, if the
  motion it was to take over has ended meanwhile, the goal is planned from
  rest (``HELD``).
- ``FOLLOWING``: the streamer streams it; followed to its result.
- ``STOPPING``: canceled during its motion: a stop was sent and is followed.
- ``TAKEN_OVER``: a newer goal took its motion over (preempted once sent).
- ``PREEMPTED``: a newer goal arrived before it was sent: it never streams.
- ``CANCELED``: canceled before it was sent: it never streams.
- ``ENDED``: its result was given.
- ``FORGOTTEN``: rclpy never accepted it (an internal error rclpy logs).

A transition not in ``TRANSITIONS`` raises ``IllegalTransition``. Pure
Python, no ROS import: the goal handle is an opaque object the node gives.
"""
from __future__ import annotations

import enum
import threading
from dataclasses import dataclass, field
from typing import Any, Callable

from .execution import Execution
from .transitions import Running

#: A goal registered on arrival but not accepted this long after (s) is forgotten.
UNACCEPTED_AFTER = 10.0


class GoalState(enum.Enum):
    ARRIVED = 'arrived'
    HELD = 'held'
    SENT = 'sent'
    FOLLOWING = 'following'
    STOPPING = 'stopping'
    TAKEN_OVER = 'taken over'
    PREEMPTED = 'preempted'
    CANCELED = 'canceled'
    ENDED = 'ended'
    FORGOTTEN = 'forgotten'


S = GoalState
#: state -> the states it may change to.
TRANSITIONS = {
    S.ARRIVED: {S.HELD, S.SENT, S.PREEMPTED, S.CANCELED, S.ENDED, S.FORGOTTEN},
    S.HELD: {S.SENT, S.PREEMPTED, S.CANCELED, S.ENDED},
    S.SENT: {S.SENT, S.HELD, S.FOLLOWING, S.TAKEN_OVER, S.ENDED, S.FORGOTTEN},
    S.FOLLOWING: {S.STOPPING, S.TAKEN_OVER, S.ENDED},
    S.STOPPING: {S.TAKEN_OVER, S.ENDED},
    S.TAKEN_OVER: {S.ENDED},
    S.PREEMPTED: {S.ENDED, S.FORGOTTEN},
    S.CANCELED: {S.ENDED, S.FORGOTTEN},
    S.ENDED: set(),
    S.FORGOTTEN: set(),
}
#: The states in which the goal's trajectory has gone to the streamer: a cancel then stops the motion.
SENT_STATES = frozenset({S.SENT, S.FOLLOWING, S.STOPPING, S.TAKEN_OVER})
#: The states of a goal that will never stream.
UNSENT_ENDS = frozenset({S.PREEMPTED, S.CANCELED})


class IllegalTransition(RuntimeError):
    """A goal asked to change to a state its state does not lead to."""


@dataclass(frozen=True)
class TakeOver:
    """A goal arriving during a motion: that motion, its arrival (ns; and by the timer, s), and its handover
    as sent on arrival (a ``handover.Sent``), or why not (``error``: a
    refusal's ValueError, or a bug's exception)."""

    running: Running
    arrived_ns: int
    arrived_t: float  # (the service's timer: what its planning time counts from)
    sent: Any = None
    error: Exception | None = None


@dataclass(eq=False)
class Goal:
    """One ExecuteMove goal: its state, its motion as sent and how it is followed."""

    arrived_ns: int
    handle: Any = None  # the server's goal handle, once accepted
    state: GoalState = S.ARRIVED
    execution: Execution | None = None
    running: Running | None = None  # its motion as sent (a stop's once canceled)
    take_over: TakeOver | None = None
    warmups: int = 0  # handover warm-ups during its motion (count, s)
    warmup_s: float = 0.0
    history: list = field(default_factory=list)  # the states it went through, for the tests and the logs

    def change(self, state: GoalState) -> None:
        """To ``state``; IllegalTransition if its state does not lead there."""
        if state not in TRANSITIONS[self.state]:
            raise IllegalTransition(f'a goal {self.state.value} cannot become {state.value}')
        self.history.append(self.state)
        self.state = state

    @property
    def sent(self) -> bool:
        return self.state in SENT_STATES


class Goals:
    """The book of goals: registered on arrival, accepted, sent, followed, ended, forgotten; one lock for all
    of it. What the streamer streams is the axes' timeline (``timeline.Timeline``), apart from it: each goal
    keeps only its own motion as sent (``Goal.running``).

    Args:
        clock: ROS time now (ns).
        unaccepted_after: s after which a goal rclpy never accepted is forgotten.
    """

    def __init__(self, clock: Callable[[], int], unaccepted_after: float = UNACCEPTED_AFTER):
        self._clock, self._unaccepted_after = clock, unaccepted_after
        self.lock = threading.Lock()
        self._goals: list[Goal] = []
        self._arriving: dict = {}  # key of the request -> its goal, until accepted

    def __len__(self) -> int:
        with self.lock:
            return len(self._goals)

    # -- arrival and acceptance -----------------------------------------------------

    def arrive(self, key) -> tuple[Goal, list[Goal]]:
        """A new goal, registered under ``key``; every goal not sent yet gives way to it (it never streams).
        Also (the goals forgotten): those registered ``unaccepted_after`` s ago and never accepted."""
        now = self._clock()
        goal = Goal(now)
        forgotten = []
        with self.lock:
            for other in self._goals:
                if other.state in (S.ARRIVED, S.HELD):
                    other.change(S.PREEMPTED)
            for old_key, other in list(self._arriving.items()):
                if now - other.arrived_ns > self._unaccepted_after * 1e9:
                    del self._arriving[old_key]
                    self._goals.remove(other)
                    other.change(S.FORGOTTEN)
                    forgotten.append(other)
            self._goals.append(goal)
            self._arriving[key] = goal
        return goal, forgotten

    def accept(self, key, handle) -> Goal:
        """The goal registered under ``key``, accepted by the server with ``handle``."""
        with self.lock:
            goal = self._arriving.pop(key)
            goal.handle = handle
        return goal

    def of(self, handle) -> Goal | None:
        with self.lock:
            return next((g for g in self._goals if g.handle is handle), None)

    def cancel(self, handle) -> Goal | None:
        """A cancel of the goal with ``handle``: one not sent is ``CANCELED`` (it will never stream); one
        sent stays as it is (its steps stop the motion)."""
        with self.lock:
            goal = next((g for g in self._goals if g.handle is handle), None)
            if goal is not None and goal.state in (S.ARRIVED, S.HELD):
                goal.change(S.CANCELED)
        return goal

    # -- the goal's motion -------------------------------------------------------------

    def hold(self, goal: Goal) -> bool:
        """Planned: held for its lead, unless it already gave way or was canceled."""
        with self.lock:
            if goal.state in UNSENT_ENDS:
                return False
            goal.change(S.HELD)
            return True

    def send(self, goal: Goal, execution: Execution, running: Running | None = None,
             canceled: Callable[[], bool] = lambda: False) -> bool:
        """Mark ``goal`` sent with the ``execution`` that follows it, unless it gave way, was canceled
        (``canceled()``: the server's own flag, read under the lock) or was taken over meanwhile: then
        nothing may be sent (False).
        ``running``: its motion as sent, the streamer's once the caller's timeline has it (a goal's own
        motion, not a handover: the settling goals observe until it starts at the latest)."""
        with self.lock:
            if goal.state is S.TAKEN_OVER:  # (while its handover was to be sent again)
                return False
            if goal.state in UNSENT_ENDS or (not goal.sent and canceled()):
                if goal.state not in UNSENT_ENDS:
                    goal.change(S.CANCELED)
                return False
            goal.change(S.SENT)
            goal.execution = execution
            if running is not None:
                for other in self._goals:
                    if other is not goal and other.execution is not None:
                        other.execution.cut(execution.start_ns)
                goal.running = running
            return True

    def follow(self, goal: Goal) -> None:
        with self.lock:
            if goal.state is S.SENT:
                goal.change(S.FOLLOWING)

    def take_over(self, goal: Goal, handover_ns: int, running: Running) -> None:
        """The streamer took ``goal``'s handover at ``handover_ns``: the motion is its own (``running``, the
        timeline's too); every other goal's settle window ends there, and one still in motion was taken over."""
        with self.lock:
            for other in self._goals:
                if other is not goal and other.execution is not None:
                    other.execution.cut(handover_ns)
                    if other.sent and other.state is not S.TAKEN_OVER and other.execution.in_motion:
                        other.change(S.TAKEN_OVER)
            if goal.state is not S.TAKEN_OVER:  # (a newer goal took it over while the streamer took it)
                goal.change(S.FOLLOWING)
            goal.running = running

    def stopping(self, goal: Goal, stop: Running, execution: Execution) -> None:
        """A stop of ``goal``'s motion sent (together: the stop's origin is learned from its execution)."""
        with self.lock:
            goal.change(S.STOPPING)
            goal.running = stop
            goal.execution = execution

    def own(self, goal: Goal, running: Running) -> None:
        """``running`` is ``goal``'s motion now (a stop of it, as the streamer streams it)."""
        with self.lock:
            goal.running = running

    def end(self, goal: Goal) -> None:
        with self.lock:
            goal.change(S.ENDED)

    def remove(self, goal: Goal) -> None:
        with self.lock:
            if goal in self._goals:
                self._goals.remove(goal)

    # -- what the inputs and the handover need --------------------------------------------

    def executions(self) -> list[Execution]:
        with self.lock:
            return [g.execution for g in self._goals if g.execution is not None]

    def owner(self, running: Running) -> Goal | None:
        """The goal whose motion ``running`` is."""
        with self.lock:
            return next((g for g in self._goals if g.running is running), None)

    def origin_of(self, running: Running) -> int | None:
        """When the streamer streams ``running``'s first knot, as its goal's stream_state said (None: not yet)."""
        goal = self.owner(running)
        execution = goal.execution if goal is not None else None
        return execution.motion_origin_ns if execution is not None else None

    def count_warmup(self, running: Running, took_s: float) -> None:
        """A handover warm-up of ``running``, counted for its goal (its status on /diagnostics)."""
        with self.lock:
            goal = next((g for g in self._goals if g.running is running), None)
            if goal is not None:
                goal.warmups, goal.warmup_s = goal.warmups + 1, goal.warmup_s + took_s
