"""One entry point for every method: validate a request, dispatch, cache solvers.

Used by the ``crane-plan`` CLI and the planner node alike, so both accept and
refuse exactly the same requests with the same messages.
"""
from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass


from crane_msgs_py.params import (CraneParams, ParameterError, check_choice, check_count, check_nonnegative,
                                  check_positive)

from .methods import METHODS, ROBUST_PARAMETERS, SHAPER_METHODS
from .model import modal_properties
from .plan import Plan, PlanError
from .pool import SolverPool
from .limits import check_fastest_request
from .profiles import BASES
from .shaped import fastest_shaped, shaped_plan


@dataclass(frozen=True)
class PlanOptions:
    """Method options beyond the model (contract: ``crane-plan`` model options).

    Attributes:
        omega: shaper design frequencies (rad/s), one per mode; None = from the
            linearized model.
        damping: shaper design damping ratio (>= 0, < 1); None = the model's
            modal damping ratios (``model.modal_properties``) when ``omega``
            is None too, else 0.
        robust: parameters RVF is made insensitive to.
        intervals: collocation intervals for NVF/RVF; None = solver default.
        solver: ``direct`` (CasADi collocation + IPOPT) or ``indirect``
            (the paper's TPBVP, scipy solve_bvp).
        max_velocity: axis limit |v| (m/s), None = no limit.
        max_acceleration: axis limit |a_ref| (m/s^2), None = no limit.
        max_jerk: axis limit on the reference's jerk (m/s^3), None = no limit.
        base: the motion shapers shape: ``quintic`` (the paper's) or
            ``limits`` (the jerk-limited time-optimal profile under the limits,
            ``profiles.limited_base``).
        max_solve_time: budget (s) of one NVF/RVF request, > 0: a plan, or
            a fastest plan's attempts together, not solved within it is refused
            (direct route only; building a solver is not counted, except by
            the caller's wait on a worker process); None = the route's own cap.
    """

    omega: tuple[float, ...] | None = None
    damping: float | None = None
    robust: tuple[str, ...] = ('L1',)
    intervals: int | None = None
    solver: str = 'direct'
    max_velocity: float | None = None
    max_acceleration: float | None = None
    max_jerk: float | None = None
    base: str = 'quintic'
    max_solve_time: float | None = None

    def __post_init__(self):
        if self.omega is not None:
            omega = tuple(check_positive('omega', w) for w in self.omega)
            if len(omega) == 0:
                raise ParameterError('omega needs at least one frequency')
            object.__setattr__(self, 'omega', omega)
        if self.damping is not None:
            damping = check_nonnegative('damping', self.damping)
            if damping >= 1.0:
                raise ParameterError(f'damping must be < 1, got {damping}')
            object.__setattr__(self, 'damping', damping)
        robust = tuple(self.robust)
        bad = [r for r in robust if r not in ROBUST_PARAMETERS]
        if bad:
            raise ParameterError(
                f'robust parameter(s) {", ".join(bad)} not among {", ".join(ROBUST_PARAMETERS)}')
        if len(set(robust)) != len(robust) or not robust:
            raise ParameterError('robust needs one or more distinct parameters')
        object.__setattr__(self, 'robust', robust)
        if self.intervals is not None:
            if int(self.intervals) != self.intervals or not 4 <= int(self.intervals) <= 2000:
                raise ParameterError(f'intervals must be an integer in [4, 2000], got {self.intervals}')
            object.__setattr__(self, 'intervals', int(self.intervals))
        if self.solver not in ('direct', 'indirect'):
            raise ParameterError(f"solver must be 'direct' or 'indirect', got {self.solver!r}")
        check_choice('base', self.base, BASES)
        if self.base == 'limits' and self.max_velocity is None and self.max_acceleration is None:
            raise ParameterError('the limits base needs max_velocity or max_acceleration (or both)')
        for name in ('max_velocity', 'max_acceleration', 'max_jerk', 'max_solve_time'):
            v = getattr(self, name)
            if v is not None:
                object.__setattr__(self, name, check_positive(name, v))


def check_request(method: str, displacement, duration) -> tuple[float, float]:
    """Validate the method name and a (D, T) pair; return them as floats."""
    if method not in METHODS:
        raise PlanError(f'unknown method {method!r}; choose from {", ".join(METHODS)}')
    try:
        displacement = float(displacement)
        duration = float(duration)
    except (TypeError, ValueError):
        raise PlanError('displacement and duration must be numbers') from None
    if not math.isfinite(displacement):
        raise PlanError(f'displacement must be finite, got {displacement}')
    if not math.isfinite(duration):
        raise PlanError(f'duration must be finite, got {duration}')
    if duration <= 0.0:
        raise PlanError(f'duration must be > 0, got {duration}')
    return displacement, duration


LIMITS = (('max_velocity', 'm/s'), ('max_acceleration', 'm/s^2'), ('max_jerk', 'm/s^3'))


def limits_of(options: PlanOptions) -> tuple:
    """(max_velocity, max_acceleration, max_jerk) of ``options``, None for none."""
    return options.max_velocity, options.max_acceleration, options.max_jerk


def check_axis_limits(plan, options: PlanOptions) -> None:
    """PlanError naming the limit if the shaped plan's |v|, |a_ref| or |jerk| peak exceeds it.

    A shaper cannot trade time for peaks: the shaped profile is fixed by the
    method and the duration, so an exceeded limit is an error, not a constraint.
    """
    if all(limit is None for limit in limits_of(options)):
        return
    for (name, unit), limit, peak in zip(LIMITS, limits_of(options), plan.peaks()):
        if limit is not None and peak > limit * (1.0 + 1e-6):
            raise PlanError(f'{plan.method} plan exceeds {name} {limit:g} {unit} (peak {peak:.4g}); '
                            'lengthen the duration or raise the limit')


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
    and kept), each with its own such Planner: IPOPT lets one MUMPS call at a
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
        #: requests ``(operation, arguments)`` (``plan`` or ``fastest``) a new worker process answers
        #: before serving, so its solvers are built
        self.warmups: list[tuple] = []
        self._processes = None
        if processes:
            from .workers import SolverProcess
            self._processes = SolverPool(lambda: SolverProcess(self.warmups), check_count('solver_processes', processes),
                                         'process', hint='raise solver_processes')

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
             params: CraneParams | None = None, options: PlanOptions | None = None) -> Plan:
        """A rest-to-rest plan from 0 to ``displacement`` (m) in ``duration`` (s).

        Raises PlanError (or its ParameterError sibling, both ValueError) with a
        message naming the problem.
        """
        params = params or CraneParams()
        options = options or PlanOptions()
        displacement, duration = check_request(method, displacement, duration)
        if method in SHAPER_METHODS:
            omegas, zetas = shaper_design(params, options)
            plan = shaped_plan(method, displacement, duration, omegas, zetas, options.base, limits_of(options))
            check_axis_limits(plan, options)
            return plan
        # the variational solvers bound v and a_ref everywhere as path constraints
        if self._processes is not None and options.solver == 'direct':
            return self._solve_in_process(method, displacement, duration, params, options)
        with self._pool(method, options).lend(self.pool_wait) as solver:
            return solver.solve(displacement, duration, params)

    def fastest(self, method: str, displacement: float, params: CraneParams | None = None,
                options: PlanOptions | None = None) -> Plan:
        """The shortest rest-to-rest plan of ``displacement`` (m) within the options' axis limits.

        Needs max_velocity or max_acceleration (a motion without either could
        be arbitrarily fast). Shapers: ``shaped.fastest_shaped``; NVF/RVF: the
        free-final-time NLP (``direct.DirectSolver.fastest``), where ``plan``
        solves (worker processes, else pooled solvers).
        """
        params = params or CraneParams()
        options = options or PlanOptions()
        check_request(method, displacement, 1.0)
        limits = limits_of(options)
        displacement = check_fastest_request(displacement, limits)  # before a worker is asked
        if method in SHAPER_METHODS:
            return fastest_shaped(method, displacement, *shaper_design(params, options), limits, options.base)
        if options.solver != 'direct':
            raise PlanError('the fastest NVF/RVF plan needs the direct solver (free final time)')
        if self._processes is not None:
            return self._solve_in_process(method, displacement, None, params, options)
        with self._pool(method, options).lend(self.pool_wait) as solver:
            return solver.fastest(displacement, params)

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
        """Answer requests ``(operation, arguments)`` in this process's threads, so its own solvers are built.

        With worker processes these take the requests that find every worker
        busy; warmed, such a request does not pay for a build.
        """
        for operation, (method, displacement, *rest) in requests:
            options = rest[-1]
            with self._pool(method, options).lend(self.pool_wait) as solver:
                if operation == 'fastest':
                    solver.fastest(float(displacement), rest[0])
                else:
                    solver.solve(*check_request(method, displacement, rest[0]), rest[1])

    def _solve_in_process(self, method, displacement, duration, params, options) -> Plan:
        """``plan`` (or with ``duration`` None ``fastest``) in a worker process."""
        t0 = time.monotonic()
        try:
            worker = self._processes.take(self.process_wait)
        except PlanError:  # every worker is busy (hard requests): solve here rather than wait or refuse
            with self._pool(method, options).lend(self.pool_wait) as solver:
                if duration is None:
                    return solver.fastest(displacement, params)
                return solver.solve(displacement, duration, params)
        request = (('fastest', (method, displacement, params, options)) if duration is None
                   else ('plan', (method, displacement, duration, params, options)))
        try:
            timeout = None
            if options.max_solve_time is not None:
                timeout = max(options.max_solve_time + self.answer_margin - (time.monotonic() - t0), 0.05)
            return worker.solve(request, timeout)
        finally:
            if worker.late:  # back to the pool once its answer is in, so no caller waits behind it
                threading.Thread(target=lambda: (worker.finish_late(), self._processes.give_back(worker)),
                                 daemon=True).start()
            else:
                self._processes.give_back(worker)

    def _pool(self, method: str, options: PlanOptions):
        from .variational import VariationalSolver
        key = VariationalSolver.key(method, options)
        with self._lock:
            pool = self._pools.get(key)
            if pool is None:
                pool = self._pools[key] = SolverPool(lambda: self._new_solver(method, options),
                                                     self._pool_size, method)
        return pool

    def _new_solver(self, method: str, options: PlanOptions):
        """A spawn of the first solver of the same structure, or (the first) a new one."""
        from .variational import VariationalSolver
        structure = VariationalSolver.structure_of(method, options)
        with self._lock:
            seed = self._seeds.get(structure)
        if seed is not None:
            return seed.spawn(options)
        solver = variational_solver(method, options)
        with self._lock:
            self._seeds.setdefault(structure, solver)
        return solver


def shaper_design(params: CraneParams, options: PlanOptions) -> tuple:
    """(frequencies rad/s, damping ratios) the shapers are designed for: the options' or the model's modes."""
    if options.omega is not None:
        return options.omega, options.damping or 0.0
    omegas, zetas = modal_properties(params)
    return omegas, (zetas if options.damping is None else options.damping)


def variational_solver(method: str, options: PlanOptions, **overrides):
    """A new NVF/RVF solver of the route ``options.solver`` picks: ``direct`` (CasADi
    collocation + IPOPT, the fast path) or ``indirect`` (the paper's TPBVP).

    Imported here, not at the top: CasADi loads only when a variational plan is asked for.
    """
    if options.solver == 'indirect':
        from .indirect import IndirectSolver
        return IndirectSolver(method, options, **overrides)
    from .direct import DirectSolver
    return DirectSolver(method, options, **overrides)
