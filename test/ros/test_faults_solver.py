"""ROS: the planner node's solver processes killed (SIGKILL) under an NVF PlanMove request.

The real planner executable alone in a namespace of a private graph (2 solver
processes; a PlanMove with an explicit start needs no streamer), always
stopped. Its solver processes are found under its process (forked by the
fork server, its child) and killed while one solves a request: the request
is answered (a plan, or a refusal naming the dead process and its signal),
/diagnostics says what happened and that new processes took their place, and
the next NVF request gets its plan. Waits are hang guards only.
"""
import os
import re
import signal
import time

import pytest

from crane_planner.tools.processes import cpu_ticks, fork_servers, process_children

NS = '/crane_faults'
SOLVER_PROCESSES = 2
#: Hang guard (s) for a start, a build or an answer on this small shared host.
GUARD = 180.0
#: An NVF request that runs to its budget (the default max_solve_time, 1 s) and finds no plan: 5 m in 0.5 s.
HOPELESS = (0.0, 5.0, 0.5)


def solver_processes(node_pid: int) -> list[int]:
    """The planner's solver processes: the children of its fork server (its other child is multiprocessing's
    resource tracker)."""
    tree = process_children()
    return sorted(w for server in fork_servers(node_pid) for w in tree.get(server, []))


def wait_until(nodes, predicate, what: str, timeout: float = GUARD, interval: float = 0.02):
    deadline = time.monotonic() + timeout
    while True:
        value = predicate()
        if value:
            return value
        nodes.check_alive()
        assert time.monotonic() < deadline, f'{what} not within {timeout:g} s'
        time.sleep(interval)


@pytest.fixture(scope='module')
def planner(ros_domain, tmp_path_factory):
    """(NodeGroup, its planner NodeProcess, a PlannerClient on a spun rclpy node) once the planner warmed up."""
    import rclpy
    from rclpy.executors import MultiThreadedExecutor

    from crane_msgs_py.client import PlannerClient
    from crane_msgs_py.runtime.runner import spinning
    from crane_planner.tools.processes import PLANNER, NodeGroup
    rclpy.init()
    node = rclpy.create_node('faults_check', namespace=NS)
    client = PlannerClient(node)
    executor = MultiThreadedExecutor(num_threads=2)
    executor.add_node(node)
    try:
        with NodeGroup(ros_domain, tmp_path_factory.mktemp('faults-node-logs')) as nodes, spinning(executor):
            process = nodes.start(*PLANNER, namespace=NS, params={'solver_processes': SOLVER_PROCESSES})
            wait_until(nodes, lambda: client.wait_for_service(0.1), 'plan_move')
            wait_until(nodes, lambda: client.diagnostics.wait_for(name='crane_planner: solvers', timeout=0.1),
                       'the planner\'s warm-up')
            yield nodes, process, client
            nodes.check_alive()
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()


def quiet(pids, seconds: float = 1.0) -> bool:
    """Whether ``pids`` spend no CPU over ``seconds``: no solver is building (the start-up's background builds
    are done), so the one that starts spending is solving our request."""
    before = {p: cpu_ticks(p) for p in pids}
    time.sleep(seconds)
    return all(cpu_ticks(p) - before[p] <= 1 for p in pids)


@pytest.mark.parametrize('fork_server', [False, True], ids=['workers', 'workers-and-fork-server'])
def test_solver_processes_killed_mid_request_are_reported_replaced_and_the_next_request_served(planner,
                                                                                               fork_server):
    import threading

    from crane_msgs_py.runtime.diagnostics import OK, WARN, level_of, status_values
    nodes, process, client = planner
    name, hardware_id = 'crane_planner: solver_processes', f'{NS}/crane_planner'
    workers = wait_until(nodes, lambda: (lambda w: w if len(w) == SOLVER_PROCESSES else None)(
        solver_processes(process.popen.pid)), 'the solver processes')
    wait_until(nodes, lambda: quiet(workers), 'quiet solver processes', interval=0.0)
    mark = client.diagnostics.mark()
    answer = {}
    request = threading.Thread(target=lambda: answer.setdefault('response', client.call('nvf', *HOPELESS)))
    request.start()
    before = {p: cpu_ticks(p) for p in workers}
    wait_until(nodes, lambda: any(cpu_ticks(p) >= before[p] + 3 for p in workers), 'a solver process solving')
    victims = list(workers)
    if fork_server:
        victims += fork_servers(process.popen.pid)
    for pid in victims:
        os.kill(pid, signal.SIGKILL)
    request.join(GUARD)
    response = answer['response']
    cause = r'\((signal 9|exit status unknown: its fork server died too)\)'
    # answered: a plan (no: it has none to give), or refused naming a dead solver process and how it ended
    # (serving.moves puts a refusal of the planning core under the field it most often concerns: move.duration)
    assert not response.success
    assert re.search(fr'the solver process ({"|".join(map(str, workers))}) died {cause} while solving; ',
                     response.message), response.message
    # /diagnostics: each death at WARN, naming its pid and signal, with what was done
    warned = wait_until(nodes, lambda: (lambda s: s if len(s) == SOLVER_PROCESSES else None)(
        client.diagnostics.statuses(name=name, level=WARN, after=mark, hardware_id=hardware_id)),
        'a status per death')
    values = [status_values(s) for s in warned]
    assert sorted(int(v['pid']) for v in values) == workers
    # the request's worker: refused, or re-run (on the other, found dead under it too; or on a new one up in
    # time, which finds no plan before the answer is due); the other, found dead idle: replaced
    assert {v['action'] for v in values} in ({'refused', 'replaced'}, {'re-run', 'refused'}, {'re-run', 'replaced'})
    for status in warned:
        assert re.match(fr'the solver process {status_values(status)["pid"]} died {cause} while ', status.message)
    if not fork_server:
        assert all(v['signal'] == '9' for v in values)
    # new processes took their places: a status each at OK, and the next NVF request gets its plan
    started = wait_until(nodes, lambda: (lambda s: s if len(s) == SOLVER_PROCESSES else None)(
        client.diagnostics.statuses(name=name, level=OK, after=mark, hardware_id=hardware_id)),
        'the new solver processes')
    new = sorted(int(status_values(s)['new_pid']) for s in started)
    assert not set(new) & set(workers) and all(level_of(s) == OK for s in started)
    assert solver_processes(process.popen.pid) == new
    plan = client.plan('nvf', 0.0, 0.3, 3.0)
    assert plan.position[-1] == pytest.approx(0.3, abs=1e-9) and plan.info.method == 'nvf'
