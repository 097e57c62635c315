"""Time to design a cascaded shaper and sample its plan at 1 ms (T = 3 s, D = 0.3 m).

Prints one JSON object: per method the median and worst of many runs (ms),
the first (cold) run separately (NZV and EI solve their impulse times once
per damping ratio and cache them), and the 5 ms target.
"""
import json
import statistics
import sys
import time

from crane_msgs_py.crane.params import CraneParams
from crane_planner.planning.methods import Family, methods_of
from crane_planner.planning.model import modal_frequencies
from crane_planner.planning.shaped import shaped_plan

RUNS = 200
TARGET_MS = 5.0


def run(method, omegas, zeta, duration):
    t0 = time.perf_counter()
    samples = shaped_plan(method, 0.3, duration, omegas, zeta).sample(1e-3)
    return (time.perf_counter() - t0) * 1e3, len(samples.t)


def main() -> int:
    omegas = modal_frequencies(CraneParams())
    zeta = 0.05  # with damping so NZV and EI really solve for their impulses
    out = {'runs': RUNS, 'zeta': zeta, 'target_ms': TARGET_MS, 'methods': {}}
    for method in methods_of(Family.SHAPER):
        duration = 4.5 if method == 'zvdd' else 3.0  # ZVDD alone lasts 3.6 s
        cold, n = run(method, omegas, zeta, duration)
        times = [run(method, omegas, zeta, duration)[0] for _ in range(RUNS)]
        out['methods'][method] = {'duration_s': duration, 'samples': n, 'cold_ms': round(cold, 3),
                                  'median_ms': round(statistics.median(times), 3),
                                  'max_ms': round(max(times), 3)}
    out['worst_median_ms'] = max(m['median_ms'] for m in out['methods'].values())
    out['meets_target'] = out['worst_median_ms'] <= TARGET_MS
    print(json.dumps(out))
    return 0


if __name__ == '__main__':
    sys.exit(main())
