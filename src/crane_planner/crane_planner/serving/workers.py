"""NVF/RVF solves in worker processes, so that no solve waits on another's linear algebra.

Why processes: IPOPT serializes every MUMPS call of a process behind one
mutex (MUMPS keeps Fortran state), so two solves in threads of one process
take turns at each factorization; a 15 ms solve beside one that runs to its
1 s budget took 40-300 ms. Each worker is a process of its own (its own
MUMPS), running one ``dispatch.VariationalRequest`` at a time on its own
solvers (``dispatch.SolverCache``) and keeping them and their warm starts
between requests.

Workers start from a fork server that has imported CasADi and the planning
core once (``multiprocessing`` "forkserver": a clean process, never a fork
of the caller's threads, e.g. rclpy's), so a new worker costs ~20 ms plus
building its solvers. A worker ignores SIGINT (Ctrl-C is the parent's to
handle) and ends when its parent's end of the pipe closes.

Pure Python, no ROS import.
"""
from __future__ import annotations

import multiprocessing
import signal
import threading

from crane_msgs_py.params import ParameterError

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
        return _CONTEXT


def _serve(conn, warmups) -> None:
    """A worker's life: warm up, say ready, then answer requests until the pipe closes or None arrives."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    from ..planning.dispatch import SolverCache
    from .yielding import YieldingCallback
    solvers = SolverCache(iteration_callback=YieldingCallback)  # workers serve the direct route only
    for request in warmups:  # a failed warm-up only means building on first use
        try:
            solvers(request)
        except Exception:
            pass
    try:
        conn.send(('ready', None))
        while True:
            request = conn.recv()
            if request is None:
                return
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


class SolverProcess:
    """One worker process; ``solve`` sends it a request and waits for the answer. One caller at a time.

    Args:
        warmups: ``VariationalRequest``s (as ``solve`` takes them) the
            worker answers before it is ready, so that its first real request
            finds its solvers built.
        start_timeout: longest wait (s) for the worker to be ready.
    """

    def __init__(self, warmups=(), start_timeout: float = 60.0):
        ctx = _context()
        self._conn, child = ctx.Pipe()
        self._process = ctx.Process(target=_serve, args=(child, list(warmups)), name='crane-solver', daemon=True)
        self._process.start()
        child.close()
        self.closed = False
        #: a request timed out and its answer is still to come (``finish_late``)
        self.late = False
        try:
            ready = self._conn.poll(start_timeout) and self._conn.recv()[0] == 'ready'
        except (EOFError, OSError):
            ready = False
        if not ready:
            self.close()
            raise PlanError(f'a solver process did not start within {start_timeout:g} s')

    @property
    def pid(self) -> int:
        return self._process.pid

    @property
    def alive(self) -> bool:
        return not self.closed and self._process.is_alive()

    def solve(self, request, timeout: float | None):
        """A ``dispatch.VariationalRequest`` run in the worker: its plan, or its PlanError/ParameterError
        raised here.

        PlanError too if the worker does not answer within ``timeout`` seconds
        (None = no limit; it is then ``late`` until ``finish_late``), or if it
        dies (it is then ``closed``; a kept-full pool replaces it).
        """
        try:
            self._conn.send(request)
            if not self._conn.poll(timeout):
                self.late = True
                raise PlanError(f'no answer within {timeout:.2f} s (the solver was still building or solving)')
            kind, value = self._conn.recv()
        except (EOFError, OSError):
            self.close(kill=True)
            code = self._process.exitcode
            raise PlanError(f'the solver process ended while solving (exit code {code}) and was restarted') from None
        if kind == 'plan':
            return value
        if kind in _ERRORS:
            raise _ERRORS[kind](value)
        raise RuntimeError(value)

    def finish_late(self, limit: float = 60.0) -> None:
        """Wait for the answer of a timed-out request and drop it; kill the worker if it takes over ``limit`` s."""
        try:
            if self._conn.poll(limit):
                self._conn.recv()
                self.late = False
                return
        except (EOFError, OSError):
            pass
        self.close(kill=True)

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
        self._process.join(timeout=0.0 if kill else 0.5)
        if self._process.is_alive():
            self._process.kill()
            self._process.join(timeout=1.0)
