"""A request onto a worker process: taken before its answer is due, re-run once if its worker dies, else
refused naming why.

``WorkerDispatch`` runs each NVF/RVF request of a ``Planner`` with worker processes on one of
``worker_processes.WorkerProcesses``: a request that finds every worker busy waits for one until its
answer is due (``max_solve_time`` + ``answer_margin``), then is refused naming ``solver_processes``; a
request whose worker died solving it is run again once on another worker when at least ``rerun_within``
s of its time are left and one frees up before its answer is due, else refused naming the dead process
and how it ended. Pure Python, no ROS import.
"""
from __future__ import annotations

import threading
import time
from dataclasses import dataclass

from ..planning.dispatch import VariationalRequest
from ..planning.plan import Plan, PlanError
from .worker_events import REPLACED, WARN
from .worker_processes import WorkerProcesses
from .workers import Death, SolverProcess, WorkerDied


@dataclass(frozen=True)
class _Due:
    """When a request's answer is due (``time.monotonic()`` s; None: it has no budget), and that budget
    for messages."""

    at: float | None
    budget: str

    def left(self) -> float | None:
        return None if self.at is None else self.at - time.monotonic()


class WorkerDispatch:
    """Runs checked NVF/RVF requests on ``processes``' workers (``Planner.variational`` with workers)."""

    #: A request is answered within ``max_solve_time`` + this (s), even if its worker is still building a
    #: solver (its late answer is dropped).
    answer_margin = 0.4
    #: How long (s) a request without ``max_solve_time`` waits for an idle one.
    unbounded_wait = 60.0
    #: A request whose worker died is run again only if at least this much (s) of its time is left: a warm
    #: solve takes tens of milliseconds, a shorter remainder would only end late.
    rerun_within = 0.1

    def __init__(self, processes: WorkerProcesses):
        self.processes = processes
        self.deaths = processes.deaths

    def __call__(self, request: VariationalRequest) -> Plan:
        """The request's plan from a worker; once again on another worker if its worker dies (``_rerun``)."""
        budget = request.options.max_solve_time
        due = _Due(None, 'no max_solve_time') if budget is None else _Due(
            time.monotonic() + budget + self.answer_margin, f'max_solve_time {budget:g} s + {self.answer_margin:g} s')
        try:
            return self._solve(request, self._take(request, due), due)
        except WorkerDied as exc:
            return self._rerun(request, due, exc.death)

    def _take(self, request: VariationalRequest, due: _Due) -> SolverProcess:
        """An idle worker, waiting until shortly before the answer is due; those found dead are replaced
        first. One that has this NLP built if one is idle, else any: a busy one may take as long as its
        request's budget, a build here would hold this process's interpreter lock for seconds."""
        self.processes.reap_idle()
        left = due.left()
        try:
            return self.processes.pool.take(self.unbounded_wait if left is None else max(left - 0.05, 0.0),
                                            prefer=lambda w: w.has(request))
        except PlanError as exc:
            dead = list(self.deaths)
            if not dead:
                raise
            raise PlanError(f'{exc}; {len(dead)} of them not ready yet, starting in place of solver processes '
                            f'that died ({", ".join(f"{d.pid}: {d.cause}" for d in dead)})') from None

    def _solve(self, request: VariationalRequest, worker: SolverProcess, due: _Due) -> Plan:
        """The request on ``worker``, answered before it is due; the worker goes back to the pool (a late
        one once its answer is in, so no caller waits behind it; a dead one to be replaced)."""
        try:
            left = due.left()
            return worker.solve(request, None if left is None else max(left, 0.05))
        except WorkerDied as exc:
            self.deaths.add(exc.death)  # (before it goes back: its replacement reports this one)
            raise
        finally:
            if worker.late:
                threading.Thread(target=self._finish_late, args=(worker,), daemon=True).start()
            else:
                self.processes.pool.give_back(worker)

    def _rerun(self, request: VariationalRequest, due: _Due, death: Death) -> Plan:
        """The request again, once, after its worker died solving it: on a worker that is idle or becomes
        so before the answer is due, if ``rerun_within`` s are left; else refused naming the death."""
        left = due.left()
        if left is not None and left < self.rerun_within:
            raise self._refused(death, f'{max(left, 0.0):.2f} s of its time ({due.budget}) was left, too little '
                                       'to solve it again')
        try:
            worker = self._take(request, due)
        except PlanError:
            raise self._refused(death, 'no other solver process was free before its answer was due '
                                       f'({due.budget})') from None
        self.deaths.report(WARN, 're-run', death, f'{death} while solving an {request.method.upper()} request; '
                           f're-run on solver process {worker.pid}; {REPLACED}', worker.pid)
        try:
            return self._solve(request, worker, due)
        except WorkerDied as again:
            raise self._refused(again.death, f'it was re-running a request after {death}') from None
        except PlanError as exc:  # late (the time the dead one took was missing), or its own refusal: either way
            # the caller is told the answer is a re-run's
            raise PlanError(f'{death} while solving; its re-run on solver process {worker.pid}: {exc}') from None

    def _refused(self, death: Death, reason: str) -> PlanError:
        """The refusal of a request whose worker died solving it, reported."""
        message = f'{death} while solving; {reason}: refused'
        self.deaths.report(WARN, 'refused', death, f'{message}; {REPLACED}')
        return PlanError(message)

    def _finish_late(self, worker: SolverProcess) -> None:
        """Back to the pool once a timed-out request's answer is in (reported if it died meanwhile)."""
        death = worker.finish_late()
        if death is not None:
            self.deaths.replaced(death, f'{death} while finishing a request that had timed out')
        self.processes.pool.give_back(worker)
