"""The worker processes of a ``Planner``: started warm, kept full, and building in the background what a
parameter change wants.

``WorkerProcesses`` owns the ``pool.SolverPool`` of ``workers.SolverProcess``es: a new one warms up on
``warmups`` first (one of them on the ``toggled_limits`` twins too); setting ``warmups`` (a parameter
change) or asking ``warm`` has the running ones build what they lack, one worker and one request at a
time, taken only when all are idle (``_upkeep_loop``); an idle one that died is replaced
(``_watch_loop``). Requests go to them through ``worker_dispatch.WorkerDispatch``. Pure Python, no ROS
import.
"""
from __future__ import annotations

import dataclasses
import threading

from crane_msgs_py.crane.axes import AXES
from crane_msgs_py.crane.params import check_count

from ..planning.dispatch import VariationalRequest
from ..planning.plan import PlanError
from .pool import SolverPool
from .worker_events import Deaths
from .workers import SolverProcess, WorkerDied, start_fork_server

#: The axis limits of the warm-ups that build the limited NLPs of a configuration without limits
#: (``WorkerProcesses.toggled_limits``): a rest-to-rest plan they leave unbounded, and a fastest plan.
SPARE_LIMITS = {'max_velocity': 0.25, 'max_acceleration': 0.5}


class WorkerProcesses:
    """``processes`` worker processes, each with its own solvers, and what they should have built.

    Args:
        processes: how many, >= 1.
        deaths: where the deaths found are kept and reported.
    """

    #: One of them also builds the NVF solvers of the warm-ups' rest-to-rest plans with the axis limits
    #: toggled (set, as ``SPARE_LIMITS`` and a fastest plan, where the configuration has none; unset where it
    #: has some) before it is ready: the limits decide the NLP's structure, so setting or clearing
    #: ``max_velocity`` would otherwise make the next NVF request build one in its budget, which a build alone
    #: can exhaust. RVF's are left out: its NLP is several times as costly to build, and every start-up would
    #: pay for it. Set before the workers start.
    toggled_limits = True
    #: How often (s) the idle ones are looked at for one that died.
    watch_period = 0.5

    def __init__(self, processes: int, deaths: Deaths):
        self.deaths = deaths
        self.warmups: list = []  # what a new worker builds before serving
        self._extra: list = []  # what warm asked for beyond them
        self.workers: list = []  # every worker process started, the closed ones dropped by the upkeep
        self._upkeep = None  # the thread building the workers' missing solvers (_keep_up)
        self._twins_starting = False  # a worker is starting with the toggled_limits twins
        self._built = threading.Event()  # no worker lacks what is wanted
        self._built.set()
        self._closing = threading.Event()
        self._watch = None  # the thread looking for idle workers that died (_watch_loop)
        self._lock = threading.Lock()
        self.pool = SolverPool(self._new_process, check_count('solver_processes', processes), 'process',
                               hint='raise solver_processes')
        start_fork_server()  # (from the caller's thread: the main one, for a node)

    def want(self, warmups) -> None:
        """The solvers of these requests are what every worker builds (a new one before serving)."""
        with self._lock:
            self.warmups = list(warmups)
        self.keep_up()

    def warm(self, requests) -> None:
        """These requests' solvers built too, by every worker, in the background."""
        with self._lock:
            self._extra += [r for r in requests if r not in self._extra]
        self.keep_up()

    def start(self, ready_within: float, all_of_them: bool) -> bool:
        """Start every worker in the background; whether one (every one) is ready within ``ready_within`` s."""
        with self._lock:
            if self._watch is None:
                self._watch = threading.Thread(target=self._watch_loop, name='solver-watch', daemon=True)
                self._watch.start()
        return self.pool.fill(ready_within, self.pool.size if all_of_them else 1)

    def wait_built(self, timeout: float | None = None) -> bool:
        return self._built.wait(timeout)

    def close(self) -> None:
        self._closing.set()
        self.pool.close()

    def reap_idle(self) -> None:
        """Take the idle workers that died out of the pool (it starts new ones), and report them."""
        for worker in self.pool.discard_idle(SolverProcess.gone):
            death = worker.died()
            self.deaths.replaced(death, f'{death} while idle')

    def _watch_loop(self) -> None:
        """Every ``watch_period`` s, the idle workers that died replaced: a killed worker is replaced before
        a request finds it dead (a busy one's death is found by its request, a building one's by the upkeep)."""
        while not self._closing.wait(self.watch_period):
            self.reap_idle()

    def _new_process(self) -> SolverProcess:
        """A worker process, warmed up on ``warmups``; the upkeep adds the rest of what is wanted.

        While no live worker has the ``toggled_limits`` twins, the new one builds them before it is ready
        too: a limit set or cleared then finds a worker that needs no build for an NVF request (requests
        prefer one that has their NLP; the upkeep takes it last), and a single worker pays for it (a build's
        CPU), not every one.
        """
        with self._lock:
            twins = self.toggled_limits and not self._twins_starting and not any(
                w.has(r) for w in self.workers if not w.closed for r in toggled_limits(self.warmups)
                if r.method == 'nvf')
            self._twins_starting |= twins
            warmups = list(self.warmups)
        if twins:
            warmups += [r for r in toggled_limits(warmups) if r.method == 'nvf' and r not in warmups]
        try:
            worker = SolverProcess(warmups)
        finally:
            if twins:
                with self._lock:
                    self._twins_starting = False
        with self._lock:
            self.workers.append(worker)
        self.deaths.started(worker)
        self.keep_up()
        return worker

    def _wanted(self) -> list:
        """What every worker should have built: the warm-ups and ``warm``'s requests."""
        return list(self.warmups) + [r for r in self._extra if r not in self.warmups]

    def keep_up(self) -> None:
        """Have the upkeep thread (started if none runs) look again at what the workers lack."""
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
                self.workers = [w for w in self.workers if not w.closed]
                if not any(w.needs(wanted) for w in self.workers):
                    self._upkeep = None
                    self._built.set()
                    return
            # the one lacking most NLP structures first: one that has them (the twins) stays for requests
            worker = self.pool.take_idle(lambda w: bool(w.needs(wanted)), keep=self.pool.size - 1,
                                         rank=lambda w: sum(not w.has(r) for r in wanted))
            if worker is None:  # a worker is busy with a request: the others stay free for the next ones
                self._closing.wait(0.05)
                continue
            try:
                worker.warm(worker.needs(wanted)[:1])
            except WorkerDied as exc:  # the pool replaces it, and the replacement is looked at
                self.deaths.replaced(exc.death, str(exc))
            except PlanError:  # it was killed (too slow): the pool replaces it too
                pass
            finally:
                self.pool.give_back(worker)


def toggled_limits(requests) -> list[VariationalRequest]:
    """The rest-to-rest direct-route plans among ``requests`` with the axis limits toggled: the cart's set
    to ``SPARE_LIMITS`` (and a fastest plan) where no axis has one, every axis's cleared where some have."""
    twins = []
    for request in requests:
        options = request.options
        if (options.solver != 'direct' or request.operation != 'plan' or request.start is not None
                or request.free_end or not isinstance(request.displacement, float | int)):
            continue
        flat = {name: None for axis in AXES for name in axis.limit_names}  # every axis's, the bridge's too
        if any(limits.any for limits in options.limits):
            cleared = dataclasses.replace(options, base='quintic', limits=(), **flat)
            twins.append(dataclasses.replace(request, options=cleared))
        else:
            limited = dataclasses.replace(options, limits=(), **{**flat, **SPARE_LIMITS})
            twins += [dataclasses.replace(request, options=limited),
                      dataclasses.replace(request, operation='fastest', duration=None, options=limited)]
    return twins
