"""Pacing IPOPT solves that share a process, so short ones are not stuck behind long ones.

IPOPT guards every MUMPS call of the process with one mutex, which a solve
that factors without pause re-takes before a waiting thread wakes: beside
one that runs to its time budget, a typical solve would wait for most of
it. ``YieldingCallback`` is the direct route's iteration callback
(``planning.ipopt.IterationCallback``, which also stops a solve at its
deadline) for solvers that serve side by side. Pure Python, no ROS import.
"""
from __future__ import annotations

import contextlib
import threading
import time

from ..planning.ipopt import IterationCallback


class YieldingCallback(IterationCallback):
    """A long solve pauses between its iterations.

    Once a solve has run ``after`` s while another solve of this process is
    running (``solving``), it sleeps half as long as its last iteration took
    after each one (it then gets at most 2/3 of the time), so short solves
    get the linear solver in between. Typical solves never get there. A solve
    alone in its process (a worker's) pauses only past ``alone_after`` s, and
    then as long as its last iteration took: by then it is likely one that
    runs to its budget, and it leaves half its core to the other processes'
    typical requests; a warm fastest request, which normally ends before
    ``alone_after``, is not slowed down.
    """

    after = 0.05
    alone_after = 0.2
    _active = 0  # solves running in this process (all instances)
    _active_lock = threading.Lock()

    @contextlib.contextmanager
    def solving(self, deadline: float | None = None):
        """Around one IPOPT call: as ``IterationCallback.solving``, and counted as running."""
        with super().solving(deadline):
            with YieldingCallback._active_lock:
                YieldingCallback._active += 1
            try:
                yield
            finally:
                with YieldingCallback._active_lock:
                    YieldingCallback._active -= 1

    def between_iterations(self, now: float) -> None:
        if YieldingCallback._active > 1 and now - self.start > self.after:
            time.sleep(min(0.5 * (now - self._last), 0.02))
        elif now - self.start > self.alone_after:
            time.sleep(min(now - self._last, 0.02))
