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

    def to(self, state: State) -> None:
        """Move to ``state``; IllegalTransition if ``TRANSITIONS`` does not allow it."""
        with self._lock:
            self._move(state)

    def end_stop(self) -> bool:
        """The loop's end of a ``~/stop``: ``STOPPING`` -> ``STOPPED``; False (nothing changes) if no stop runs
        any more (a halt came first)."""
        with self._lock:
            if self._state is not State.STOPPING:
                return False
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

    def _move(self, state: State) -> None:
        if state not in TRANSITIONS[self._state]:
            raise IllegalTransition(f'{self._state.value} -> {state.value}')
        self._state = state
        if state in RUNNING:
            self.running.set()
        else:
            self.running.clear()
