"""NVF/RVF solvers in this process's threads: kept in pools per solver key, spawned from the first of
their NLP structure.

``ThreadSolvers`` is a ``Planner``'s ``Variational`` without worker processes. Pure Python, no ROS
import; CasADi loads with the first solver.
"""
from __future__ import annotations

import threading

from crane_msgs_py.crane.params import check_count

from ..planning.dispatch import PlanOptions, VariationalRequest, variational_solver
from ..planning.plan import Plan
from .pool import SolverPool
from .workers import solver_settings


class ThreadSolvers:
    """Solvers kept per ``VariationalSolver.key`` in a ``pool.SolverPool`` of up to ``pool_size`` each: a
    request takes an idle one, so requests (for the same method too) never queue behind each other.
    Instances beyond the first are spawned from one already built for the same NLP structure
    (``VariationalSolver.spawn``), which costs milliseconds.

    Args:
        pool_size: most solver instances per key, >= 1 (``resize``).
        pool_wait: longest wait (s) for an instance when all are busy, after which the request is refused
            naming ``solver_pool_size``.
    """

    def __init__(self, pool_size: int, pool_wait: float):
        self.pool_wait = pool_wait
        self.pools: dict = {}  # VariationalSolver.key -> SolverPool
        self._seeds: dict = {}  # VariationalSolver.structure_of -> the first solver built for it
        self._lock = threading.Lock()
        self.pool_size = check_count('solver_pool_size', pool_size)

    def resize(self, size: int) -> None:
        """Pools of up to ``size`` instances from now on, those made already too."""
        size = check_count('solver_pool_size', size)
        with self._lock:
            self.pool_size = size
            for pool in self.pools.values():
                pool.size = size

    def __call__(self, request: VariationalRequest) -> Plan:
        """The request run on a pooled solver of its key."""
        with self._pool(request.method, request.options).lend(self.pool_wait) as solver:
            return request.run(solver)

    def _pool(self, method: str, options: PlanOptions):
        from ..planning.variational import VariationalSolver
        key = VariationalSolver.key(method, options)
        with self._lock:
            pool = self.pools.get(key)
            if pool is None:
                pool = self.pools[key] = SolverPool(lambda: self._new_solver(method, options),
                                                    self.pool_size, method)
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
