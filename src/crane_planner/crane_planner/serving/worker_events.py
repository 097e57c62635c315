"""What became of worker processes that died, told to the operator (``Planner(on_event=...)``).

``Deaths`` keeps the deaths whose replacement is not ready yet and reports each event; the request
dispatch (``worker_dispatch``) and the pool's upkeep (``worker_processes``) both find deaths. Pure
Python, no ROS import.
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass

from .workers import Death, SolverProcess

#: The levels of a ``WorkerEvent``, numbered as diagnostic_msgs/DiagnosticStatus numbers its own, so that a
#: node passes them on to /diagnostics as they are.
OK, WARN = 0, 1

#: What every report of a death ends with: the pool is kept full.
REPLACED = 'replaced: a new solver process is starting in its place'


@dataclass(frozen=True)
class WorkerEvent:
    """What became of a worker process that died, for the operator (``Planner(on_event=...)``).

    ``action`` is what the planner did: 're-run' (its request solved again on solver process ``new_pid``),
    'refused' (its request refused: too little time or no worker left, or it died under a re-run),
    'replaced' (it died idle, building solvers or finishing a timed-out request) and, at level OK once a
    new process is ready in its place, 'started' (``new_pid`` is then the new one's). Every death is
    followed by a new process (the pool is kept full); the level is WARN but for 'started'.
    """

    level: int
    action: str
    death: Death
    message: str
    new_pid: int = 0

    def values(self) -> dict:
        """Its key values for a status: the dead process, how it ended, what was done."""
        return {'pid': self.death.pid, 'signal': self.death.signal or 0, 'exit': self.death.cause,
                'action': self.action, 'new_pid': self.new_pid}


class Deaths:
    """The worker deaths whose replacement is not ready yet, oldest first, and their reports to ``on_event``."""

    def __init__(self, on_event=None):
        self._on_event = on_event
        self._dead: deque = deque()

    def __iter__(self):
        return iter(list(self._dead))

    def __len__(self) -> int:
        return len(self._dead)

    def add(self, death: Death) -> None:
        """A death found (its replacement, once ready, reports it: ``started``)."""
        self._dead.append(death)

    def replaced(self, death: Death, message: str) -> None:
        """A death found outside a request (idle, building, finishing late): kept and reported."""
        self.add(death)
        self.report(WARN, 'replaced', death, f'{message}; {REPLACED}')

    def started(self, worker: SolverProcess) -> None:
        """A new worker ready: if it replaces one that died, reported (level OK: the pool is whole again
        once every dead one has its replacement)."""
        try:
            death = self._dead.popleft()
        except IndexError:  # one of the first ones
            return
        self.report(OK, 'started', death, f'solver process {worker.pid} started in place of solver process '
                                          f'{death.pid}, which died ({death.cause})', worker.pid)

    def report(self, level: int, action: str, death: Death, message: str, new_pid: int = 0) -> None:
        """``on_event`` told, if given; a failure of it never reaches the request."""
        if self._on_event is None:
            return
        try:
            self._on_event(WorkerEvent(level, action, death, message, new_pid))
        except Exception:
            pass
