"""Fixed-rate loops on their own thread: absolute deadlines, precise sleeps, lateness statistics.

The streamer's 1 kHz publisher and the simulator's 1 kHz stepper share this:
tick k is due at ``epoch + k * period`` on CLOCK_MONOTONIC (absolute, so
lateness never accumulates into drift); the thread sleeps until each
deadline, or (given a busy wait) until shortly before it and spins the rest. Pure Python, no ROS import.
"""
from __future__ import annotations

import ctypes
import json
import os
import signal
import sys
import time

import numpy as np

_PR_SET_TIMERSLACK = 29  # linux/prctl.h
_PR_SET_PDEATHSIG = 1
#: Set (to any value) in a process's environment by whoever starts it as a child that must not
#: outlive it (the tests' and crane-demo's node groups): see ``die_with_parent``.
DIE_WITH_PARENT = 'CRANE_DIE_WITH_PARENT'


def die_with_parent(sig: int = signal.SIGINT) -> bool:
    """If ``DIE_WITH_PARENT`` is set: get ``sig`` when the parent dies, even by SIGKILL (Linux).

    Nodes run in sessions of their own (so a terminal's Ctrl-C reaches their
    starter first), so nothing else would stop them when a test run or a
    demo is killed: a leftover 1 kHz node loads every later run. A process
    whose parent is already gone signals itself at once. Whether it is armed.
    """
    if not os.environ.get(DIE_WITH_PARENT):
        return False
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        if libc.prctl(_PR_SET_PDEATHSIG, int(sig), 0, 0, 0) != 0:
            return False
    except (OSError, AttributeError):
        return False
    if os.getppid() == 1:  # the parent died before the call
        os.kill(os.getpid(), sig)
    return True


def tune_thread(priority: int = 0) -> list[str]:
    """Make the calling thread's sleeps precise; with ``priority`` > 0 also SCHED_FIFO.

    Linux pads every sleep by the thread's timer slack (50 us by default);
    1 ns removes that padding. SCHED_FIFO needs CAP_SYS_NICE or an rtprio
    limit. Also shortens the interpreter's switch interval so a loop thread
    woken while another thread runs Python waits one short interval for the GIL,
    not the interpreter's default 5 ms.
    Returns warnings for what could not be done.
    """
    warnings = []
    sys.setswitchinterval(1e-4)
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        if libc.prctl(_PR_SET_TIMERSLACK, 1, 0, 0, 0) != 0:
            warnings.append(f'timer slack unchanged: {os.strerror(ctypes.get_errno())}')
    except (OSError, AttributeError) as exc:
        warnings.append(f'timer slack unchanged: {exc}')
    if priority > 0:
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
        except (OSError, AttributeError) as exc:
            warnings.append(f'SCHED_FIFO priority {priority} refused: {exc}')
    return warnings


def set_fifo(priority: int) -> str:
    """Run the calling thread at SCHED_FIFO ``priority`` (1..99), or 0: normal scheduling (SCHED_OTHER).
    Returns '' or why the priority was refused (it needs CAP_SYS_NICE or an rtprio limit)."""
    return _schedule(0, priority)


#: Fast DDS's receive threads (its UDP and shared-memory listeners), by the names it gives them: a message
#: reaches the executor only once one of them has run, at normal priority behind whatever else wants a core.
MIDDLEWARE_RECEIVE_THREADS = ('dds.udp.', 'dds.shm.')


def set_threads_fifo(priority: int, prefixes=MIDDLEWARE_RECEIVE_THREADS) -> tuple[int, str]:
    """Run this process's threads named with one of ``prefixes`` (by default the middleware's receive
    threads) at SCHED_FIFO ``priority`` (0: normal scheduling), as ``set_fifo`` does the calling thread:
    (how many, '' or why one was refused). Threads started later keep their creator's policy. Linux
    (/proc); elsewhere none."""
    try:
        tasks = os.listdir('/proc/self/task')
    except OSError as exc:
        return 0, f'threads not listed: {exc}'
    count, refused = 0, ''
    for tid in tasks:
        try:
            with open(f'/proc/self/task/{tid}/comm') as comm:
                if not comm.read().startswith(tuple(prefixes)):
                    continue
        except OSError:  # it ended meanwhile
            continue
        reason = _schedule(int(tid), priority)
        count += not reason
        refused = refused or reason
    return count, refused


def _schedule(tid: int, priority: int) -> str:
    """Thread ``tid`` (0: the calling one) at SCHED_FIFO ``priority``, or normal scheduling: '' or why not."""
    try:
        if priority > 0:
            os.sched_setscheduler(tid, os.SCHED_FIFO, os.sched_param(priority))
        else:
            os.sched_setscheduler(tid, os.SCHED_OTHER, os.sched_param(0))
    except (OSError, AttributeError) as exc:
        return f'SCHED_FIFO priority {priority} refused: {exc}' if priority > 0 else f'normal scheduling refused: {exc}'
    return ''


#: mallopt parameter (malloc.h) and the fixed threshold (bytes) set by ``fix_mmap_threshold``.
_M_MMAP_THRESHOLD = -3
MMAP_THRESHOLD = 128 * 1024


def fix_mmap_threshold() -> str | None:
    """Serve every allocation of 128 KiB or more by mmap, returned to the system when freed.

    glibc raises this threshold each time such a block is freed, after which
    large blocks come from the per-thread heaps and stay there: a process
    whose many threads allocate and free solver workspaces (the planner:
    MUMPS, several MB a solve) then grows by a heap's worth per thread,
    without bound as requests go on. A fixed threshold keeps its size
    flat. Returns a warning if it could not be set (not glibc).
    """
    try:
        if ctypes.CDLL(None).mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD) == 1:
            return None
        return 'mallopt(M_MMAP_THRESHOLD) refused'
    except (OSError, AttributeError) as exc:
        return f'mmap threshold unchanged: {exc}'


def sleep_until(deadline_ns: int, busy_wait_ns: int) -> int:
    """Return at or just after ``deadline_ns`` (time.monotonic_ns); the time of return.

    Sleeps until ``busy_wait_ns`` before the deadline and spins the rest,
    trading that much CPU per tick for a wake-up latency of a few us.
    """
    while True:
        now = time.monotonic_ns()
        remaining = deadline_ns - now
        if remaining <= 0:
            return now
        if remaining > busy_wait_ns:
            time.sleep((remaining - busy_wait_ns) * 1e-9)


class Lateness:
    """Tick lateness samples (ns): a window the diagnostics take once a second, and an optional full log."""

    def __init__(self, keep_all: bool = False, limit: int = 3_600_000):
        self._window: list[int] = []
        self.all: list[int] | None = [] if keep_all else None
        self._limit = limit

    def add(self, ns: int):
        self._window.append(ns)  # list.append is atomic: the loop adds while the timer takes
        if self.all is not None and len(self.all) < self._limit:
            self.all.append(ns)

    def take(self) -> np.ndarray:
        """The samples since the last call (ns)."""
        window, self._window = self._window, []
        return np.asarray(window, dtype=float)

    def dump(self, path: str, rate_hz: float, first_tick_ns: int | None) -> None:
        """Write the full log (``keep_all``) as JSON {rate_hz, first_tick_ns (ROS time of the first tick),
        lateness_us: [...]}, for the timing benchmarks; nothing without one."""
        if self.all is None:
            return
        with open(path, 'w') as f:
            json.dump({'rate_hz': rate_hz, 'first_tick_ns': first_tick_ns,
                       'lateness_us': [x * 1e-3 for x in self.all]}, f)


def lateness_summary_us(samples_ns: np.ndarray) -> dict:
    """p50, p99 and max (us) of lateness samples; NaN when there are none."""
    if samples_ns.size == 0:
        return {'lateness_p50_us': float('nan'), 'lateness_p99_us': float('nan'), 'lateness_max_us': float('nan')}
    p50, p99 = np.percentile(samples_ns, [50, 99]) * 1e-3
    return {'lateness_p50_us': float(p50), 'lateness_p99_us': float(p99),
            'lateness_max_us': float(samples_ns.max() * 1e-3)}


class Ticker:
    """Tick ``tick`` is due at ``epoch + tick * period`` (time.monotonic_ns), absolute deadlines.

    A loop that falls behind runs the missed ticks back to back (none is
    lost); one more than ``max_backlog`` ticks behind (the machine was
    suspended, say) skips ahead instead of bursting.
    """

    def __init__(self, period_ns: int, max_backlog: int = 100):
        self.period = int(period_ns)
        self.max_backlog = max_backlog
        self.restart()

    def restart(self) -> int:
        """Tick 0 one period from now; returns the epoch."""
        self.epoch = time.monotonic_ns() + self.period
        self.tick = 0
        return self.epoch

    @property
    def deadline(self) -> int:
        return self.epoch + self.tick * self.period

    def advance(self, now: int) -> int:
        """Move on from the current tick, finished at ``now``; returns how many ticks were skipped."""
        backlog = (now - self.deadline) // self.period
        if backlog > self.max_backlog:
            self.tick += backlog
            return backlog - 1
        self.tick += 1
        return 0

