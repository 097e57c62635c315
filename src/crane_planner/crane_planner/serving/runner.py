"""One worker for every executing goal: a current goal and at most one pending, as nav2's SimpleActionServer.

A goal's execution is a generator of steps (``Steps``): each step does what
is due (plan, send, publish feedback, look at the goal's state) and yields
how long (s) until its next one; what it returns is the goal's outcome. The
runner steps them all on one thread. A goal submitted while another executes
is pending; at the worker's next step it becomes the current one, and the
one it preempts is stepped beside it until it ends as the book of goals
decides (a goal not sent gave way on arrival; one in motion is taken over
once the streamer takes the new one's handover; one settling is observed
until the new motion starts): the runner decides who runs, never how a goal
ends. A step that plans runs to its end before the next step of any other
goal (as in nav2, whose execute callback plans between its preemption
checks); so does a step that waits for a reply it needs before it can go on
(the streamer taking a handover, its first ``stream_state`` after a
restart), while the waits between steps (holding until a start, feedback)
never hold the worker. The planner node's execute callback
submits a goal and waits for its outcome on the run's Event (``run``):
rclpy's action server takes what that callback returns as the goal's
result and ends the goal then, so the callback, its executor thread and
the result's timing stay as they were; only the steps moved to the worker.
Pure Python, no ROS import; the clock (``timer``, ``sleep``) is given, so
it runs on a fake one in tests.
"""
from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Generator

#: A goal's execution: yields the seconds until its next step, returns its outcome.
Steps = Generator[float, None, Any]


class RunnerStopped(RuntimeError):
    """The runner stopped (the node shuts down) before the goal had an outcome."""


@dataclass(eq=False)
class Run:
    """One goal's execution on the runner: its steps, when its next one is due (timer, s), its outcome."""

    steps: Steps
    due: float
    done: threading.Event = field(default_factory=threading.Event)
    outcome: Any = None
    error: BaseException | None = None

    def finish(self, outcome: Any = None, error: BaseException | None = None) -> None:
        if not self.done.is_set():  # (the first end counts: a stop's RunnerStopped or the goal's own)
            self.outcome, self.error = outcome, error
            self.done.set()

    def result(self) -> Any:
        """Its outcome, once it has one; what its steps raised is raised here."""
        self.done.wait()
        if self.error is not None:
            raise self.error
        return self.outcome


class GoalRunner:
    """The worker of executing goals.

    Args:
        timer: monotonic time now (s).
        sleep: how a caller driving it on its own thread waits (``run`` without ``start``).
    """

    def __init__(self, timer: Callable[[], float] = time.perf_counter, sleep: Callable[[float], None] = time.sleep):
        self._timer, self._sleep = timer, sleep
        self._wake = threading.Condition()
        self._stepping = threading.Lock()  # one step at a time: a generator runs on one thread at a time
        self.current: Run | None = None
        self.pending: Run | None = None
        self.finishing: list[Run] = []  # preempted ones, stepped to their outcome beside the current one
        self._thread: threading.Thread | None = None
        self._stopped = False

    def submit(self, steps: Steps) -> Run:
        """A goal to execute, pending until the worker's next step. A pending one it replaces (two goals within
        one step) gave way to it in the book of goals: it is stepped to that outcome."""
        run = Run(steps, self._timer())
        with self._wake:
            if self._stopped:
                run.finish(error=RunnerStopped('the goal runner has stopped'))
                return run
            if self.pending is not None:
                self.finishing.append(self.pending)
            self.pending = run
            self._wake.notify()
        return run

    def step(self) -> float | None:
        """One step of the worker: the pending goal becomes the current one, then every goal due steps once.
        Returns when the next step is due (timer, s); None: no goal is left."""
        with self._stepping:
            with self._wake:
                if self.pending is not None:
                    if self.current is not None:
                        self.finishing.append(self.current)
                    self.current, self.pending = self.pending, None
                runs = self.finishing + ([self.current] if self.current is not None else [])
            for run in runs:
                if run.due <= self._timer():
                    self._advance(run)
            with self._wake:
                self.finishing = [run for run in self.finishing if not run.done.is_set()]
                if self.current is not None and self.current.done.is_set():
                    self.current = None
                return self._next_due()

    def _advance(self, run: Run) -> None:
        try:
            wait = next(run.steps)
        except StopIteration as end:
            run.finish(end.value)
        except Exception as exc:  # a bug's, or the node's (a goal handle gone at shutdown): for its caller
            run.finish(error=exc)
        else:
            run.due = self._timer() + wait

    def _next_due(self) -> float | None:
        runs = [run for run in (*self.finishing, self.current, self.pending) if run is not None]
        return min((run.due for run in runs), default=None)

    # -- driven ---------------------------------------------------------------------------

    def run(self, steps: Steps) -> Any:
        """``steps`` executed to their outcome: by the worker once ``start``ed (the caller waits for it), else
        on the caller's thread with the runner's ``sleep`` (the tests, on a fake clock)."""
        run = self.submit(steps)
        if self._thread is None:
            try:
                while not run.done.is_set():
                    due = self.step()
                    if not run.done.is_set() and due is not None:
                        self._sleep(max(0.0, due - self._timer()))
            except BaseException as exc:  # raised by the wait itself (a fake clock's hook): as if by the goal's
                self._drop(run, exc)
                raise
        return run.result()

    def _drop(self, run: Run, error: BaseException) -> None:
        with self._wake:
            if self.pending is run:
                self.pending = None
            if self.current is run:
                self.current = None
            if run in self.finishing:
                self.finishing.remove(run)
        run.finish(error=error)

    def start(self) -> None:
        """The worker's thread started: from now on ``run`` waits for it."""
        self._thread = threading.Thread(target=self._serve, name='goal-runner', daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        try:
            while True:
                with self._wake:
                    while not self._stopped:
                        due = self._next_due()
                        wait = None if due is None else due - self._timer()
                        if wait is not None and wait <= 0.0:
                            break
                        self._wake.wait(wait)
                    if self._stopped:
                        return
                self.step()
        except BaseException as exc:  # the worker itself failed: no goal may wait for it for ever
            self._end_all(RunnerStopped(f'the goal runner failed: {type(exc).__name__}: {exc}'))
            raise

    def _end_all(self, error: BaseException) -> None:
        """Stopped: every goal still executing, and every one submitted from now on, ends with ``error``."""
        with self._wake:
            self._stopped = True
            runs = [run for run in (*self.finishing, self.current, self.pending) if run is not None]
        for run in runs:
            run.finish(error=error)

    def stop(self, timeout: float = 1.0) -> None:
        """The worker stopped; a goal still executing then ends with ``RunnerStopped`` for its caller."""
        with self._wake:
            self._stopped = True
            self._wake.notify()
        if self._thread is not None:
            self._thread.join(timeout)
        self._end_all(RunnerStopped('the goal runner stopped before the goal ended'))
