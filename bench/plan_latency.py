"""Variational planner latency: direct (collocation + IPOPT) vs indirect (TPBVP, solve_bvp).

Default model (Table 1, tau = 0.01 s), D = 0.3 m, T = 3 s, default intervals,
through the variational solvers' solve as the planning facade calls it (wall time,
plan object included). Measured:
- first_s: a new solver's first solve, NLP build included (target <= 3 s);
- warm_ms: median of 25 repeated solves of the same request, warm-started
  (targets NVF <= 30 ms, RVF <= 80 ms);
- varied_ms: median of 25 warm solves cycling D over 0.28..0.32 m and T over
  2.9..3.1 s, i.e. never the same request twice;
- indirect_s: median of 3 indirect solves of the same problem (linearized
  start, so independent of IPOPT) and the ratio indirect / direct warm
  (target >= 20);
- peak_rss_mb: the process's peak resident memory (target <= 500 MB).
Prints one JSON object.
"""
import json
import resource
import statistics
import sys
import time

from crane_msgs_py.crane.params import CraneParams
from crane_planner.planning import PlanOptions
from crane_planner.planning.dispatch import variational_solver

D, T = 0.3, 3.0
REPEATS = 25
TARGET_WARM_MS = {'nvf': 30.0, 'rvf': 80.0}


def timed(fn, *args):
    t0 = time.perf_counter()
    out = fn(*args)
    return time.perf_counter() - t0, out


def direct(method: str, params: CraneParams) -> dict:
    t0 = time.perf_counter()
    solver = variational_solver(method, PlanOptions())
    _, first = timed(solver.solve, D, T, params)
    first_s = time.perf_counter() - t0
    warm = [timed(solver.solve, D, T, params)[0] for _ in range(REPEATS)]
    varied, iterations = [], []
    for k in range(REPEATS):
        dt, plan = timed(solver.solve, D * (0.93 + 0.14 * (k % 5) / 4), T * (0.97 + 0.06 * (k % 7) / 6), params)
        varied.append(dt)
        iterations.append(plan.info['iterations'])
    return {'first_s': round(first_s, 3), 'build_s': round(first.info['build_time_s'], 3),
            'warm_ms': round(1e3 * statistics.median(warm), 2),
            'varied_ms': round(1e3 * statistics.median(varied), 2),
            'varied_iterations_median': statistics.median(iterations),
            'intervals': first.info['intervals']}


def indirect(method: str, params: CraneParams) -> dict:
    solver = variational_solver(method, PlanOptions(solver='indirect'))
    runs = [timed(solver.solve, D, T, params) for _ in range(3)]
    plan = runs[-1][1]
    return {'indirect_s': round(statistics.median(r[0] for r in runs), 3), 'indirect_nodes': plan.info['intervals']}


def main() -> int:
    params = CraneParams()
    out = {'D': D, 'T': T, 'tau': params.tau}
    ok = True
    for method in ('nvf', 'rvf'):
        r = direct(method, params)
        r.update(indirect(method, params))
        r['ratio_indirect_to_direct'] = round(1e3 * r['indirect_s'] / r['warm_ms'], 1)
        r['ratio_indirect_to_direct_varied'] = round(1e3 * r['indirect_s'] / r['varied_ms'], 1)
        r['meets_targets'] = (r['warm_ms'] <= TARGET_WARM_MS[method] and r['first_s'] <= 3.0
                              and r['ratio_indirect_to_direct'] >= 20)
        ok &= r['meets_targets']
        out[method] = r
    out['peak_rss_mb'] = round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1)
    out['meets_targets'] = bool(ok and out['peak_rss_mb'] <= 500)
    print(json.dumps(out))
    return 0


if __name__ == '__main__':
    sys.exit(main())
