"""The planning facade for callers that serve requests: pooled solvers and worker processes.

``Planner`` answers ``planning.dispatch`` requests (the same checks, the
same routes) with NVF/RVF solvers kept in pools, and optionally in worker
processes, so concurrent requests never queue behind each other. Used by the
``crane-plan`` CLI and the planner node alike. Pure Python, no ROS import.
"""
from __future__ import annotations

import threading
import time

from crane_msgs_py.params import CraneParams, check_count

from ..planning import dispatch
from ..planning.dispatch import PlanOptions, VariationalRequest, variational_solver
from ..planning.plan import Plan, PlanError
from .pool import SolverPool
from .workers import SolverProcess


def solver_settings(options: PlanOptions) -> dict:
    """The settings of every solver that serves beside others: the direct route's solves pace each other
    (``yielding.YieldingCallback``).

    Imported here, not at the top: CasADi loads only when a variational plan is asked for.
    """
    if options.solver != 'direct':
        return {}
    from .yielding import YieldingCallback
    return {'iteration_callback': YieldingCallback}


class Planner:
    """Makes plans of every method; thread-safe, and concurrent requests run side by side.

    Variational solvers are expensive to build, so they are kept per
    (route, method, intervals, robust set, limits, time budget) in a
    ``pool.SolverPool`` of up to ``pool_size`` instances: a request takes an
    idle one, so requests (for the same method too) never queue behind each
    other. Instances beyond the first are spawned from one already built for
    the same NLP structure (``VariationalSolver.spawn``), which costs
    milliseconds. The options' ``solver`` picks the route.

    With ``processes`` > 0, direct-route solves run instead in that many
    worker processes (``workers.SolverProcess``, started by ``start_processes``
    and kept), each with its own solvers (``dispatch.SolverCache``): IPOPT lets one MUMPS call at a
    time run per process, so threads of one process still wait on each
    other's factorizations, processes do not. A request that finds every
    worker busy (e.g. with requests running to their time budget) is solved
    in this process's threads after ``process_wait``, not refused. The
    worker processes start from a fork server, so a script using them needs
    the usual ``if __name__ == '__main__':`` guard (``multiprocessing``).

    Args:
        pool_size: most solver instances per key, >= 1 (settable).
        pool_wait: longest wait (s) for an instance when all are busy, after
            which the request is refused naming ``solver_pool_size``.
        processes: worker processes for NVF/RVF (direct route); 0 = solve in
            this process's threads.
    """

    #: With worker processes, a request is answered within ``max_solve_time`` + this (s),
    #: even if its worker is still building a solver (its late answer is dropped).
    answer_margin = 0.4
    #: With worker processes, how long (s) a request waits for one to be idle before it
    #: is solved in this process's threads instead (typical solves take 2-20 ms).
    process_wait = 0.02

    def __init__(self, pool_size: int = 8, pool_wait: float = 0.3, processes: int = 0):
        self.pool_wait = pool_wait
        self._pools: dict = {}  # VariationalSolver.key -> SolverPool
        self._seeds: dict = {}  # VariationalSolver.structure_of -> the first solver built for it
        self._lock = threading.Lock()
        self.pool_size = pool_size
        #: ``VariationalRequest``s a new worker process answers before serving, so its solvers are built
        self.warmups: list[VariationalRequest] = []
        self._processes = None
        if processes:
            self._processes = SolverPool(lambda: SolverProcess(self.warmups),
                                         check_count('solver_processes', processes), 'process',
                                         hint='raise solver_processes')

    @property
    def pool_size(self) -> int:
        return self._pool_size

    @pool_size.setter
    def pool_size(self, size: int):
        size = check_count('solver_pool_size', size)
        with self._lock:
            self._pool_size = size
            for pool in self._pools.values():
                pool.size = self._pool_size

    def plan(self, method: str, displacement: float, duration: float,
             params: CraneParams | None = None, options: PlanOptions | None = None, hoist=None) -> Plan:
        """A rest-to-rest plan from 0 to ``displacement`` (m) in ``duration`` (s) (``dispatch.plan``;
        ``hoist`` = (L1_start, L1_goal) moves the rope too).

        Raises PlanError (or its ParameterError sibling, both ValueError) with a
        message naming the problem.
        """
        return dispatch.plan(method, displacement, duration, params, options, self._variational, hoist)

    def fastest(self, method: str, displacement: float, params: CraneParams | None = None,
                options: PlanOptions | None = None, hoist=None) -> Plan:
        """The shortest rest-to-rest plan of ``displacement`` (m) within the options' axis limits
        (``dispatch.fastest``)."""
        return dispatch.fastest(method, displacement, params, options, self._variational, hoist)

    def start_processes(self, ready_within: float = 60.0, all_of_them: bool = False) -> bool:
        """Start every worker process in the background (each warms up on ``warmups`` first).

        Waits up to ``ready_within`` seconds for one (or, ``all_of_them``, every
        one) to be ready and idle; whether it is (True without worker processes).
        """
        if self._processes is None:
            return True
        return self._processes.fill(ready_within, self._processes.size if all_of_them else 1)

    def close(self) -> None:
        """Stop the worker processes (busy ones after their request)."""
        if self._processes is not None:
            self._processes.close()

    def warm_threads(self, requests) -> None:
        """Run ``VariationalRequest``s in this process's threads, so its own solvers are built.

        With worker processes these take the requests that find every worker
        busy; warmed, such a request does not pay for a build.
        """
        for request in requests:
            self._in_threads(request)

    def variational(self, request: VariationalRequest) -> Plan:
        """Run one checked NVF/RVF request (e.g. a plan from a state, ``serving.transitions``) like
        ``plan`` runs its own: in a worker process, else in a pooled solver."""
        return self._variational(request)

    def _variational(self, request: VariationalRequest) -> Plan:
        """An NVF/RVF request in a worker process (direct route, if there are workers), else in a thread."""
        if self._processes is None or request.options.solver != 'direct':
            return self._in_threads(request)
        t0 = time.monotonic()
        try:
            worker = self._processes.take(self.process_wait)
        except PlanError:  # every worker is busy (hard requests): solve here rather than wait or refuse
            return self._in_threads(request)
        try:
            timeout = None
            if request.options.max_solve_time is not None:
                timeout = max(request.options.max_solve_time + self.answer_margin - (time.monotonic() - t0), 0.05)
            return worker.solve(request, timeout)
        finally:
            if worker.late:  # back to the pool once its answer is in, so no caller waits behind it
                threading.Thread(target=lambda: (worker.finish_late(), self._processes.give_back(worker)),
                                 daemon=True).start()
            else:
                self._processes.give_back(worker)

    def _in_threads(self, request: VariationalRequest) -> Plan:
        with self._pool(request.method, request.options).lend(self.pool_wait) as solver:
            return request.run(solver)

    def _pool(self, method: str, options: PlanOptions):
        from ..planning.variational import VariationalSolver
        key = VariationalSolver.key(method, options)
        with self._lock:
            pool = self._pools.get(key)
            if pool is None:
                pool = self._pools[key] = SolverPool(lambda: self._new_solver(method, options),
                                                     self._pool_size, method)
        return pool

    def _new_solver(self, method: str, options: PlanOptions):
        """A spawn of the first solver of the same structure, or (the first) a new one."""
        from ..planning.variational import VariationalSolver
        structure = VariationalSolver.structure_of(method, options)
        with self._lock:
            seed = self._seeds.get(structure)
        if seed is not None:
            return seed.spawn(options)
        solver = variational_solver(method, options, **solver_settings(options))
        with self._lock:
            self._seeds.setdefault(structure, solver)
        return solver
