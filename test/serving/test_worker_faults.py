"""Worker processes that die (crane_planner.serving.planner, workers): real processes, real SIGKILLs.

A solver process can be killed under a request (the OOM killer, an operator's
``kill -9``) with its fork server or without. These tests kill them while
they solve, or while idle, and check what the caller gets (the plan of a
re-run, or a refusal naming the dead process and its signal), that the pool is
whole again with new processes, that the next request is served, and what the
planner reports (``WorkerEvent``s, which the node puts on /diagnostics).
The waits are hang guards only (the host is small and shared); the order of
events is what is asserted, the latency of an answer is bench/worker_death.py's.
"""
import os
import re
import signal
import threading
from multiprocessing import forkserver

import pytest

from crane_msgs_py.crane.params import CraneParams
from crane_planner.planning import PlanError, PlanOptions
from crane_planner.planning.dispatch import VariationalRequest
from crane_planner.serving import Planner
from crane_planner.serving.planner import OK, WARN
from crane_planner.serving.workers import Death
from crane_planner.tools.processes import cpu_ticks

MODEL = CraneParams()
OPTIONS = PlanOptions(max_solve_time=1.0)
#: What every worker builds before it is ready: NVF only (RVF's NLP costs several times as much to build).
WARMUPS = [VariationalRequest('plan', 'nvf', 0.3, 3.0, MODEL, OPTIONS)]
#: An NVF plan that exists but takes IPOPT a second or more (3 m in half a second): time to kill its worker
#: mid-solve, and a budget that leaves time to solve it again.
SLOW = ('nvf', 3.0, 0.5, MODEL, PlanOptions(max_solve_time=60.0))
#: An NVF request that runs to its budget of 1 s and finds no plan (10 m in half a second).
HOPELESS = ('nvf', 10.0, 0.5, MODEL, OPTIONS)
#: Hang guard (s) for anything a worker start or a solve decides on this host.
GUARD = 180.0


def wait_until(predicate, timeout=GUARD):
    event = threading.Event()
    while not predicate():
        assert timeout > 0, 'condition not met in time'
        event.wait(0.05)
        timeout -= 0.05


class Request:
    """A plan asked in a thread of its own: its outcome (the plan or the exception) once ``join``ed."""

    def __init__(self, planner, args):
        self.outcome = None
        self._thread = threading.Thread(target=self._run, args=(planner, args))
        self._thread.start()

    def _run(self, planner, args):
        try:
            self.outcome = planner.plan(*args)
        except Exception as exc:
            self.outcome = exc

    def join(self):
        self._thread.join(GUARD)
        assert not self._thread.is_alive(), 'the request was never answered'
        return self.outcome


def started_planner(processes: int, events: list) -> Planner:
    planner = Planner(processes=processes, on_event=events.append)
    planner.processes.toggled_limits = False  # only what the tests need built
    planner.warmups = WARMUPS
    assert planner.start_processes(ready_within=GUARD, all_of_them=True) and planner.wait_built(GUARD)
    return planner


def live(planner) -> list:
    """The pids of the idle workers that are alive."""
    return [w.pid for w in planner.processes.pool._idle if not w.gone()]


def solving_worker(planner):
    """The worker a request was lent, once it has spent CPU on it: the request is in its hands."""
    def lent():
        idle = planner.processes.pool._idle
        return [w for w in planner.processes.workers if not w.closed and all(w is not i for i in idle)]
    wait_until(lambda: len(lent()) == 1)
    worker = lent()[0]
    before = cpu_ticks(worker.pid)
    wait_until(lambda: cpu_ticks(worker.pid) >= before + 3)
    return worker


def refilled(planner, size: int, dead) -> list:
    """Wait until the pool holds ``size`` live idle workers, none of ``dead``; their pids."""
    wait_until(lambda: len(live(planner)) == size and not set(live(planner)) & set(dead))
    assert planner.processes.pool.instances == size
    return live(planner)


def assert_served(planner):
    plan = planner.plan('nvf', 0.3, 3.0, MODEL, OPTIONS)
    assert plan.evaluate(3.0).position[0] == pytest.approx(0.3, abs=1e-9)


def test_a_death_says_which_process_and_how_it_ended():
    assert str(Death(41, -9)) == 'the solver process 41 died (signal 9)' and Death(41, -9).signal == 9
    assert str(Death(41, 1)) == 'the solver process 41 died (exit code 1)' and Death(41, 1).signal is None
    assert 'its fork server died too' in str(Death(41, 255))  # multiprocessing's code when no status came


def test_a_worker_killed_mid_solve_has_its_request_rerun_on_the_other_one_and_is_replaced():
    events = []
    planner = started_planner(2, events)
    try:
        request = Request(planner, SLOW)
        worker = solving_worker(planner)
        other = [pid for pid in live(planner) if pid != worker.pid]
        os.kill(worker.pid, signal.SIGKILL)
        plan = request.join()
        assert not isinstance(plan, Exception), plan
        assert plan.evaluate(0.5).position[0] == pytest.approx(3.0, abs=1e-9)
        rerun = events[0]
        assert (rerun.level, rerun.action, rerun.death.pid, rerun.death.signal) == (WARN, 're-run', worker.pid, 9)
        assert rerun.new_pid == other[0]  # the other worker, idle meanwhile
        assert rerun.message.startswith(f'the solver process {worker.pid} died (signal 9) while solving an NVF '
                                        f'request; re-run on solver process {other[0]}')
        pids = refilled(planner, 2, [worker.pid])
        wait_until(lambda: events[-1].action == 'started')
        assert events[-1].level == OK and events[-1].death.pid == worker.pid and events[-1].new_pid in pids
        assert_served(planner)
    finally:
        planner.close()


def test_with_one_worker_the_request_is_rerun_on_its_replacement_when_its_budget_leaves_time():
    events = []
    planner = started_planner(1, events)
    try:
        request = Request(planner, SLOW)  # 60 s of budget: a new worker starts well within it
        worker = solving_worker(planner)
        os.kill(worker.pid, signal.SIGKILL)
        plan = request.join()
        assert not isinstance(plan, Exception), plan
        assert plan.evaluate(0.5).position[0] == pytest.approx(3.0, abs=1e-9)
        actions = [(e.action, e.death.pid) for e in events]
        assert actions[:2] == [('started', worker.pid), ('re-run', worker.pid)], actions  # the fresh one ran it
        assert events[1].new_pid == events[0].new_pid != worker.pid
        assert refilled(planner, 1, [worker.pid]) == [events[0].new_pid]
        assert_served(planner)
    finally:
        planner.close()


@pytest.mark.parametrize('with_server', [False, True], ids=['workers', 'workers-and-fork-server'])
def test_every_worker_killed_at_once_answers_the_request_and_the_pool_comes_back(with_server):
    events = []
    planner = started_planner(2, events)
    try:
        request = Request(planner, HOPELESS)  # a re-run only if a new worker is up within its 1.4 s
        worker = solving_worker(planner)
        victims = [w.pid for w in planner.processes.workers if not w.closed]
        assert len(victims) == 2 and worker.pid in victims
        if with_server:
            victims.append(forkserver._forkserver._forkserver_pid)
        for pid in victims:
            os.kill(pid, signal.SIGKILL)
        outcome = request.join()
        assert isinstance(outcome, PlanError)
        # refused: no worker was left before the answer was due; or (the other one's end of the pipe closes
        # only once the kernel has torn it down) the other took the re-run and was found dead under it; or a
        # new worker was up in time to take the re-run, and found no plan before the answer was due, saying
        # so itself or late
        other = (set(victims[:2]) - {worker.pid}).pop()
        message, causes = str(outcome), r'\((signal 9|exit status unknown: its fork server died too)\)'
        assert re.fullmatch(
            fr'the solver process {worker.pid} died {causes} while solving; no other solver process was free '
            r'before its answer was due \(max_solve_time 1 s \+ 0.4 s\): refused|'
            fr'the solver process {other} died {causes} while solving; it was re-running a request after the '
            fr'solver process {worker.pid} died {causes}: refused|'
            fr'the solver process {worker.pid} died {causes} while solving; its re-run on solver process \d+: (no '
            r'answer within [\d.]+ s \(the solver was still building or solving\)|nvf: no plan for D=10 m, T=0.5 s '
            r'within max_solve_time 1 s \(IPOPT stopped after \d+ iterations\); lengthen the duration, shorten the '
            r'move or raise max_solve_time)', message), message
        assert with_server or 'unknown' not in message  # the fork server reports a worker's signal
        pids = refilled(planner, 2, victims)
        wait_until(lambda: sum(e.action == 'started' for e in events) == 2)
        assert {e.death.pid for e in events if e.level == WARN} == {worker.pid, other}  # each reported once
        assert len([e for e in events if e.level == WARN]) == 2
        assert [e.action for e in events if e.action in ('refused', 're-run')] in (['refused'], ['re-run', 'refused'],
                                                                                  ['re-run'])
        assert sorted(e.new_pid for e in events if e.action == 'started') == sorted(pids)
        assert_served(planner)
    finally:
        planner.close()


def test_a_worker_killed_while_idle_is_replaced_before_any_request_finds_it():
    events = []
    planner = started_planner(1, events)
    try:
        (pid,) = live(planner)
        os.kill(pid, signal.SIGKILL)
        wait_until(lambda: any(e.action == 'started' for e in events))
        replaced, started = events
        assert (replaced.level, replaced.action, replaced.death.signal) == (WARN, 'replaced', 9)
        assert replaced.message == (f'the solver process {pid} died (signal 9) while idle; replaced: a new solver '
                                    'process is starting in its place')
        assert started.message.startswith(f'solver process {started.new_pid} started in place of solver '
                                          f'process {pid}, which died (signal 9)')
        assert refilled(planner, 1, [pid]) == [started.new_pid]
        assert_served(planner)
    finally:
        planner.close()


def test_a_death_read_while_another_worker_starts_keeps_its_signal(monkeypatch):
    """``Process.start`` polls every child for its exit status, which the fork server sends once: a worker's
    death read at the same moment must still name its signal, not an EOF's "fork server died too"."""
    import multiprocessing.connection
    import time

    from crane_planner.serving.workers import SolverProcess
    dead = SolverProcess()
    os.kill(dead.pid, signal.SIGKILL)
    assert multiprocessing.connection.wait([dead._process.sentinel], GUARD)  # its status is there to read
    read_signed = forkserver.read_signed
    # each read of a status (and of a new worker's pid) a little slow, so that the two reads overlap
    monkeypatch.setattr(forkserver, 'read_signed', lambda fd: time.sleep(0.3) or read_signed(fd))
    pollers, popen = set(), dead._process._popen
    poll = popen.poll
    monkeypatch.setattr(popen, 'poll', lambda *flag: pollers.add(threading.current_thread().name) or poll(*flag))
    started = {}
    starting = threading.Thread(target=lambda: started.setdefault('worker', SolverProcess()), name='starting')
    starting.start()  # its Process.start polls the dead worker too
    time.sleep(0.1)
    death = dead.died()
    starting.join(GUARD)
    assert started.get('worker') is not None, 'the second worker did not start'
    started['worker'].close()
    assert pollers == {'starting', threading.current_thread().name}  # both read the dead worker's status
    assert death.signal == signal.SIGKILL and death.cause == 'signal 9', death
