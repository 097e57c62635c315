"""The streamer's loop core: the active source, the corrections after it, the state, and one realtime inbox.

The update loop of ros2_controllers' JointTrajectoryController is the model:
the executor thread writes a request into the ``Inbox`` (the newest wins)
and the loop takes it at its next tick, so the executor never swaps what the
loop is streaming under it. A request names the mode and its source
(``source.Source``): a mode change at rest, or a fresh operator stream at a
start. ``tick`` takes the inbox, samples the active source, applies the
corrections in order (``source.corrected``), shows the result to the watches
(the runway guard) and ends a ``~/stop`` once the source is at rest; it
names no source.

What the trajectory source already hands over thread-safely stays its own:
``ReferenceStream.accept`` (a motion, a handover, a stop's trajectory),
``stop``, ``resume`` and ``hold_at`` take its locks and keep its handover
timing; the operator stream's ``command`` and ``stop`` are one assignment
each. Pure Python, no ROS import.
"""
from __future__ import annotations

import threading
from dataclasses import dataclass
from typing import Callable

from .reference_stream import ReferenceStream
from .source import Correction, Setpoint, Source, Watch, corrected
from .streamer_state import Mode, State, StreamerState

_STOPPING = State.STOPPING  # (the loop asks every tick: a global, not the enum's attribute)


@dataclass(frozen=True)
class Request:
    """What the executor asks of the loop: stream ``source`` in ``mode`` from the next tick."""

    mode: Mode
    source: Source


class Inbox:
    """One realtime request slot: the executor writes, the loop takes what is new at its next tick (the newest
    of what was written meanwhile); ``latest`` is the newest written, taken or not."""

    def __init__(self, initial):
        self._lock = threading.Lock()
        self._latest = initial
        self._new = False

    @property
    def latest(self):
        return self._latest

    def write(self, request) -> None:
        with self._lock:
            self._latest, self._new = request, True

    def take(self):
        """The request written since the last ``take``, else None (no lock then: the loop asks every tick)."""
        if not self._new:
            return None
        with self._lock:
            self._new = False
            return self._latest


class Streamer:
    """What the streamer's loop streams (see the module docstring).

    Args:
        stream: the trajectory mode's source, the one at start-up; it also keeps the hold between sources
            and at a stop.
        corrections: applied after the source every tick, in order.
        watches: shown every published setpoint, after the corrections.
    """

    def __init__(self, stream: ReferenceStream, corrections: tuple = (), watches: tuple = ()):
        self.stream = stream
        self.corrections: tuple[Correction, ...] = tuple(corrections)
        self.watches: tuple[Watch, ...] = tuple(watches)
        self._state = StreamerState()
        self._inbox = Inbox(Request(Mode.TRAJECTORY, stream))
        self._active: Source = stream  # the loop's

    # -- the executor's view -------------------------------------------------------------------

    @property
    def state(self) -> State:
        return self._state.state

    @property
    def running(self) -> threading.Event:
        """Set while the loop runs (streaming or stopping)."""
        return self._state.running

    @property
    def mode(self) -> Mode:
        """The mode asked last (the loop streams its source from its next tick)."""
        return self._inbox.latest.mode

    @property
    def source(self) -> Source:
        """The source asked last."""
        return self._inbox.latest.source

    @property
    def commanded(self) -> bool:
        """Whether velocity commands reach the source: in operator mode, streaming (not stopping)."""
        return self._inbox.latest.mode is Mode.OPERATOR and self._state.state is State.STREAMING

    def use(self, mode: Mode, source: Source) -> None:
        """Stream ``source`` in ``mode`` from the loop's next tick."""
        self._inbox.write(Request(mode, source))

    def settle(self):
        """The hold where the source asked last has left the axes (a change of source at rest starts there);
        returns the hold."""
        source = self.source
        if source is not self.stream:
            self.stream.hold_at(source.position)
        return self.stream.hold

    # -- the state (executor) ------------------------------------------------------------------

    def wait(self) -> None:
        """A start waits for the hold position."""
        self._state.to(State.WAITING)

    def go(self, mode: Mode, source: Source) -> None:
        """Stream ``source`` in ``mode`` from the hold (``stream.hold_at`` it first)."""
        def resume():  # (before the move: the loop wakes on the state and starts the stream)
            self.use(mode, source)
            self.stream.resume()
        self._state.to(State.STREAMING, then=resume)

    def stopping(self) -> None:
        """A ``~/stop`` runs to rest (its source was told to stop): the loop stops once it is at rest."""
        self._state.to(State.STOPPING)

    def halt(self) -> None:
        """Stop streaming now: the loop holds nothing and waits for a start."""
        self._state.to(State.STOPPED, then=self.stream.stop)

    def cancel(self) -> bool:
        """A ``~/stop`` while not running: a start waiting for the hold is dropped; False if none waited."""
        return self._state.cancel()

    # -- the loop --------------------------------------------------------------------------------

    def start(self, epoch_ns: int, tick: Callable[[], int]) -> bool:
        """The loop's ticks begin (``ReferenceStream.start``); False if stopped meanwhile."""
        return self.stream.start(epoch_ns, tick)

    def tick(self, tick: int, stamp_ns: int) -> Setpoint:
        """The setpoint published at ``tick`` with the stamp ``stamp_ns``: the request taken, the active
        source sampled and corrected; a ``~/stop`` whose source came to rest ends here (the stream stops
        after publishing this tick)."""
        request = self._inbox.take()
        if request is not None:
            self._active = request.source
        source = self._active
        setpoint = source.sample(tick)
        if self.corrections:
            setpoint = corrected(self.corrections, tick, stamp_ns, setpoint)
        for watch in self.watches:
            watch.watch(stamp_ns, setpoint, source)
        if self._state.state is _STOPPING and source.at_rest:
            self._stopped(source)
        return setpoint

    @property
    def moving(self) -> bool:
        """Whether the loop's source moves now."""
        return self._active.moving

    def _stopped(self, source: Source) -> None:
        def stop():  # (under the state's lock: a start once stopped finds the stream stopped, not stopping it after)
            if source is not self.stream:  # the hold where the source stopped the axes
                self.stream.hold_at(source.position)
            self.stream.stop()
        self._state.end_stop(then=stop)
