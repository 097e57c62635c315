"""The axes' timeline: what the streamer streams from when, as this planner sent it.

One motion at a time is the streamer's: the last one sent (a goal's from
rest, a handover's once taken, a stop's, a settle's), a ``Running`` that
carries its origin (when its first knot streams, confirmed by
stream_state); before it, after it or when none was sent, the streamer
holds the axes where its stream_state says (``CraneView.hold``). The
timeline is apart from the book of goals (``goals.Goals``, the goals'
states): a writer of the motion (a goal, a stop, a settle) changes it here
under this object's own lock, and where a goal's state must change with it
(a goal sent, taken over, stopping) that change runs under the same lock
(``together``), so that nobody sees the one without the other. Pure
Python, no ROS import.
"""
from __future__ import annotations

import threading
from typing import Callable

from .transitions import Running


class Timeline:
    """The motion this planner last sent to the streamer (None: none, or it was not taken)."""

    def __init__(self):
        self._lock = threading.Lock()
        self._running: Running | None = None
        self._ever_sent = False  # a motion streaming before this planner sent any is not its own

    @property
    def running(self) -> Running | None:
        with self._lock:
            return self._running

    def sent_any(self) -> bool:
        """Whether this planner is streaming a motion or has sent one since it started."""
        with self._lock:
            return self._running is not None or self._ever_sent

    def send(self, running: Running | None, together: Callable[[], bool] = lambda: True) -> bool:
        """``running`` is streamed from now on (None: nothing is), if ``together()`` (the goal's own change,
        under this lock) says it may be."""
        with self._lock:
            if not together():
                return False
            self._set(running)
            return True

    def replace(self, old: Running, new: Running | None, together: Callable[[], object] = lambda: None) -> bool:
        """``new`` instead of ``old`` (``together()`` with it), if ``old`` still is what is streamed."""
        with self._lock:
            if self._running is not old:
                return False
            self._set(new)
            together()
            return True

    def clear(self, running: Running) -> bool:
        """``running`` was not taken by the streamer: nothing is in motion (unless a newer one was sent)."""
        return self.replace(running, None)

    def _set(self, running: Running | None) -> None:
        self._running = running
        self._ever_sent |= running is not None
