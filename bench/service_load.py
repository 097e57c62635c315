"""The planner service under load: 8 client threads, 2,000 requests of a seeded mix, three nodes running.

Starts the real planner, streamer and sim executables in a private ROS graph
and sends ``~/plan_move`` requests (every method, and the default one) from 8 threads of one
client node: a seeded mix of
- typical valid requests (70 %): any method that fits T, T 2.6-8 s, |D| <= 1 m;
- edge cases (15 %): tiny and huge T (1 ms - 0.5 s, 30-60 s) and D (1 nm - 0.1 mm,
  3-10 m), valid for the node's limits but often not solvable in time;
- hostile ones (15 %): NaN and infinite positions, zero, negative and
  infinite durations, beyond max_duration or max_displacement.
Judged: every request answered (within max_solve_time + 0.5 s); typical
valid requests p50 <= 30 ms and p99 <= 150 ms; every answered plan starts
at the start and ends at the goal at the goal's stamp; planner RSS (the node
and its solver processes) after the run <= 1.1 x that after the first 200
requests. Meanwhile joint_states is
recorded by header stamps over at least 60 s (the load goes on until then):
50 Hz, no gap over 40 ms. Prints one JSON object.

    .venv/bin/python bench/service_load.py [--requests 2000] [--threads 8] [--seed 1]
"""
import argparse
import json
import math
import os
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

NS = '/bench_load'
BUDGET_S = 1.0  # the planner's default max_solve_time
TARGETS = {'typical_p50_ms': 30.0, 'typical_p99_ms': 150.0, 'answer_slack_s': 0.5, 'rss_growth': 1.1,
           'joint_states_hz': 50.0, 'joint_states_max_gap_ms': 40.0, 'observed_s': 60.0}


def requests(n: int, seed: int, weights=(0.7, 0.15, 0.15)):
    """(kind, method or None, start, goal, duration) of the seeded mix."""
    from crane_msgs_py.crane.params import CraneParams
    from crane_planner.planning import METHODS
    from crane_planner.planning.methods import Family, methods_of
    from crane_planner.planning.model import modal_frequencies
    from crane_planner.planning.shapers import design
    shortest = {m: design(m, modal_frequencies(CraneParams()), 0.0).duration for m in methods_of(Family.SHAPER)}
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < n:
        kind = rng.choice(['typical', 'edge', 'hostile'], p=weights)
        method = METHODS[rng.integers(len(METHODS))]
        start = float(rng.uniform(-2.0, 2.0))
        if kind == 'typical':
            T = float(rng.uniform(2.6, 8.0))
            if T <= shortest.get(method, 0.0):
                continue  # a method that fits T
            goal = start + float(rng.uniform(-1.0, 1.0))
        elif kind == 'edge':
            T = float(rng.choice([rng.uniform(1e-3, 0.5), rng.uniform(30.0, 60.0), rng.uniform(2.6, 8.0)]))
            D = float(rng.choice([rng.uniform(1e-9, 1e-4), rng.uniform(3.0, 10.0), rng.uniform(0.1, 1.0)]))
            goal = start + D * rng.choice([-1.0, 1.0])
        else:
            T, goal = float(rng.uniform(2.6, 8.0)), start + 0.3
            bad = rng.integers(7)
            if bad == 0:
                start = math.nan
            elif bad == 1:
                goal = math.inf
            elif bad == 2:
                T = 0.0
            elif bad == 3:
                T = -float(rng.uniform(0.1, 5.0))
            elif bad == 4:
                T = 1e6  # beyond max_duration
            elif bad == 5:
                goal = start + 50.0  # beyond max_displacement
            else:
                goal = -math.inf
        out.append((str(kind), None if rng.random() < 0.05 else method, start, goal, T))
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--requests', type=int, default=2000, help='requests (default 2000)')
    ap.add_argument('--threads', type=int, default=8, help='client threads (default 8)')
    ap.add_argument('--seed', type=int, default=1, help='seed of the mix (default 1)')
    ap.add_argument('--rate', type=float, default=5.0,
                    help='requests per second of each client thread, Poisson (default 5: a UI or scheduler '
                         'previewing plans); 0 = back to back, which measures the saturation throughput')
    ap.add_argument('--mix', type=float, nargs=3, default=(0.7, 0.15, 0.15), metavar=('TYPICAL', 'EDGE', 'HOSTILE'),
                    help='shares of the three kinds of request (default 0.7 0.15 0.15)')
    args = ap.parse_args()
    from crane_planner.tools.processes import isolated_graph
    with isolated_graph() as env:
        return measure(args, env)


def family(pid: int) -> list[int]:
    """A process and all its descendants (the planner's solver processes and their fork server)."""
    children = {}
    for stat in Path('/proc').glob('[0-9]*/stat'):
        try:
            fields = stat.read_text().rsplit(')', 1)[1].split()
        except OSError:
            continue
        children.setdefault(int(fields[1]), []).append(int(stat.parent.name))
    out, todo = [], [pid]
    while todo:
        p = todo.pop()
        out.append(p)
        todo.extend(children.get(p, []))
    return out


def _status_kb(pid: int, path: str, key: str) -> float:
    try:
        for line in Path(f'/proc/{pid}/{path}').read_text().splitlines():
            if line.startswith(key):
                return float(line.split()[1])
    except OSError:  # it just ended
        pass
    return 0.0


def rss_mb(pid: int) -> float:
    """Resident set size (MB) of a process and its descendants, from /proc (shared pages counted in each)."""
    return sum(_status_kb(p, 'status', 'VmRSS:') for p in family(pid)) / 1024.0


def pss_mb(pid: int) -> float:
    """Proportional set size (MB) of a process and its descendants: shared pages split between them."""
    return sum(_status_kb(p, 'smaps_rollup', 'Pss:') for p in family(pid)) / 1024.0


def cpu_s(pid: int | None = None) -> float:
    """User + system CPU time (s) of a process and its descendants (this process alone by default)."""
    total = 0
    for p in family(pid) if pid else ['self']:
        try:
            fields = Path(f'/proc/{p}/stat').read_text().rsplit(')', 1)[1].split()
        except OSError:
            continue
        total += int(fields[11]) + int(fields[12])
    return total / os.sysconf('SC_CLK_TCK')


def measure(args, env: dict) -> int:
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.experimental import EventsExecutor
    from sensor_msgs.msg import JointState

    from crane_msgs_py.client import PlannerClient
    from crane_msgs_py.messages.conversions import stamp_ns
    from crane_msgs_py.messages.names import JOINT_STATES_TOPIC
    from crane_msgs_py.runtime.qos import JOINT_STATES_QOS, recording
    from crane_msgs_py.runtime.runner import spinning
    from crane_planner.tools.harness import start_crane_nodes
    from crane_planner.tools.processes import NodeGroup

    mix = requests(args.requests, args.seed, np.asarray(args.mix) / sum(args.mix))
    rclpy.init()
    node = rclpy.create_node('service_load_bench', namespace=NS)
    client = PlannerClient(node)
    executor = SingleThreadedExecutor()  # the client threads only wait on it
    executor.add_node(node)
    # joint_states on a node and executor of their own, with a deep queue: this process's own
    # lag must not look like a gap in the sim's stamps
    recorder = rclpy.create_node('service_load_recorder', namespace=NS)
    stamps: list = []
    recorder.create_subscription(JointState, JOINT_STATES_TOPIC, lambda m: stamps.append(stamp_ns(m.header.stamp)),
                                 recording(JOINT_STATES_QOS, 100.0, 50.0))
    rec_executor = EventsExecutor()
    rec_executor.add_node(recorder)
    result = {'requests': len(mix), 'threads': args.threads, 'seed': args.seed, 'rate_per_thread_hz': args.rate,
              'mix': {k: sum(1 for r in mix if r[0] == k) for k in ('typical', 'edge', 'hostile')}}
    try:
        with spinning(executor), spinning(rec_executor), \
                NodeGroup(env, Path(tempfile.mkdtemp(prefix='service-load-'))) as nodes:
            start_crane_nodes(nodes, NS)
            planner_pid = nodes.processes[0].popen.pid
            t_up = time.monotonic()
            while client.diagnostics.wait_for(None, 0.2, name='crane_planner: solvers') is None:
                nodes.check_alive()
                if time.monotonic() - t_up > 120.0:
                    raise TimeoutError('planner warm-up not done in 120 s')
            answers = [None] * len(mix)
            rss = {}
            cursor = iter(range(len(mix)))
            lock = threading.Lock()
            done = [0]

            def worker(seed):
                rng = np.random.default_rng(seed)
                due = time.monotonic()
                while True:
                    if args.rate > 0.0:  # a Poisson client: the next request when it is due, or at once if late
                        due += rng.exponential(1.0 / args.rate)
                        time.sleep(max(0.0, due - time.monotonic()))
                    with lock:
                        k = next(cursor, None)
                    if k is None:
                        return
                    kind, method, start, goal, T = mix[k]
                    start_ns = time.time_ns() + 2_000_000_000 if k % 3 == 0 else 0
                    t0 = time.perf_counter()
                    try:
                        response = client.call(method, start, goal, T, start_ns=start_ns, timeout=10.0)
                    except TimeoutError:
                        response = None
                    answers[k] = (time.perf_counter() - t0, response, start_ns)
                    with lock:
                        done[0] += 1
                        if done[0] == 200:
                            rss['after_200_mb'] = rss_mb(planner_pid)
                        if done[0] % 500 == 0:
                            rss[f'after_{done[0]}_mb'] = rss_mb(planner_pid)

            t_load = time.monotonic()
            cpu0 = {name: cpu_s(pid) for name, pid in
                    [('planner', planner_pid), ('client', None),
                     *((p.name, p.popen.pid) for p in nodes.processes[1:])]}
            mark = len(stamps)
            threads = [threading.Thread(target=worker, args=(args.seed * 100 + k,)) for k in range(args.threads)]
            for th in threads:
                th.start()
            for th in threads:
                th.join()
            result['load_s'] = round(time.monotonic() - t_load, 2)
            result['throughput_per_s'] = round(len(mix) / result['load_s'], 1)
            result['cpu_ms_per_request'] = {
                name: round(1e3 * (cpu_s(pid) - cpu0[name]) / len(mix), 2)
                for name, pid in [('planner', planner_pid), ('client', None),
                                  *((p.name, p.popen.pid) for p in nodes.processes[1:])]}
            rss['after_run_mb'] = rss_mb(planner_pid)
            result['planner_processes'] = len(family(planner_pid))
            result['planner_pss_after_run_mb'] = round(pss_mb(planner_pid), 1)
            time.sleep(0.5)  # the last statuses in
            served = {}  # the planner's own account of the requests it served, per method
            for status in client.diagnostics.statuses('crane_planner: plan', level=0):
                values = {kv.key: kv.value for kv in status.values}
                served.setdefault(values['method'], []).append(
                    [float(values[k]) for k in ('plan_time', 'solve_time', 'iterations', 'build_time')])
            result['planner_side_ms_median'] = {
                m: dict(zip(('plan', 'solve', 'iterations', 'build'),
                            np.round(np.median(np.array(v), axis=0) * [1e3, 1e3, 1, 1e3], 2).tolist()))
                for m, v in sorted(served.items())}
            # keep a client busy until joint_states has been watched for 60 s
            extra = 0
            while time.monotonic() - t_load < TARGETS['observed_s'] + 0.5:
                client.call('rvf', 0.0, 0.5, 4.0)
                client.call('zv', 0.0, 0.5, 4.0)
                extra += 2
            js = np.array(stamps[mark:], dtype=np.int64)
            nodes.check_alive()
        judged = judge(mix, answers)
        gaps = np.diff(js) * 1e-6
        span = (js[-1] - js[0]) * 1e-9 if js.size > 1 else 0.0
        result.update(judged)
        result['planner_rss_mb'] = {k: round(v, 1) for k, v in rss.items()}
        result['rss_growth'] = round(rss['after_run_mb'] / rss['after_200_mb'], 3)
        result['joint_states'] = {'observed_s': round(span, 1), 'rate_hz': round((js.size - 1) / span, 2),
                                  'max_gap_ms': round(float(gaps.max()), 1), 'gaps_over_40ms': int(np.sum(gaps > 40.0)),
                                  'extra_requests': extra}
        result['pass'] = {
            'all_answered': judged['unanswered'] == 0 and judged['late'] == 0,
            'plans_start_and_end_right': judged['wrong_plans'] == 0,
            'typical_p50': judged['typical_ms'].get('p50', math.nan) <= TARGETS['typical_p50_ms'],
            'typical_p99': judged['typical_ms'].get('p99', math.nan) <= TARGETS['typical_p99_ms'],
            'rss': result['rss_growth'] <= TARGETS['rss_growth'],
            'joint_states': (span >= TARGETS['observed_s'] and abs(result['joint_states']['rate_hz'] - 50.0) < 0.5
                             and float(gaps.max()) <= TARGETS['joint_states_max_gap_ms']),
        }
    finally:
        node.destroy_node()
        recorder.destroy_node()
        rclpy.try_shutdown()
    print(json.dumps(result))
    return 0 if all(result['pass'].values()) else 1


def judge(mix, answers) -> dict:
    from crane_msgs_py.messages.conversions import joint_trajectory_to_arrays, stamp_ns
    typical, by_kind, by_method, wrong, late, unanswered, refused = [], {}, {}, [], 0, 0, {}
    for (kind, method, start, goal, T), answer in zip(mix, answers):
        elapsed, response, start_ns = answer
        if response is None:
            unanswered += 1
            continue
        late += elapsed > BUDGET_S + TARGETS['answer_slack_s']
        by_kind.setdefault(kind, []).append(elapsed)
        if not response.success:
            refused[kind] = refused.get(kind, 0) + 1
            if kind == 'typical':
                wrong.append(('refused', method, start, goal, T, response.message))
            continue
        if kind == 'typical':
            typical.append(elapsed)
            by_method.setdefault(method or 'default', []).append(elapsed)
        t, p, _, _ = joint_trajectory_to_arrays(response.trajectory)
        if not (p[0] == start and abs(p[-1] - goal) <= 1e-9 * max(1.0, abs(goal))
                and stamp_ns(response.trajectory.header.stamp) == start_ns and abs(t[-1] - T) <= 1e-9):
            wrong.append(('plan', method, start, goal, T))
    return {
        'unanswered': unanswered, 'late': int(late), 'wrong_plans': len(wrong), 'wrong_examples': wrong[:5],
        'refused': refused,
        'typical_ms': _stats(typical),
        'by_kind_ms': {k: _stats(v) for k, v in by_kind.items()},
        'typical_by_method_ms': {k: _stats(v) for k, v in sorted(by_method.items())},
    }


def _stats(values) -> dict:
    v = np.asarray(values) * 1e3
    if v.size == 0:
        return {}
    return {'p50': round(float(np.percentile(v, 50)), 2), 'p90': round(float(np.percentile(v, 90)), 2),
            'p99': round(float(np.percentile(v, 99)), 2), 'max': round(float(v.max()), 2), 'n': int(v.size)}


if __name__ == '__main__':
    sys.exit(main())
