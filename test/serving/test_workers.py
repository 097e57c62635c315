"""NVF/RVF in worker processes (crane_planner.serving.workers): real processes, real CasADi/IPOPT.

The workers exist so that a solve never waits on another's linear algebra
(IPOPT's MUMPS runs one call at a time per process), and so that building
and solving never take the interpreter lock from the threads answering cheap
requests; these tests check that what comes back is what an in-process solve
gives, that a worker that dies, is late or is busy never costs a request its
answer or another its plan, and that a shaper's plan is answered while the
workers build a new configuration's solvers.
"""
import dataclasses
import os
import signal
import threading

import numpy as np
import pytest

from crane_msgs_py.crane.params import CraneParams
from crane_planner.planning import PlanError, PlanOptions
from crane_planner.planning.dispatch import VariationalRequest
from crane_planner.serving import Planner
from crane_planner.serving.workers import SolverProcess, WorkerLate

MODEL = CraneParams()
OPTIONS = PlanOptions(max_solve_time=1.0)
#: No plan exists that a solver finds in a second: 10 m in half a second.
HOPELESS = ('rvf', 10.0, 0.5, MODEL, OPTIONS)
#: The same as a worker request.
HOPELESS_REQUEST = VariationalRequest('plan', *HOPELESS)
WARMUPS = [VariationalRequest('plan', m, 0.3, 3.0, MODEL, OPTIONS) for m in ('nvf', 'rvf')]


@pytest.fixture(scope='module')
def planner():
    planner = Planner(processes=2)
    planner.warmups = WARMUPS
    assert planner.start_processes(ready_within=60.0)
    planner.warm_threads(WARMUPS)  # as the node does: the workers have them, nothing is built here
    assert planner.wait_built(120.0)  # and their twins with limits: no upkeep takes a worker from a test
    yield planner
    planner.close()


def wait_until(predicate, timeout=30.0):
    event = threading.Event()
    while not predicate():
        assert timeout > 0, 'condition not met in time'
        event.wait(0.05)
        timeout -= 0.05


@pytest.mark.parametrize('method, D, T', [('nvf', 0.3, 3.0), ('rvf', -0.6, 4.4), ('rvf', 1.0, 2.6)])
def test_a_worker_returns_the_plan_an_in_process_solve_gives(planner, method, D, T):
    remote = planner.plan(method, D, T, MODEL, OPTIONS)
    local = Planner().plan(method, D, T, MODEL, OPTIONS)
    t = np.linspace(0.0, T, 301)
    # warm starts differ (each solver's last solution), so agreement is to the solver's tolerance
    assert np.max(np.abs(remote.evaluate(t).position - local.evaluate(t).position)) < 1e-7 * max(abs(D), 1.0)
    assert remote.evaluate(T).position[0] == pytest.approx(D, abs=1e-9)
    assert remote.info['status'] == 'Solve_Succeeded'


def test_a_refusal_in_a_worker_is_raised_in_the_caller_with_its_reason(planner, monkeypatch):
    # the worker's own refusal, however slow a busy host makes its last iteration, not the caller's deadline
    # (beside a CPU-bound process, 0.4 s past its 1 s budget came without an answer)
    monkeypatch.setattr(planner.dispatch, 'answer_margin', 10.0)
    with pytest.raises(PlanError, match=r'rvf: no plan for D=10 m, T=0.5 s within max_solve_time 1 s'):
        planner.plan(*HOPELESS)


def run_in_thread(target, done, name):
    """Start ``target`` in a thread that appends (name, its result or exception) to ``done`` when it ends."""
    def run():
        try:
            done.append((name, target()))
        except Exception as exc:
            done.append((name, exc))
    th = threading.Thread(target=run)
    th.start()
    return th


def test_a_request_finding_every_worker_busy_waits_for_one_and_nothing_is_built_in_this_process(planner):
    done = []
    threads = [run_in_thread(lambda: planner.plan(*HOPELESS), done, 'hopeless') for _ in range(2)]
    wait_until(lambda: planner.processes.pool.instances == 2 and not planner.processes.pool._idle)
    # due long after a hopeless request's budget of 1 s ends: it waits for that worker, then is solved there
    # (how long the wait and the solve take is the host's: a budget of its own keeps them apart; when a
    # hopeless request gives up is IPOPT's, at its budget or earlier)
    plan = planner.plan('rvf', 0.3, 3.0, MODEL, dataclasses.replace(OPTIONS, max_solve_time=30.0))
    for th in threads:
        th.join()
    # solved by one of the two workers (no third was started for it), which it had only once a hopeless
    # request had given up
    assert planner.processes.pool.instances == 2
    assert len(done) == 2 and all(isinstance(result, PlanError) for _, result in done)
    assert plan.evaluate(3.0).position[0] == pytest.approx(0.3, abs=1e-9)
    assert planner.threads.pools == {}  # no solver of this process's own, built or used


def test_a_request_whose_answer_is_due_before_a_worker_frees_up_is_refused_naming_solver_processes(planner):
    # both workers held by this test, not by requests that might end early: none frees up before
    # the answer is due, whatever the host does to this thread's timing
    held = []
    try:
        held += [planner.processes.pool.take(10.0) for _ in range(2)]
        with pytest.raises(PlanError, match='raise solver_processes') as refusal:
            planner.plan('nvf', 0.3, 3.0, MODEL, dataclasses.replace(OPTIONS, max_solve_time=0.1))
        assert not isinstance(refusal.value, WorkerLate)  # refused before any worker was given it
        assert all(worker.alive and not worker.late for worker in held)
    finally:
        for worker in held:
            planner.processes.pool.give_back(worker)
    # and the workers serve the next request as before
    plan = planner.plan('nvf', 0.3, 3.0, MODEL, dataclasses.replace(OPTIONS, max_solve_time=30.0))
    assert plan.evaluate(3.0).position[0] == pytest.approx(0.3, abs=1e-9)


def test_a_shaper_plan_is_answered_while_the_workers_build_a_new_configuration():
    """Setting ``warmups`` to another NLP structure (intervals) has the worker build it, in its own
    process: a ZV plan asked meanwhile is answered before that build ends, and before an NVF request of
    the new configuration sent ahead of it."""
    planner = Planner(processes=1)
    planner.processes.toggled_limits = False  # only what the test needs built
    planner.warmups = WARMUPS
    try:
        assert planner.start_processes(ready_within=60.0) and planner.wait_built(60.0)
        rebuilt = dataclasses.replace(OPTIONS, intervals=20, max_solve_time=30.0)
        events = []
        planner.warmups = [VariationalRequest('plan', m, 0.3, 3.0, MODEL, rebuilt) for m in ('nvf', 'rvf')]
        building = run_in_thread(lambda: planner.wait_built(120.0), events, 'rebuilt')
        expensive = run_in_thread(lambda: planner.plan('nvf', 0.3, 3.0, MODEL, rebuilt), events, 'nvf')
        wait_until(lambda: not planner.processes.pool._idle)  # the worker builds (for the upkeep or the NVF request)
        shaped = planner.plan('zv', 0.3, 3.0, MODEL, rebuilt)
        events.append(('zv', shaped))
        building.join()
        expensive.join()
        order = [name for name, _ in events]
        assert order[0] == 'zv' and set(order) == {'zv', 'rebuilt', 'nvf'}, order
        results = dict(events)
        assert results['rebuilt'] is True
        assert results['nvf'].evaluate(3.0).position[0] == pytest.approx(0.3, abs=1e-9)
        assert shaped.evaluate(3.0).position[0] == pytest.approx(0.3, abs=1e-12)
        assert planner.threads.pools == {}
        worker = planner.processes.pool._idle[0]
        assert worker.has(VariationalRequest('plan', 'rvf', 0.3, 3.0, MODEL, rebuilt))
    finally:
        planner.close()


def test_one_worker_starts_with_the_limits_twins_and_a_request_under_a_new_limit_goes_to_it():
    """Setting max_velocity (another NLP structure than none) needs no build in the request: one worker
    built NVF's twins with limits before it was ready, and a request under the new limit goes to it (it
    prefers a worker that has its NLP) and obeys the limit."""
    planner = Planner(processes=2)
    planner.warmups = WARMUPS[:1]
    # a roomy budget (not part of the NLP's structure): what is checked is where the request goes, not how fast a
    # loaded host solves it (beside a CPU-bound process, a second was not enough)
    limited = PlanOptions(max_solve_time=30.0, max_velocity=0.16)
    request = VariationalRequest('plan', 'nvf', 0.3, 3.0, MODEL, limited)
    try:
        assert planner.start_processes(ready_within=60.0, all_of_them=True) and planner.wait_built(60.0)
        holders = [w for w in planner.processes.pool._idle if w.has(request)]
        assert len(holders) == 1
        plan = planner.variational(request)
        assert planner.processes.pool._idle[-1] is holders[0]  # the one that solved it came back last
        speed = np.diff(plan.evaluate(np.linspace(0.0, 3.0, 601)).position) / 0.005
        assert 0.1 < np.max(np.abs(speed)) <= 0.16 * (1 + 1e-6)
    finally:
        planner.close()


def test_a_worker_that_dies_mid_solve_costs_one_refusal_naming_it_and_is_replaced():
    """Its request (hopeless, 1 s of budget) is refused naming the dead process and its signal, and a new
    worker takes its place (more in test_worker_faults.py)."""
    planner = Planner(processes=1)
    planner.warmups = WARMUPS
    try:
        assert planner.start_processes(ready_within=60.0)
        worker = planner.processes.pool._idle[0]
        errors = []

        def hopeless():
            try:
                planner.plan(*HOPELESS)
            except PlanError as exc:
                errors.append(str(exc))

        th = threading.Thread(target=hopeless)
        th.start()
        wait_until(lambda: not planner.processes.pool._idle)
        os.kill(worker.pid, signal.SIGKILL)
        th.join()
        assert errors and errors[0].startswith(f'the solver process {worker.pid} died (signal 9) while solving; ')
        wait_until(lambda: planner.processes.pool._idle)  # the replacement is up
        assert planner.processes.pool._idle[0] is not worker and planner.processes.pool.instances == 1
        plan = planner.plan('nvf', 0.3, 3.0, MODEL, OPTIONS)
        assert plan.evaluate(3.0).position[0] == pytest.approx(0.3, abs=1e-9)
    finally:
        planner.close()


def test_a_late_answer_is_dropped_never_given_to_the_next_request():
    worker = SolverProcess(WARMUPS)
    try:
        with pytest.raises(PlanError, match='no answer within'):
            worker.solve(HOPELESS_REQUEST, timeout=0.05)
        assert worker.late
        worker.finish_late()
        assert not worker.late and not worker.closed
        plan = worker.solve(VariationalRequest('plan', 'nvf', 0.2, 3.5, MODEL, OPTIONS), timeout=10.0)
        assert (plan.method, plan.displacement, plan.duration) == ('nvf', 0.2, 3.5)
    finally:
        worker.close()
    assert not worker._process.is_alive()


def test_workers_ignore_ctrl_c_and_end_with_their_parent_pipe():
    worker = SolverProcess()
    os.kill(worker.pid, signal.SIGINT)  # a terminal's Ctrl-C reaches the whole process group
    plan = worker.solve(VariationalRequest('plan', 'nvf', 0.3, 3.0, MODEL, OPTIONS), timeout=30.0)
    assert plan.displacement == 0.3
    worker._conn.close()  # as when the parent ends
    worker._process.join(timeout=10.0)
    assert worker._process.exitcode == 0


def test_a_worker_answers_the_fastest_plan_as_an_in_process_planner_does(planner):
    # a budget no loaded host exhausts (the worker may build this free-time NLP first): the plan is asserted
    options = PlanOptions(max_velocity=0.25, max_acceleration=0.5, max_solve_time=60.0)
    remote = planner.fastest('nvf', 0.3, MODEL, options)
    local = Planner().fastest('nvf', 0.3, MODEL, options)
    assert remote.duration == pytest.approx(local.duration, rel=1e-6)
    assert 'fastest' in remote.info


def test_a_parameter_change_is_reported_once_every_worker_has_built_it(planner):
    """``service.report_when_built``: the solvers status of a parameter change comes once no worker lacks the
    new warm-ups (here the fastest plan's NLP that limits add), not before."""
    from crane_planner.serving.service import report_when_built
    limited = PlanOptions(max_solve_time=1.0, max_velocity=0.25)
    wanted = WARMUPS + [VariationalRequest('fastest', 'nvf', 0.3, None, MODEL, limited)]
    reported = []
    try:
        planner.warmups = wanted
        report_when_built(planner, lambda message: reported.append(
            (message, [worker.needs(wanted) for worker in planner.processes.workers])))  # what they lacked when told
        wait_until(lambda: reported, timeout=120.0)
        message, lacking = reported[0]
        assert message.startswith('solvers rebuilt for the new parameters in') and not any(lacking), reported
    finally:
        planner.warmups = WARMUPS
