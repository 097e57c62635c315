"""The streamer's state and mode as an explicit state machine.

``State``: nothing streams while ``STOPPED`` or ``WAITING`` for the hold
position (``start_position``); ``STREAMING`` publishes the active source
every tick (a motion, the operator's command, or the hold at rest);
``STOPPING`` is a ``~/stop`` running to rest, which the loop ends
(``STOPPED``) at the first tick its source is at rest. ``TRANSITIONS`` are
the legal moves; any other raises ``IllegalTransition``. ``Mode`` says which
source streams: the trajectories the planner sends, or the operator's
``cmd_vel``.

The executor thread and the loop both move the state (the loop only from
``STOPPING``), so every move is made under a lock; ``running`` is an event
the loop waits on. Pure Python, no ROS import.
"""
from __future__ import annotations

import enum
import threading
from typing import Callable


class State(enum.Enum):
    """Whether and how the streamer streams."""

    STOPPED = 'stopped'      # nothing streams (start-up, a ~/stop ended, the axes' fault reaction)
    WAITING = 'waiting'      # a start waits for the hold position: nothing streams yet
    STREAMING = 'streaming'  # the active source streams every tick
    STOPPING = 'stopping'    # a ~/stop runs to rest; new trajectories and commands are refused


class Mode(enum.Enum):
    """Which source streams while streaming."""

    TRAJECTORY = 'trajectory'  # the planner's trajectories (and the hold between them)
    OPERATOR = 'operator'      # cmd_vel, shaped online


TRANSITIONS = {
    State.STOPPED: {State.STOPPED, State.WAITING, State.STREAMING},  # (a halt racing the loop's own stop)
    State.WAITING: {State.WAITING, State.STREAMING, State.STOPPED},  # (every start asks again)
    State.STREAMING: {State.STOPPING, State.STOPPED},
    State.STOPPING: {State.STOPPED},
}
#: The states in which the loop runs.
RUNNING = frozenset({State.STREAMING, State.STOPPING})


class IllegalTransition(RuntimeError):
    """A move ``TRANSITIONS`` does not allow."""


class StreamerState:
    """The streamer's state (see the module docstring). Thread-safe."""

    def __init__(self):
        self._lock = threading.Lock()
        self._state = State.STOPPED
        #: set while the loop runs (``RUNNING``): the loop waits on it
        self.running = threading.Event()

    @property
    def state(self) -> State:
        return self._state

    def to(self, state: State, then: Callable[[], None] | None = None) -> None:
        """Move to ``state``; IllegalTransition (and nothing done) if ``TRANSITIONS`` does not allow it.
        ``then`` runs once the move is known legal, before it, under the lock: what goes with the move (a
        stream resumed) happens whole before any other move, never after a move that came later."""
        with self._lock:
            self._check(state)
            if then is not None:
                then()
            self._move(state)

    def end_stop(self, then: Callable[[], None] | None = None) -> bool:
        """The loop's end of a ``~/stop``: ``STOPPING`` -> ``STOPPED``, ``then`` run first under the lock (the
        stream stopped where the source came to rest); False (nothing done) if no stop runs any more (a halt,
        maybe a start after it, came first: stopping the stream then would stop the new start's)."""
        with self._lock:
            if self._state is not State.STOPPING:
                return False
            if then is not None:
                then()
            self._move(State.STOPPED)
            return True

    def cancel(self) -> bool:
        """A ``~/stop`` while not running: a start waiting for the hold asks no more (``WAITING`` ->
        ``STOPPED``); False if none waited."""
        with self._lock:
            if self._state is not State.WAITING:
                return False
            self._move(State.STOPPED)
            return True

    def _check(self, state: State) -> None:
        if state not in TRANSITIONS[self._state]:
            raise IllegalTransition(f'{self._state.value} -> {state.value}')

    def _move(self, state: State) -> None:
        self._check(state)
        self._state = state
        if state in RUNNING:
            self.running.set()
        else:
            self.running.clear()
