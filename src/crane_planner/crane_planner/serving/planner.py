"""The planning facade for callers that serve requests: pooled solvers and worker processes.

``Planner`` answers ``planning.dispatch`` requests (the same checks, the
same routes) with NVF/RVF solvers kept in pools, and optionally in worker
processes, so concurrent requests never queue behind each other. Used by the
``crane-plan`` CLI and the planner node alike. Pure Python, no ROS import.
"""
from __future__ import annotations

import dataclasses
import threading
import time
from collections import deque
from dataclasses import dataclass

from crane_msgs_py.crane.params import CraneParams, check_count

from ..planning import dispatch
from ..planning.dispatch import PlanOptions, VariationalRequest, variational_solver
from ..planning.plan import Plan, PlanError
from .pool import SolverPool
from .workers import Death, SolverProcess, WorkerDied, solver_settings, start_fork_server

#: The axis limits of the warm-ups that build the limited NLPs of a configuration without limits
#: (``Planner.toggled_limits``): a rest-to-rest plan they leave unbounded, and a fastest plan.
SPARE_LIMITS = {'max_velocity': 0.25, 'max_acceleration': 0.5}

#: The levels of a ``WorkerEvent``, numbered as diagnostic_msgs/DiagnosticStatus numbers its own, so that a
#: node passes them on to /diagnostics as they are.
OK, WARN = 0, 1


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


@dataclass(frozen=True)
class _Due:
    """When a request's answer is due (``time.monotonic()`` s; None: it has no budget), and that budget
    for messages."""

    at: float | None
    budget: str

    def left(self) -> float | None:
        return None if self.at is None else self.at - time.monotonic()


class Planner:
    """Makes plans of every method; thread-safe, and concurrent requests run side by side.

    Variational solvers are expensive to build, so they are kept per
    (route, method, intervals, robust set, limits, time budget) in a
    ``pool.SolverPool`` of up to ``pool_size`` instances: a request takes an
    idle one, so requests (for the same method too) never queue behind each
    other. Instances beyond the first are spawned from one already built for
    the same NLP structure (``VariationalSolver.spawn``), which costs
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
    ``answer_margin``), then is refused naming ``solver_processes``. Setting
    ``warmups`` (a parameter change) has the workers build the new
    configuration's solvers in the background, one worker at a time, taken
    only when all are idle, at a lower priority still (``_upkeep_loop``). The
    worker processes start from a fork server, so a script using them needs
    the usual ``if __name__ == '__main__':`` guard (``multiprocessing``).

    A worker process that dies is replaced (the pool is kept full): found
    dead under a request, at the next request or by a watch on the idle ones
    (``_watch_loop``). A request whose worker died while solving it is run
    again once on another worker (a fresh one if one is ready in time) when
    at least ``rerun_within`` s of its time are left and a worker frees up
    before its answer is due; else it is refused naming the dead process and
    how it ended. Each such event goes to ``on_event`` (a ``WorkerEvent``),
    for the operator: a node's /diagnostics.

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

    #: With worker processes, a request is answered within ``max_solve_time`` + this (s),
    #: even if its worker is still building a solver (its late answer is dropped).
    answer_margin = 0.4
    #: With worker processes, how long (s) a request without ``max_solve_time`` waits for an idle one.
    unbounded_wait = 60.0
    #: With worker processes, one of them also builds the NVF solvers of the warm-ups' rest-to-rest
    #: plans with the axis limits toggled (set, as ``SPARE_LIMITS`` and a fastest plan, where the
    #: configuration has none; unset where it has some) before it is ready: the limits decide the NLP's
    #: structure, so setting or clearing ``max_velocity`` would otherwise make the next NVF request build
    #: one in its budget, which a build alone can exhaust. RVF's are left out: its NLP is several times
    #: as costly to build, and every start-up would pay for it.
    toggled_limits = True
    #: With worker processes, a request whose worker died is run again only if at least this much (s) of its
    #: time is left: a warm solve takes tens of milliseconds, a shorter remainder would only end late.
    rerun_within = 0.1
    #: With worker processes, how often (s) the idle ones are looked at for one that died.
    watch_period = 0.5

    def __init__(self, pool_size: int = 8, pool_wait: float = 0.3, processes: int = 0, on_event=None):
        self.pool_wait = pool_wait
        self._pools: dict = {}  # VariationalSolver.key -> SolverPool
        self._seeds: dict = {}  # VariationalSolver.structure_of -> the first solver built for it
        self._lock = threading.Lock()
        self.pool_size = pool_size
        self._warmups: list = []  # what a new worker builds before serving
        self._extra: list = []  # what warm_threads asked for beyond them
        self._workers: list = []  # every worker process started, the closed ones dropped by the upkeep
        self._upkeep = None  # the thread building the workers' missing solvers (_keep_up)
        self._twins_starting = False  # a worker is starting with the toggled_limits twins
        self._built = threading.Event()  # no worker lacks what is wanted
        self._built.set()
        self._closing = threading.Event()
        self._on_event = on_event
        self._dead: deque = deque()  # the Deaths whose replacement is not ready yet, oldest first
        self._watch = None  # the thread looking for idle workers that died (_watch_loop)
        self._processes = None
        if processes:
            self._processes = SolverPool(self._new_process, check_count('solver_processes', processes), 'process',
                                         hint='raise solver_processes')
            start_fork_server()  # (from the caller's thread: the main one, for a node)

    @property
    def warmups(self) -> list[VariationalRequest]:
        """``VariationalRequest``s that build the solvers of the current configuration: a new worker
        process answers them before serving; set, the running workers build what they lack of them in
        the background."""
        return list(self._warmups)

    @warmups.setter
    def warmups(self, requests):
        with self._lock:
            self._warmups = list(requests)
        self._keep_up()

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
             params: CraneParams | None = None, options: PlanOptions | None = None, hoist=None,
             bridge: float | None = None) -> Plan:
        """A rest-to-rest plan from 0 to ``displacement`` (m) in ``duration`` (s) (``dispatch.plan``;
        ``hoist`` = (L1_start, L1_goal) moves the rope too, ``bridge`` (m) the bridge).

        Raises PlanError (or its ParameterError sibling, both ValueError) with a
        message naming the problem.
        """
        return dispatch.plan(method, displacement, duration, params, options, self._variational, hoist, bridge)

    def fastest(self, method: str, displacement: float, params: CraneParams | None = None,
                options: PlanOptions | None = None, hoist=None, bridge: float | None = None) -> Plan:
        """The shortest rest-to-rest plan of ``displacement`` (m) within the options' axis limits
        (``dispatch.fastest``)."""
        return dispatch.fastest(method, displacement, params, options, self._variational, hoist, bridge)

    def start_processes(self, ready_within: float = 60.0, all_of_them: bool = False) -> bool:
        """Start every worker process in the background (each warms up on ``warmups`` first).

        Waits up to ``ready_within`` seconds for one (or, ``all_of_them``, every
        one) to be ready and idle; whether it is (True without worker processes).
        One of them warms up on the ``toggled_limits`` twins too.
        """
        if self._processes is None:
            return True
        with self._lock:
            if self._watch is None:
                self._watch = threading.Thread(target=self._watch_loop, name='solver-watch', daemon=True)
                self._watch.start()
        return self._processes.fill(ready_within, self._processes.size if all_of_them else 1)

    def wait_built(self, timeout: float | None = None) -> bool:
        """Wait up to ``timeout`` s until every worker process has built the solvers of ``warmups`` (and
        of ``warm_threads``' requests); whether they have (True without worker processes)."""
        return self._built.wait(timeout)

    def close(self) -> None:
        """Stop the worker processes (busy ones after their request)."""
        self._closing.set()
        if self._processes is not None:
            self._processes.close()

    def warm_threads(self, requests) -> None:
        """Build the solvers of these ``VariationalRequest``s where requests are solved.

        Without worker processes: in this process's threads, now (each request
        run once). With them, never in this process (its threads answer the
        cheap requests): the workers build what they lack of them in the
        background, as for ``warmups``; this returns at once.
        """
        if self._processes is None:
            for request in requests:
                self._in_threads(request)
            return
        with self._lock:
            self._extra += [r for r in requests if r not in self._extra]
        self._keep_up()

    def variational(self, request: VariationalRequest) -> Plan:
        """Run one checked NVF/RVF request (e.g. a plan from a state, ``serving.transitions``) like
        ``plan`` runs its own: in a worker process, else in a pooled solver."""
        return self._variational(request)

    def _variational(self, request: VariationalRequest) -> Plan:
        """An NVF/RVF request in a worker process (if there are workers), else in a thread; once again on
        another worker if its worker dies solving it (``_rerun``)."""
        if self._processes is None:
            return self._in_threads(request)
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
        self._reap_idle()
        left = due.left()
        try:
            return self._processes.take(self.unbounded_wait if left is None else max(left - 0.05, 0.0),
                                        prefer=lambda w: w.has(request))
        except PlanError as exc:
            dead = list(self._dead)
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
            self._dead.append(exc.death)  # (before it goes back: its replacement reports this one)
            raise
        finally:
            if worker.late:
                threading.Thread(target=self._finish_late, args=(worker,), daemon=True).start()
            else:
                self._processes.give_back(worker)

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
        self._report(WARN, 're-run', death, f'{death} while solving an {request.method.upper()} request; re-run '
                     f'on solver process {worker.pid}; {_REPLACED}', worker.pid)
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
        self._report(WARN, 'refused', death, f'{message}; {_REPLACED}')
        return PlanError(message)

    def _finish_late(self, worker: SolverProcess) -> None:
        """Back to the pool once a timed-out request's answer is in (reported if it died meanwhile)."""
        death = worker.finish_late()
        if death is not None:
            self._dead.append(death)
            self._report(WARN, 'replaced', death, f'{death} while finishing a request that had timed out; '
                                                  f'{_REPLACED}')
        self._processes.give_back(worker)

    # -- workers that die ----------------------------------------------------------------------------

    def _reap_idle(self) -> None:
        """Take the idle workers that died out of the pool (it starts new ones), and report them."""
        for worker in self._processes.discard_idle(SolverProcess.gone):
            death = worker.died()
            self._dead.append(death)
            self._report(WARN, 'replaced', death, f'{death} while idle; {_REPLACED}')

    def _watch_loop(self) -> None:
        """Every ``watch_period`` s, the idle workers that died replaced: a killed worker is replaced before
        a request finds it dead (a busy one's death is found by its request, a building one's by the upkeep)."""
        while not self._closing.wait(self.watch_period):
            self._reap_idle()

    def _report(self, level: int, action: str, death: Death, message: str, new_pid: int = 0) -> None:
        """``on_event`` told, if given; a failure of it never reaches the request."""
        if self._on_event is None:
            return
        try:
            self._on_event(WorkerEvent(level, action, death, message, new_pid))
        except Exception:
            pass

    # -- the worker processes' solvers ---------------------------------------------------------------

    def _new_process(self) -> SolverProcess:
        """A worker process, warmed up on ``warmups``; the upkeep adds the rest of what is wanted.

        While no live worker has the ``toggled_limits`` twins, the new one builds them before it is ready
        too: a limit set or cleared then finds a worker that needs no build for an NVF request (requests
        prefer one that has their NLP; the upkeep takes it last), and a single worker pays for it (a build's
        CPU), not every one.
        """
        with self._lock:
            twins = self.toggled_limits and not self._twins_starting and not any(
                w.has(r) for w in self._workers if not w.closed for r in toggled_limits(self._warmups)
                if r.method == 'nvf')
            self._twins_starting |= twins
        warmups = self.warmups
        if twins:
            warmups += [r for r in toggled_limits(warmups) if r.method == 'nvf' and r not in warmups]
        try:
            worker = SolverProcess(warmups)
        finally:
            if twins:
                with self._lock:
                    self._twins_starting = False
        with self._lock:
            self._workers.append(worker)
        self._started(worker)
        self._keep_up()
        return worker

    def _started(self, worker: SolverProcess) -> None:
        """A new worker ready: if it replaces one that died, reported (level OK: the pool is whole again
        once every dead one has its replacement)."""
        try:
            death = self._dead.popleft()
        except IndexError:  # one of the first ones
            return
        self._report(OK, 'started', death, f'solver process {worker.pid} started in place of solver process '
                                           f'{death.pid}, which died ({death.cause})', worker.pid)

    def _wanted(self) -> list:
        """What every worker should have built: the warm-ups and ``warm_threads``' requests."""
        return list(self._warmups) + [r for r in self._extra if r not in self._warmups]

    def _keep_up(self) -> None:
        """Have the upkeep thread (started if none runs) look again at what the workers lack."""
        if self._processes is None:
            return
        with self._lock:
            self._built.clear()
            if self._upkeep is not None:
                return
            self._upkeep = threading.Thread(target=self._upkeep_loop, name='solver-upkeep', daemon=True)
        self._upkeep.start()

    def _upkeep_loop(self) -> None:
        """Until every live worker has built what is wanted: when every worker is idle (no request is being
        solved or waits), take one that lacks some, have it build one request's solvers (at a low CPU
        priority, ``workers.WARM_NICE``), give it back. One request at a time, so a worker is back in the
        pool after at most one build and the others serve meanwhile."""
        while not self._closing.is_set():
            with self._lock:
                wanted = self._wanted()
                self._workers = [w for w in self._workers if not w.closed]
                if not any(w.needs(wanted) for w in self._workers):
                    self._upkeep = None
                    self._built.set()
                    return
            # the one lacking most NLP structures first: one that has them (the twins) stays for requests
            worker = self._processes.take_idle(lambda w: bool(w.needs(wanted)), keep=self._processes.size - 1,
                                               rank=lambda w: sum(not w.has(r) for r in wanted))
            if worker is None:  # a worker is busy with a request: the others stay free for the next ones
                self._closing.wait(0.05)
                continue
            try:
                worker.warm(worker.needs(wanted)[:1])
            except WorkerDied as exc:  # the pool replaces it, and the replacement is looked at
                self._dead.append(exc.death)
                self._report(WARN, 'replaced', exc.death, f'{exc}; {_REPLACED}')
            except PlanError:  # it was killed (too slow): the pool replaces it too
                pass
            finally:
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


#: What every report of a death ends with: the pool is kept full.
_REPLACED = 'replaced: a new solver process is starting in its place'


def toggled_limits(requests) -> list[VariationalRequest]:
    """The rest-to-rest direct-route plans among ``requests`` with the axis limits toggled: the cart's set
    to ``SPARE_LIMITS`` (and a fastest plan) where no axis has one, every axis's cleared where some have."""
    twins = []
    for request in requests:
        options = request.options
        if (options.solver != 'direct' or request.operation != 'plan' or request.start is not None
                or request.free_end or not isinstance(request.displacement, float | int)):
            continue
        flat = {name: None for name in ('max_velocity', 'max_acceleration', 'max_jerk', 'max_hoist_velocity',
                                        'max_hoist_acceleration', 'max_hoist_jerk')}
        if any(limits.any for limits in options.limits):
            cleared = dataclasses.replace(options, base='quintic', limits=(), **flat)
            twins.append(dataclasses.replace(request, options=cleared))
        else:
            limited = dataclasses.replace(options, limits=(), **{**flat, **SPARE_LIMITS})
            twins += [dataclasses.replace(request, options=limited),
                      dataclasses.replace(request, operation='fastest', duration=None, options=limited)]
    return twins
