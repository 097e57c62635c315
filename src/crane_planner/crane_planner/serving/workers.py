"""NVF/RVF solves in worker processes, so that no solve waits on another's linear algebra.

Why processes: IPOPT serializes every MUMPS call of a process behind one
mutex (MUMPS keeps Fortran state), so two solves in threads of one process
take turns at each factorization, and a short solve beside one that runs to
its budget takes many times as long. Each worker is a process of its own (its own
MUMPS), running one ``dispatch.VariationalRequest`` at a time on its own
solvers (``SharedSolvers``: a new key of a known NLP structure is a spawn)
and keeping them and their warm starts between requests. Building and
solving there also keeps CasADi and IPOPT off the caller's interpreter lock,
and a worker runs at a lower CPU priority (``WORKER_NICE``) than the caller
answering cheap requests; it builds a parameter change's solvers on request
(``SolverProcess.warm``) at a lower one still.

Workers start from a fork server that has imported CasADi and the planning
core once (``multiprocessing`` "forkserver": a clean process, never a fork
of the caller's threads, e.g. rclpy's), so a new worker costs little beyond
building its solvers. A worker ignores SIGINT (Ctrl-C is the parent's to
handle) and ends when its parent's end of the pipe closes.

A worker can die under a request (the kernel's OOM killer, an operator's
``kill -9``, a crash in native code): ``solve`` then raises ``WorkerDied``
(a PlanError) carrying a ``Death``, the process's pid and, as far as it is
known, the signal that ended it, so the caller can say what happened and
decide whether to run the request again elsewhere. The fork server can die
too: Python starts it again on the next worker start, but one killed a moment
earlier is not reaped yet and still looks alive, so that start fails; it is
tried again (``_start``) once the dead server can be seen as dead.

Pure Python, no ROS import.
"""
from __future__ import annotations

import multiprocessing.connection
import multiprocessing.context
import os
import signal
import threading
import time
from collections import OrderedDict
from dataclasses import dataclass
from multiprocessing import popen_forkserver

from crane_msgs_py.crane.params import ParameterError

from ..planning.plan import PlanError

#: Modules the fork server imports before forking workers: CasADi and the whole solver.
_PRELOAD = ['crane_planner.planning.dispatch', 'crane_planner.planning.direct', 'crane_planner.planning.free_time',
            'crane_planner.serving.yielding']
_CONTEXT = None
_CONTEXT_LOCK = threading.Lock()
#: exceptions a worker reports by name, raised again in the caller
_ERRORS = {'PlanError': PlanError, 'ParameterError': ParameterError}


def _context():
    global _CONTEXT
    with _CONTEXT_LOCK:
        if _CONTEXT is None:
            _CONTEXT = multiprocessing.get_context('forkserver')
            _CONTEXT.set_forkserver_preload(_PRELOAD)
            _start_forkserver()
        return _CONTEXT


def _start_forkserver() -> None:
    """Start the fork server with SIGINT ignored, if called from the main thread (see ``start_fork_server``).

    The fork server protects itself from Ctrl-C only once it has imported ``_PRELOAD`` (which takes a
    while): a node stopped by SIGINT to its process group (Ctrl-C in a terminal, a launcher) meanwhile
    would have it die with a KeyboardInterrupt traceback. An ignored signal stays ignored across the
    server's exec (and Python keeps it so), and the workers it forks inherit that.
    """
    from multiprocessing import forkserver
    if threading.current_thread() is not threading.main_thread():  # (only the main thread sets handlers)
        forkserver.ensure_running()
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        forkserver.ensure_running()
    finally:
        signal.signal(signal.SIGINT, previous)


def start_fork_server() -> None:
    """Start the workers' fork server now; from the main thread, immune to SIGINT while it loads CasADi.

    Workers are usually started from background threads; a caller that will start some calls this first
    from its main thread (a node's constructor), so that stopping the node with Ctrl-C early leaves no
    traceback of a half-loaded fork server."""
    _context()


def solver_settings(options) -> dict:
    """The settings of every solver that serves beside others: the direct route's solves pace each other
    (``yielding.YieldingCallback``).

    Imported here, not at the top: CasADi loads only when a variational plan is asked for.
    """
    if options.solver != 'direct':
        return {}
    from .yielding import YieldingCallback
    return {'iteration_callback': YieldingCallback}


class SharedSolvers:
    """NVF/RVF solvers kept per ``VariationalSolver.key``, with their warm starts, one caller at a time
    (a worker's): a ``dispatch.Variational``.

    A request whose key is new but whose NLP structure (``VariationalSolver.structure_of``) is known
    gets a spawn of the first solver of that structure: a new limit value or time budget (a
    parameter change) costs a small fraction of a build of its NLP. Beyond
    ``keep`` solvers the least recently used spawn is dropped (the first of each structure stays).
    """

    keep = 32

    def __init__(self):
        self._solvers: OrderedDict = OrderedDict()  # key -> solver, the most recently used last
        self._seeds: dict = {}  # structure -> the first solver built for it

    def __call__(self, request):
        from ..planning.dispatch import variational_solver
        from ..planning.variational import VariationalSolver
        key = VariationalSolver.key(request.method, request.options)
        solver = self._solvers.get(key)
        if solver is None:
            structure = VariationalSolver.structure_of(request.method, request.options)
            seed = self._seeds.get(structure)
            solver = (seed.spawn(request.options) if seed is not None else
                      variational_solver(request.method, request.options, **solver_settings(request.options)))
            self._seeds.setdefault(structure, solver)
            self._solvers[key] = solver
            while len(self._solvers) > self.keep:
                self._solvers.popitem(last=False)
        self._solvers.move_to_end(key)
        return request.run(solver)


def _structure(request) -> tuple:
    from ..planning.variational import VariationalSolver
    return VariationalSolver.structure_of(request.method, request.options)


def _warm(solvers, requests) -> None:
    for request in requests:  # a failed warm-up only means building on first use
        try:
            solvers(request)
        except Exception:
            pass


#: What a worker process adds to the nice value it inherits from its caller: its solves and builds
#: (long runs of CPU) yield a shared core to the caller answering the cheap requests (a shaper's
#: plan, a little Python across a few executor threads); alone on a core it runs as fast. Two
#: steps (~1.6x the caller's share against it), not more: against other processes of the host at the
#: caller's priority a worker must still solve a typical request within its budget.
WORKER_NICE = 2
#: What the thread building solvers on request (``SolverProcess.warm``) adds to the caller's nice value:
#: requests being solved get the cores before it.
WARM_NICE = 10


def _warm_niced(solvers, requests) -> None:
    """``_warm`` on a thread of its own at ``WARM_NICE`` (Linux sets a nice value per thread; one that
    ends needs no privilege to be raised back), the worker's main thread waiting for it."""
    def run():
        try:  # a new thread starts at the worker's nice value, WORKER_NICE above the caller's
            tid = threading.get_native_id()
            os.setpriority(os.PRIO_PROCESS, tid, min(19, os.getpriority(os.PRIO_PROCESS, tid)
                                                     + WARM_NICE - WORKER_NICE))
        except (AttributeError, OSError):  # not Linux, or not permitted: build at the worker's own priority
            pass
        _warm(solvers, requests)
    builder = threading.Thread(target=run, name='solver-build')
    builder.start()
    builder.join()


def _serve(conn, warmups) -> None:
    """A worker's life: warm up, say ready, then answer requests until the pipe closes or None arrives.

    A request is a ``VariationalRequest`` (answered with its plan or its refusal), or ``('warm',
    requests)``: build these (a parameter change), answered ``('warmed', None)``.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        os.nice(WORKER_NICE)
    except OSError:
        pass
    solvers = SharedSolvers()
    _warm(solvers, warmups)
    try:
        conn.send(('ready', None))
        while True:
            request = conn.recv()
            if request is None:
                return
            if isinstance(request, tuple) and request[0] == 'warm':
                _warm_niced(solvers, request[1])
                conn.send(('warmed', None))
                continue
            try:
                # a callable request (``stops.StopRequest``) runs on the worker's solvers and answers itself
                reply = ('plan', request(solvers) if callable(request) else solvers(request))
            except (PlanError, ParameterError) as exc:
                reply = (type(exc).__name__, str(exc))
            except Exception as exc:  # a solver bug: the caller reports it, the worker lives on
                reply = ('internal', f'{type(exc).__name__}: {exc}')
            conn.send(reply)
    except (EOFError, OSError):  # the parent is gone
        return


@dataclass(frozen=True)
class Death:
    """A worker process that ended without being asked to, as its caller learns of it.

    ``exitcode`` is ``multiprocessing``'s: negative for the signal that ended it, 255 when the fork server
    (the worker's parent, which reports the status) died too, None if it had not been reported yet.
    """

    pid: int
    exitcode: int | None

    #: the exit code ``multiprocessing`` gives a worker whose fork server is gone (our workers never exit so)
    SERVER_GONE = 255

    @property
    def signal(self) -> int | None:
        """The number of the signal that ended it, if it is known."""
        return -self.exitcode if self.exitcode is not None and self.exitcode < 0 else None

    @property
    def cause(self) -> str:
        """How it ended, as far as is known: 'signal 9', 'exit code 1' or why that is unknown."""
        if self.signal is not None:
            return f'signal {self.signal}'
        if self.exitcode == self.SERVER_GONE:
            return 'exit status unknown: its fork server died too'
        if self.exitcode is None:
            return 'exit status not reported'
        return f'exit code {self.exitcode}'

    def __str__(self) -> str:
        return f'the solver process {self.pid} died ({self.cause})'


class WorkerDied(PlanError):
    """The worker died before answering (its pipe closed): a PlanError saying so, with the ``death``.

    A PlanError, so that a caller that only refuses (``stops.StopWorker``) needs nothing new; the
    planner catches it to run the request again on another worker."""

    def __init__(self, death: Death, doing: str):
        super().__init__(f'{death} while {doing}')
        self.death = death
        self.doing = doing


class WorkerLate(PlanError):
    """The worker did not answer within the caller's timeout (it is ``late`` until ``finish_late``)."""


#: Waits (s) before starting a worker again when its start failed for want of a live fork server: a
#: server killed a moment ago is not reaped yet, so Python sends the request to it and reads EOF; a
#: moment later it is seen dead and started anew.
START_RETRIES = (0.05, 0.2, 0.5, 1.0)
#: Longest wait (s) for a dead worker's exit status (its fork server reports it within milliseconds).
STATUS_WAIT = 0.5


class _Popen(popen_forkserver.Popen):
    """``multiprocessing``'s fork-server ``Popen``, its exit-status read one thread's at a time.

    It reads a child's status from a pipe once, in whichever thread polls first, and ``Process.start`` polls
    every child: of two threads polling one process at once the second read an EOF and took it for the fork
    server's death (exit code 255). The lock is held only while the status is read: it is there to be read
    once the process's sentinel is ready, and ``_exitcode`` waits for that first.
    """

    def __init__(self, process_obj):
        self._polling = threading.Lock()
        super().__init__(process_obj)

    def poll(self, flag=os.WNOHANG):
        with self._polling:
            return super().poll(flag)


class _WorkerProcess(multiprocessing.context.ForkServerProcess):
    """A fork-server process whose exit status threads may poll at once (``_Popen``)."""

    @staticmethod
    def _Popen(process_obj):
        return _Popen(process_obj)


def _exitcode(process, wait: float) -> int | None:
    """``process``'s exit code once it has ended, waited for up to ``wait`` s (None: still running)."""
    multiprocessing.connection.wait([process.sentinel], wait)
    return process.exitcode


class SolverProcess:
    """One worker process; ``solve`` sends it a request and waits for the answer. One caller at a time.

    Args:
        warmups: ``VariationalRequest``s (as ``solve`` takes them) the
            worker answers before it is ready, so that its first real request
            finds its solvers built.
        start_timeout: longest wait (s) for the worker to be ready.
    """

    def __init__(self, warmups=(), start_timeout: float = 60.0):
        self._conn, self._process = self._start(list(warmups))
        self.closed = False
        #: a request timed out and its answer is still to come (``finish_late``)
        self.late = False
        #: the warm-ups it has run (at its start and by ``warm``)
        self.warmed: list = list(warmups)
        #: the NLP structures (``VariationalSolver.structure_of``) it has solvers of: a request of one
        #: of these is a spawn at most, never a build
        self.structures: set = {_structure(r) for r in self.warmed}
        try:
            ready = self._conn.poll(start_timeout) and self._conn.recv()[0] == 'ready'
        except (EOFError, OSError):
            ready = False
        if not ready:
            self.close()
            raise PlanError(f'a solver process did not start within {start_timeout:g} s')

    @staticmethod
    def _start(warmups: list):
        """(our end of the pipe, the started process); a start that finds the fork server just died is
        tried again after ``START_RETRIES`` (see the module's docstring), then PlanError."""
        ctx = _context()
        for delay in (*START_RETRIES, None):
            conn, child = ctx.Pipe()
            process = _WorkerProcess(target=_serve, args=(child, warmups), name='crane-solver', daemon=True)
            try:
                process.start()
                return conn, process
            except (EOFError, OSError) as exc:
                conn.close()
                if delay is None:
                    raise PlanError(f'a solver process could not be started: {type(exc).__name__}: {exc}') from None
                time.sleep(delay)
            finally:
                child.close()

    @property
    def pid(self) -> int:
        return self._process.pid

    def gone(self) -> bool:
        """Whether an idle worker (no answer owed, not ``late``) has died: its end of the pipe can be read
        only at EOF then. For a pool to drop dead workers before a request is sent to one."""
        if self.closed:
            return True
        try:
            return self._conn.poll(0)
        except (EOFError, OSError):
            return True

    def died(self) -> Death:
        """Close a worker found dead and say how it ended (its status waited for up to ``STATUS_WAIT`` s)."""
        death = Death(self.pid, _exitcode(self._process, STATUS_WAIT))
        self.close(kill=death.exitcode is None)  # (a process already reported dead is not signalled again)
        return death

    @property
    def alive(self) -> bool:
        return not self.closed and self._process.is_alive()

    def has(self, request) -> bool:
        """Whether the worker has a solver of the request's NLP structure (so it builds none for it)."""
        return _structure(request) in self.structures

    def needs(self, requests) -> list:
        """Those of ``requests`` it has not run as warm-ups."""
        return [r for r in requests if r not in self.warmed]

    def warm(self, requests, limit: float = 600.0) -> None:
        """Have the worker run ``requests`` to build their solvers (a failed one only means building on
        first use); PlanError if it does not finish within ``limit`` s (it is then killed), WorkerDied if
        it dies."""
        requests = list(requests)
        try:
            self._conn.send(('warm', requests))
            if self._conn.poll(limit):
                self._conn.recv()
                self.warmed += requests
                self.structures.update(_structure(r) for r in requests)
                return
        except (EOFError, OSError):
            raise WorkerDied(self.died(), 'building solvers') from None
        self.close(kill=True)
        raise PlanError(f'a solver process did not finish building its solvers within {limit:g} s')

    def solve(self, request, timeout: float | None):
        """A ``dispatch.VariationalRequest`` run in the worker: its plan, or its PlanError/ParameterError
        raised here.

        PlanError too if the worker does not answer within ``timeout`` seconds
        (None = no limit; it is then ``late`` until ``finish_late``), and
        WorkerDied if it dies (it is then ``closed``; a kept-full pool replaces it).
        """
        if not callable(request):  # (a callable request, a stop, is run whole in the worker: no CasADi here)
            self.structures.add(_structure(request))  # built by this request if it was not
        try:
            self._conn.send(request)
            if not self._conn.poll(timeout):
                self.late = True
                raise WorkerLate(f'no answer within {timeout:.2f} s (the solver was still building or solving)')
            kind, value = self._conn.recv()
        except (EOFError, OSError):
            raise WorkerDied(self.died(), 'solving') from None
        if kind == 'plan':
            return value
        if kind in _ERRORS:
            raise _ERRORS[kind](value)
        raise RuntimeError(value)

    def finish_late(self, limit: float = 60.0) -> Death | None:
        """Wait for the answer of a timed-out request and drop it; kill the worker if it takes over ``limit`` s.
        How it ended if it died meanwhile (it is then ``closed``), else None."""
        try:
            if self._conn.poll(limit):
                self._conn.recv()
                self.late = False
                return None
        except (EOFError, OSError):
            return self.died()
        self.close(kill=True)
        return None

    def close(self, kill: bool = False) -> None:
        """Stop the worker: at once with ``kill``, else after its current request; idempotent."""
        if self.closed:
            return
        self.closed = True
        if kill:
            self._process.kill()
        try:
            self._conn.send(None)  # an idle worker ends by itself
        except OSError:
            pass
        self._conn.close()
        if _exitcode(self._process, 0.0 if kill else 0.5) is None:
            self._process.kill()
            _exitcode(self._process, 1.0)
