"""Planner round trips over ROS: start-up time, warm PlanMove round trips of every method, ExecuteMove acceptance.

Starts the real planner executable in a private ROS graph, measures how long
until ``~/plan_move`` and ``~/execute_move`` are up, waits for its solver
warm-up, then times warm ``PlanMove`` round trips of the paper's case (T = 3 s,
D = 0.3 m; the default knots, where the plan needs them) and splits each
into the solve time the response's ``PlanInfo`` reports and the rest
(request/response conversion, transport, trajectory building), and times
``ExecuteMove`` goals from sending to acceptance (no streamer runs: each is
then aborted, which the acceptance does not wait for). Targets: PlanMove
median <= 5 ms for ZV and NVF (<= 10 ms for every method), acceptance median
<= 20 ms, services up <= 5 s. Prints one JSON object.

    .venv/bin/python bench/ros_roundtrip.py [--requests 20]
"""
import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

TARGET_MS = 10.0
GOAL_MS = 5.0  # the target for ZV and NVF
ACCEPT_TARGET_MS = 20.0
STARTUP_TARGET_S = 5.0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--requests', type=int, default=20, help='timed requests per method (default 20)')
    args = ap.parse_args()

    from crane_planner.tools.processes import isolated_graph
    with isolated_graph() as env:  # this process joins the planner's private graph
        return measure(args, env)


def measure(args, env: dict) -> int:
    import rclpy
    from rclpy.executors import SingleThreadedExecutor

    from crane_msgs_py.client import PlannerClient
    from crane_msgs_py.runtime.runner import spinning
    from crane_planner.planning import METHODS
    from crane_planner.tools.processes import PLANNER, NodeGroup

    rclpy.init()
    node = rclpy.create_node('ros_roundtrip_bench', namespace='/bench')
    client = PlannerClient(node)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    result = {'requests': args.requests, 'duration_s': 3.0, 'displacement_m': 0.3}
    try:
        with spinning(executor), NodeGroup(env, Path(tempfile.mkdtemp(prefix='ros-roundtrip-'))) as nodes:
            t0 = time.monotonic()
            nodes.start(*PLANNER, namespace='/bench')
            while not client.wait_for_service(timeout=0.05):
                nodes.check_alive()
                if time.monotonic() - t0 > 60.0:
                    raise TimeoutError('plan_move and execute_move not up in 60 s')
            result['services_up_s'] = round(time.monotonic() - t0, 3)
            warm = client.diagnostics.wait_for(None, 120.0, name='crane_planner: solvers')
            result['warmup_s'] = round(time.monotonic() - t0, 3)
            if warm is None:
                raise TimeoutError('no solver warm-up status within 120 s')
            for method in METHODS:
                round_trips, solve = [], []
                T = 3.0 if method in ('nvf', 'rvf') else max(3.0, shaper_duration(method) + 0.5)
                for k in range(args.requests + 2):  # two untimed: first use of this request shape
                    start, goal = (0.0, 0.3) if k % 2 == 0 else (0.3, 0.0)
                    t = time.perf_counter()
                    response = client.call(method, start, goal, T)
                    rt = time.perf_counter() - t
                    if not response.success:
                        raise RuntimeError(f'{method} request {k} refused: {response.message}')
                    if k >= 2:
                        round_trips.append(rt)
                        solve.append(response.info.solve_time)
                median_rt = statistics.median(round_trips)
                median_solve = statistics.median(solve)
                result[method] = {
                    'round_trip_ms': {'median': _ms(median_rt), 'p90': _ms(_quantile(round_trips, 0.9)),
                                      'max': _ms(max(round_trips))},
                    'solve_ms_median': _ms(median_solve),
                    'message_handling_ms_median': _ms(median_rt - median_solve),
                    'knots': len(response.trajectory.points),
                    'duration_s': T,
                }
            accept = []
            for k in range(args.requests):
                t = time.perf_counter()
                handle = client.send_execute('zv', 0.0, 0.3, 3.0)
                accept.append(time.perf_counter() - t)
                client._wait(handle.get_result_async(), 10.0, 'the goal')  # aborted: no streamer runs
            result['execute_move_accept_ms'] = {'median': _ms(statistics.median(accept)),
                                                'p90': _ms(_quantile(accept, 0.9)), 'max': _ms(max(accept))}
            nodes.check_alive()
        result['pass'] = {
            'services_up': result['services_up_s'] <= STARTUP_TARGET_S,
            **{m: result[m]['round_trip_ms']['median'] <= (GOAL_MS if m in ('zv', 'nvf') else TARGET_MS)
               for m in METHODS},
            'execute_move_accept': result['execute_move_accept_ms']['median'] <= ACCEPT_TARGET_MS,
        }
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    print(json.dumps(result))
    return 0 if all(result['pass'].values()) else 1


def shaper_duration(method: str) -> float:
    """The shaper's own length at the default model (s): ZVDD is longer than the paper's 3 s."""
    from crane_msgs_py.crane.params import CraneParams
    from crane_planner.planning.model import modal_frequencies
    from crane_planner.planning.shapers import design
    return design(method, modal_frequencies(CraneParams()), 0.0).duration


def _ms(seconds: float) -> float:
    return round(1e3 * seconds, 2)


def _quantile(values, q: float) -> float:
    values = sorted(values)
    return values[min(len(values) - 1, int(q * len(values)))]


if __name__ == '__main__':
    sys.exit(main())
