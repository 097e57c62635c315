"""Time of ``identify`` on 10 s of a recorded move at 50 Hz (target <= 2 s), and its iterations.

Recordings are simulated (crane_sim, seeded 1 mrad angle noise): a 0.3 m
quintic move in 1 s, then free swing, on five cranes drawn within +-30 % of
Table 1 (one with joint damping). The first call builds the CasADi model of
that record length (cached for later calls of the same length) and is reported
apart. Prints one JSON object.
"""
import json
import statistics
import sys
import time

import numpy as np

from crane_msgs_py.crane.params import CraneParams
from crane_planner.identification import Recording, identify
from crane_planner.planning.profiles import quintic
from crane_sim.measurement import measured_angles
from crane_sim.simulator import simulate

TARGET_S = 2.0
RECORD_S, RATE_HZ = 10.0, 50.0


def recording(plant: CraneParams, seed: int) -> Recording:
    t = np.arange(0.0, RECORD_S + 1e-9, 1e-3)
    _, _, a, _ = quintic(t, 0.3, 1.0)
    r = simulate(t, a, plant, dt=1e-3, record_every=round(1e3 / RATE_HZ))
    th1, th2 = measured_angles(r, 1e-3, seed)
    return Recording(r.t, r.y[0], th1[0], th2[0])


def main() -> int:
    rng = np.random.default_rng(2)
    base = CraneParams()
    runs = []
    for k in range(5):
        f = rng.uniform(0.7, 1.3, 4)
        plant = base.replace(L1=base.L1 * f[0], L2=base.L2 * f[1], m1=base.m1 * f[2], m2=base.m2 * f[3],
                             **({'c1': 0.004, 'c2': 0.001} if k == 4 else {}))
        rec = recording(plant, k)
        t0 = time.perf_counter()
        result = identify(rec, base)
        elapsed = time.perf_counter() - t0
        runs.append({'seconds': round(elapsed, 3), 'iterations': result.iterations,
                     'L1_error': round(result.values['L1'] / plant.L1 - 1, 5),
                     'L2_error': round(result.values['L2'] / plant.L2 - 1, 5)})
    warm = [r['seconds'] for r in runs[1:]]
    out = {'record_s': RECORD_S, 'rate_hz': RATE_HZ, 'samples': int(RECORD_S * RATE_HZ) + 1, 'target_s': TARGET_S,
           'first_s_incl_build': runs[0]['seconds'], 'median_s': round(statistics.median(warm), 3),
           'max_s': max(warm), 'iterations_median': statistics.median(r['iterations'] for r in runs),
           'runs': runs}
    out['meets_target'] = out['first_s_incl_build'] <= TARGET_S and out['max_s'] <= TARGET_S
    print(json.dumps(out))
    return 0


if __name__ == '__main__':
    sys.exit(main())
