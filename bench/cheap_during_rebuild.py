"""A shaper's plan while the NVF/RVF solvers are built: ZV round trips over ROS during a rebuild.

Starts the real planner executable in a private ROS graph (3 solver processes,
its defaults), waits for its solver warm-up, then times ``PlanMove`` round trips
of a ZV plan (0.3 m in 3 s):

- **quiet**: nothing else asked;
- **rebuilding**: for ``--window`` s after ``intervals`` is set to a value not
  built before (every NVF/RVF NLP of the configuration is built anew, in the
  solver processes), with an NVF plan of the new configuration asked first (it
  needs a build too). The CPU time the planner's solver processes spent over
  the window shows the rebuild ran meanwhile; it is repeated ``--rebuilds`` times
  with different interval counts.

And, without ROS, ``serving.Planner``'s own answer to a ZV plan while a CasADi
NLP is built in a thread of the same process (what a planner without worker
processes, or one building in-process, puts its cheap requests beside) and
while a worker process builds it.

Target: a ZV round trip's median <= 20 ms while the solvers rebuild (and its ratio to the quiet
median, which a shared host's load raises alike). Prints one JSON object.

    .venv/bin/python bench/cheap_during_rebuild.py [--window 3] [--rebuilds 3]
"""
import argparse
import json
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path

TARGET_MS = 20.0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--window', type=float, default=3.0, help='seconds of ZV round trips per rebuild (default 3)')
    ap.add_argument('--rebuilds', type=int, default=3, help='rebuilds timed (default 3)')
    ap.add_argument('--quiet', type=int, default=40, help='ZV round trips timed with nothing else asked (default 40)')
    args = ap.parse_args()
    result = {'in_process': in_process()}
    from crane_planner.tools.processes import isolated_graph
    with isolated_graph() as env:
        result.update(over_ros(args, env))
    # a shared host's own load shows in both: the ratio is what the rebuild adds
    result['rebuilding_over_quiet'] = round(result['rebuilding']['round_trip_ms']['median']
                                            / result['quiet']['round_trip_ms']['median'], 2)
    result['pass'] = result['rebuilding']['round_trip_ms']['median'] <= TARGET_MS
    print(json.dumps(result))
    return 0 if result['pass'] else 1


def stats_ms(seconds) -> dict:
    ms = sorted(1e3 * s for s in seconds)
    return {'median': round(statistics.median(ms), 2), 'p90': round(ms[min(len(ms) - 1, int(0.9 * len(ms)))], 2),
            'max': round(ms[-1], 2), 'n': len(ms)}


def zv_while(planner, busy) -> dict:
    """ZV plans through ``planner`` (perf_counter s each) while ``busy()`` runs in a thread."""
    from crane_msgs_py.crane.params import CraneParams
    done, times = threading.Event(), []
    th = threading.Thread(target=lambda: (busy(), done.set()))
    t0 = time.perf_counter()
    th.start()
    while not done.is_set():
        t = time.perf_counter()
        planner.plan('zv', 0.3, 3.0, CraneParams())
        times.append(time.perf_counter() - t)
        time.sleep(0.002)
    th.join()
    return {'plan_ms': stats_ms(times), 'busy_s': round(time.perf_counter() - t0, 2)}


def in_process() -> dict:
    """ZV plans beside an NVF NLP built (and solved once) in a thread of this process, and in a worker."""
    from crane_msgs_py.crane.params import CraneParams
    from crane_planner.planning import PlanOptions
    from crane_planner.planning.dispatch import VariationalRequest
    from crane_planner.serving import Planner
    planner = Planner()
    planner.plan('zv', 0.3, 3.0, CraneParams())
    options = PlanOptions(intervals=22, max_solve_time=30.0)
    out = {'build_in_a_thread': zv_while(planner, lambda: planner.plan('nvf', 0.3, 3.0, CraneParams(), options))}
    workers = Planner(processes=1)
    workers.processes.toggled_limits = False
    try:
        workers.start_processes(60.0)
        request = VariationalRequest('plan', 'nvf', 0.3, 3.0, CraneParams(), PlanOptions(intervals=23,
                                                                                       max_solve_time=30.0))
        out['build_in_a_worker'] = zv_while(workers, lambda: workers.variational(request))
    finally:
        workers.close()
    return out


def over_ros(args, env: dict) -> dict:
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter
    from rclpy.parameter_client import AsyncParameterClient
    from service_load import cpu_s, family  # (bench/)

    from crane_msgs_py.client import PlannerClient
    from crane_msgs_py.messages.names import PLANNER_NODE
    from crane_msgs_py.runtime.runner import spinning
    from crane_planner.tools.processes import PLANNER, NodeGroup

    rclpy.init()
    ns = '/bench_rebuild'
    node = rclpy.create_node('cheap_during_rebuild_bench', namespace=ns)
    client = PlannerClient(node)
    params = AsyncParameterClient(node, f'{ns}/{PLANNER_NODE}')
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    out = {'requests': 'zv, 0.3 m in 3 s'}
    try:
        with spinning(executor), NodeGroup(env, Path(tempfile.mkdtemp(prefix='cheap-during-rebuild-'))) as nodes:
            nodes.start(*PLANNER, namespace=ns)
            if not client.wait_for_service(timeout=60.0):
                raise TimeoutError('plan_move not up in 60 s')
            if client.diagnostics.wait_for(None, 120.0, name='crane_planner: solvers') is None:
                raise TimeoutError('no solver warm-up status within 120 s')
            planner_pid = next(p.popen.pid for p in nodes.processes if p.name == 'planner')
            time.sleep(5.0)  # the solver processes' own upkeep after start-up (the limits' twins) mostly done

            def zv():
                t = time.perf_counter()
                response = client.call('zv', 0.0, 0.3, 3.0, timeout=30.0)
                if not response.success:
                    raise RuntimeError(f'zv refused: {response.message}')
                return time.perf_counter() - t

            for _ in range(3):  # untimed: first use of this request shape
                zv()
            quiet = [zv() for _ in range(args.quiet)]
            out['quiet'] = {'round_trip_ms': stats_ms(quiet)}

            rebuilding, workers_cpu, nvf = [], [], []
            for k in range(args.rebuilds):
                intervals = 21 + k  # never built before in this run
                future = params.set_parameters([Parameter('intervals', value=intervals)])
                while not future.done():
                    time.sleep(0.005)
                if not future.result().results[0].successful:
                    raise RuntimeError(f'intervals {intervals} refused: {future.result().results[0].reason}')
                solvers = [p for p in family(planner_pid) if p != planner_pid]
                cpu0, t0 = sum(cpu_s(p) for p in solvers), time.monotonic()
                answer = {}
                expensive = threading.Thread(target=lambda: answer.update(
                    r=client.call('nvf', 0.0, 0.3, 3.0, timeout=30.0), t=time.monotonic()))
                expensive.start()
                time.sleep(0.02)  # the NVF request first
                while time.monotonic() - t0 < args.window:
                    rebuilding.append(zv())
                    time.sleep(0.01)
                expensive.join(30.0)
                workers_cpu.append(sum(cpu_s(p) for p in solvers) - cpu0)
                response = answer.get('r')
                nvf.append({'intervals': intervals, 'success': bool(response and response.success),
                            'answered_after_s': round(answer.get('t', float('nan')) - t0, 3),
                            'message': '' if response is None or response.success else response.message})
            params.set_parameters([Parameter('intervals', value=0)])
            out['rebuilding'] = {'round_trip_ms': stats_ms(rebuilding), 'window_s': args.window,
                                 'solver_processes_cpu_s_per_window': [round(c, 2) for c in workers_cpu],
                                 'nvf_of_the_new_configuration': nvf}
            out['target_ms'] = TARGET_MS
            nodes.check_alive()
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return out


if __name__ == '__main__':
    sys.exit(main())
