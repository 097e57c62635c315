"""The planning facade for callers that serve requests: pooled solvers and worker processes.

``Planner`` answers ``planning.dispatch`` requests (the same checks, the
same routes) with NVF/RVF solvers kept in pools (``thread_solvers``), and
optionally in worker processes (``worker_processes`` keeps them,
``worker_dispatch`` sends a request to one, ``worker_events`` tells of their
deaths), so concurrent requests never queue behind each other. Used by the
``crane-plan`` CLI and the planner node alike. Pure Python, no ROS import.
"""
from __future__ import annotations

from crane_msgs_py.crane.params import CraneParams

from ..planning import dispatch
from ..planning.dispatch import PlanOptions, VariationalRequest
from ..planning.plan import Plan
from .thread_solvers import ThreadSolvers
from .worker_dispatch import WorkerDispatch
from .worker_events import OK, WARN, Deaths, WorkerEvent
from .worker_processes import SPARE_LIMITS, WorkerProcesses, toggled_limits

__all__ = ['OK', 'SPARE_LIMITS', 'WARN', 'Planner', 'WorkerEvent', 'toggled_limits']


class Planner:
    """Makes plans of every method; thread-safe, and concurrent requests run side by side.

    Variational solvers are expensive to build, so they are kept per
    (route, method, intervals, robust set, limits, time budget) in a
    ``pool.SolverPool`` of up to ``pool_size`` instances (``threads``, a
    ``thread_solvers.ThreadSolvers``): a request takes an idle one, so
    requests (for the same method too) never queue behind each other.
    Instances beyond the first are spawned from one already built for the
    same NLP structure (``VariationalSolver.spawn``), which costs
    milliseconds. The options' ``solver`` picks the route.

    With ``processes`` > 0, every NVF/RVF request runs instead in one of that
    many worker processes (``workers.SolverProcess``, started by
    ``start_processes`` and kept), each with its own solvers: IPOPT lets one
    MUMPS call at a time run per process, so threads of one process still
    wait on each other's factorizations, processes do not. Nothing of NVF/RVF
    is then built or solved in this process: building an NLP takes seconds
    of CasADi and IPOPT's Python callbacks take the interpreter lock every
    iteration, which the threads answering the cheap requests (a shaper's
    plan, a millisecond's work) would have to share; and the
    workers run at a lower CPU priority (``workers.WORKER_NICE``), so on a
    shared core those threads come first. A request that finds every worker
    busy waits for one until its answer is due (``max_solve_time`` +
    ``dispatch.answer_margin``), then is refused naming ``solver_processes``.
    Setting ``warmups`` (a parameter change) has the workers build the new
    configuration's solvers in the background, one worker at a time, taken
    only when all are idle, at a lower priority still (``processes``, a
    ``worker_processes.WorkerProcesses``, whose ``toggled_limits`` says
    whether one worker builds the limits' twins too). The worker processes
    start from a fork server, so a script using them needs the usual
    ``if __name__ == '__main__':`` guard (``multiprocessing``).

    A worker process that dies is replaced (the pool is kept full): found
    dead under a request, at the next request or by a watch on the idle ones
    (``processes``). A request whose worker died while solving it is run
    again once on another worker (a fresh one if one is ready in time) when
    at least ``dispatch.rerun_within`` s of its time are left and a worker
    frees up before its answer is due; else it is refused naming the dead
    process and how it ended (``dispatch``, a ``worker_dispatch.WorkerDispatch``).
    Each such event goes to ``on_event`` (a ``WorkerEvent``), for the
    operator: a node's /diagnostics.

    Args:
        pool_size: most solver instances per key, >= 1 (settable); in this
            process, so only without worker processes.
        pool_wait: longest wait (s) for an instance when all are busy, after
            which the request is refused naming ``solver_pool_size``.
        processes: worker processes for NVF/RVF; 0 = solve in this process's
            threads.
        on_event: called with a ``WorkerEvent`` (from whichever thread found
            it) when a worker process died and when its replacement is ready.
    """

    def __init__(self, pool_size: int = 8, pool_wait: float = 0.3, processes: int = 0, on_event=None):
        #: the in-thread solvers (used without worker processes)
        self.threads = ThreadSolvers(pool_size, pool_wait)
        self._warmups: list = []
        #: the worker processes and the dispatch of requests onto them; None without
        self.processes = WorkerProcesses(processes, Deaths(on_event)) if processes else None
        self.dispatch = WorkerDispatch(self.processes) if processes else None

    @property
    def warmups(self) -> list[VariationalRequest]:
        """``VariationalRequest``s that build the solvers of the current configuration: a new worker
        process answers them before serving; set, the running workers build what they lack of them in
        the background."""
        return list(self._warmups)

    @warmups.setter
    def warmups(self, requests):
        self._warmups = list(requests)
        if self.processes is not None:
            self.processes.want(self._warmups)

    @property
    def pool_size(self) -> int:
        """Most solver instances per key in this process, >= 1 (only without worker processes)."""
        return self.threads.pool_size

    @pool_size.setter
    def pool_size(self, size: int):
        self.threads.resize(size)

    def plan(self, method: str, displacement: float, duration: float,
             params: CraneParams | None = None, options: PlanOptions | None = None, hoist=None,
             bridge: float | None = None) -> Plan:
        """A rest-to-rest plan from 0 to ``displacement`` (m) in ``duration`` (s) (``dispatch.plan``;
        ``hoist`` = (L1_start, L1_goal) moves the rope too, ``bridge`` (m) the bridge).

        Raises PlanError (or its ParameterError sibling, both ValueError) with a
        message naming the problem.
        """
        return dispatch.plan(method, displacement, duration, params, options, self.variational, hoist, bridge)

    def fastest(self, method: str, displacement: float, params: CraneParams | None = None,
                options: PlanOptions | None = None, hoist=None, bridge: float | None = None) -> Plan:
        """The shortest rest-to-rest plan of ``displacement`` (m) within the options' axis limits
        (``dispatch.fastest``)."""
        return dispatch.fastest(method, displacement, params, options, self.variational, hoist, bridge)

    def start_processes(self, ready_within: float = 60.0, all_of_them: bool = False) -> bool:
        """Start every worker process in the background (each warms up on ``warmups`` first).

        Waits up to ``ready_within`` seconds for one (or, ``all_of_them``, every
        one) to be ready and idle; whether it is (True without worker processes).
        One of them warms up on the ``toggled_limits`` twins too.
        """
        return True if self.processes is None else self.processes.start(ready_within, all_of_them)

    def wait_built(self, timeout: float | None = None) -> bool:
        """Wait up to ``timeout`` s until every worker process has built the solvers of ``warmups`` (and
        of ``warm_threads``' requests); whether they have (True without worker processes)."""
        return True if self.processes is None else self.processes.wait_built(timeout)

    def close(self) -> None:
        """Stop the worker processes (busy ones after their request)."""
        if self.processes is not None:
            self.processes.close()

    def warm_threads(self, requests) -> None:
        """Build the solvers of these ``VariationalRequest``s where requests are solved.

        Without worker processes: in this process's threads, now (each request
        run once). With them, never in this process (its threads answer the
        cheap requests): the workers build what they lack of them in the
        background, as for ``warmups``; this returns at once.
        """
        if self.processes is None:
            for request in requests:
                self.threads(request)
            return
        self.processes.warm(requests)

    def variational(self, request: VariationalRequest) -> Plan:
        """Run one checked NVF/RVF request (e.g. a plan from a state, ``serving.transitions``) like
        ``plan`` runs its own: in a worker process (once again on another worker if its worker dies
        solving it), else in a pooled solver."""
        return (self.threads if self.dispatch is None else self.dispatch)(request)
