"""A pool of interchangeable solvers, so that concurrent requests never queue behind each other.

One solver instance serves one request at a time (an IPOPT instance keeps
per-call state, and its warm start is its last solution). A ``SolverPool``
hands each request an idle instance. Beyond the first, instances are built
lazily, up to ``size``: a spare in the background when the last idle one
is lent (so a request beside a long solve does not pay for a build, which
takes far longer than a typical solve), and one in the request when every
existing one stays busy for ``grace`` seconds (each instance holds a few
MB). A request that finds ``size`` instances busy waits at most ``wait``
seconds for one to come back, then is refused: answering late would break
the planner's answer-time promise. ``fill`` makes all ``size`` up front and
keeps them (an instance that reports itself ``closed``, or that
``discard_idle`` finds broken, is dropped and replaced; a replacement that
fails to start is tried again a few times): for instances too slow to make
on demand, such as worker processes (``workers.SolverProcess``). Pure
Python, no ROS import.
"""
from __future__ import annotations

import threading
import time
from contextlib import contextmanager

from crane_msgs_py.crane.params import check_count

from ..planning.plan import PlanError


class SolverPool:
    """Up to ``size`` solvers made by ``create()``, each lent to one caller at a time; thread-safe.

    Kept full (``fill``), a replacement whose ``create()`` fails is tried again after each of
    ``retry_delays`` (s): a worker process's start can fail while its fork server restarts, and a pool
    one short would have the next request start a process on its own time.

    Args:
        create: makes a new instance (called outside the pool's lock).
        size: most instances at once, >= 1; may be changed while in use
            (instances beyond a smaller size are dropped as they come back).
        name: what the instances solve, for the refusal message.
        grace: how long (s) a request waits for a busy instance before a new
            one is made (about as long as a typical NVF/RVF solve: a short wait usually finds one idle).
        hint: what the refusal advises when all stay busy.
    """

    retry_delays = (0.5, 2.0, 5.0)

    def __init__(self, create, size: int, name: str = 'solver', grace: float = 0.02,
                 hint: str = 'raise solver_pool_size'):
        self._create, self.name, self.grace, self.hint = create, name, grace, hint
        self._idle: list = []  # the most recently returned last: its warm start is the freshest
        self._count = 0  # instances in existence (idle, lent or being made)
        self._keep_full = self._closing = False
        self._upkept: set = set()  # ids of instances lent by take_idle: busy, but not with a request
        self._waiting = 0  # callers of take waiting for an instance
        self._cond = threading.Condition()
        self.size = size

    @property
    def size(self) -> int:
        return self._size

    @size.setter
    def size(self, size: int):
        size = check_count('pool size', size)
        with self._cond:
            self._size = size
            self._cond.notify_all()  # a larger pool frees waiting callers

    @property
    def instances(self) -> int:
        """Instances in existence (idle, lent or being made)."""
        return self._count

    def fill(self, ready_within: float = 0.0, count: int = 1) -> bool:
        """Make instances up to ``size`` in the background, and from now on replace those that close.

        Waits up to ``ready_within`` seconds for ``count`` to be idle (or lent by ``take_idle``); whether
        they are.
        """
        with self._cond:
            self._keep_full = True
            missing = self._size - self._count
            self._count += max(missing, 0)
        for _ in range(missing):
            self._make_spare_in_background()
        with self._cond:
            return bool(self._cond.wait_for(lambda: len(self._idle) + len(self._upkept) >= min(count, self._size),
                                            timeout=ready_within))

    def close(self) -> None:
        """Close the instances that have a ``close()``: idle ones now, lent ones when they come back."""
        with self._cond:
            self._keep_full, self._closing = False, True
            idle, self._idle = self._idle, []
            self._count -= len(idle)
        for solver in idle:
            getattr(solver, 'close', lambda: None)()

    @contextmanager
    def lend(self, wait: float):
        """An idle instance for the block (``take``, then ``give_back``)."""
        solver = self.take(wait)
        try:
            yield solver
        finally:
            self.give_back(solver)

    def take(self, wait: float, prefer=None):
        """An idle instance, to ``give_back`` when done; PlanError if ``size`` stay busy for ``wait`` s.

        ``prefer(instance)``: among idle ones, one for which it is true if there is one.
        """
        with self._cond:
            self._waiting += 1
            try:
                if self._count and not self._idle:  # a busy one may come back before a new one is worth making
                    self._cond.wait_for(lambda: self._idle, timeout=min(self.grace, wait))
                if not self._cond.wait_for(lambda: self._idle or self._count < self._size, timeout=wait):
                    raise PlanError(f'all {self._count} {self.name} solvers stayed busy for {wait:g} s; {self.hint}')
            finally:
                self._waiting -= 1
            solver = self._pop(prefer) if self._idle else None
            if solver is None:
                self._count += 1
            elif not self._idle and self._count < self._size:
                # the last idle one is lent: make a spare off the request path, so the next
                # request beside this one does not pay for a build
                self._count += 1
                self._make_spare_in_background()
        if solver is None:
            try:
                solver = self._create()
            except BaseException:
                self.give_back(None)
                raise
        return solver

    def take_idle(self, wanted, keep: int = 1, rank=None):
        """An idle instance for which ``wanted(instance)`` is true (of those, the first with the highest
        ``rank(instance)``), to ``give_back`` when done, if more than ``keep`` are idle and no caller of
        ``take`` is waiting (so that requests still find one); else None, at once.

        For upkeep that must not make a request wait: e.g. building a worker's solvers after a
        parameter change, one worker at a time.
        """
        with self._cond:
            if len(self._idle) <= keep or self._waiting:
                return None
            candidates = [k for k in range(len(self._idle) - 1, -1, -1) if wanted(self._idle[k])]
            if not candidates:
                return None
            k = max(candidates, key=lambda k: rank(self._idle[k])) if rank is not None else candidates[0]
            self._upkept.add(id(self._idle[k]))
            return self._idle.pop(k)

    def discard_idle(self, broken) -> list:
        """Take out the idle instances for which ``broken(instance)`` is true (e.g. a worker process that
        died while idle), replaced after ``fill`` as closed ones are; they are returned for the caller to
        close and report. Cheap checks only: ``broken`` runs under the pool's lock."""
        with self._cond:
            found = [solver for solver in self._idle if broken(solver)]
            if not found:
                return []
            self._idle = [solver for solver in self._idle if not any(solver is f for f in found)]
            # as give_back does: a kept-full pool replaces them, up to its size
            replace = min(len(found), max(self._size - self._count + len(found), 0)) \
                if self._keep_full and not self._closing else 0
            self._count -= len(found) - replace
            self._cond.notify_all()
        for _ in range(replace):
            self._make_spare_in_background()
        return found

    def _pop(self, prefer):
        """The most recently returned idle instance (its warm start is the freshest), or the most recent
        one ``prefer`` likes."""
        if prefer is not None:
            for k in range(len(self._idle) - 1, -1, -1):
                if prefer(self._idle[k]):
                    return self._idle.pop(k)
        return self._idle.pop()

    def _make_spare_in_background(self):
        threading.Thread(target=self._make_spare, daemon=True).start()

    def _make_spare(self):
        spare = None
        for delay in (0.0, *(self.retry_delays if self._keep_full else ())):
            if delay:
                time.sleep(delay)
            if self._closing:
                break
            try:
                spare = self._create()
                break
            except Exception:  # the request that needs one will build it and report why
                pass
        self.give_back(spare)

    def give_back(self, solver) -> None:
        """Return an instance from ``take``; one that reports itself ``closed`` is dropped (replaced after ``fill``)."""
        closed = solver is None or getattr(solver, 'closed', False)
        replace = drop = False
        with self._cond:
            self._upkept.discard(id(solver))
            if closed and self._keep_full and solver is not None and self._count <= self._size:
                replace = True  # its count goes to the replacement
            elif closed or self._count > self._size or self._closing:
                self._count -= 1
                drop = not closed
            else:
                self._idle.append(solver)
            self._cond.notify_all()  # a request's take, and fill's wait
        if drop:  # beyond a reduced size, or the pool is closing
            getattr(solver, 'close', lambda: None)()
        if replace:
            self._make_spare_in_background()
