"""The spatial crane's planning cost beside the one-axis crane's, measured in one run.

Default model (Table 1, tau = 0.01 s), through ``dispatch.plan`` with one ``SolverCache`` (as a worker
process runs requests):
- warm NVF and RVF (robust to L1) solves cycling over varied requests (D 0.28..0.32 m, T 2.9..3.1 s),
  of the cart alone and of the cart with the bridge (0.3 x 0.2 m scaled alike): medians, and the ratio
  two axes / one axis (target <= 3). The planner solves such a straight move on its vertical plane
  (``planning.straight``); ``two_axes_coupled`` is the same requests solved on the coupled NLP, as
  moves from a state, routes and moves under axis limits are (its ratio for information);
- the first solve of each (the NLP built), then the wait until its derivatives are compiled
  (``planning.compiled``: 0 s from the machine's cache; ``compiled`` false when compiling is off);
- a ZV handover planned as the planner serves a new goal mid-move (``transitions.handover_state``
  from a measurement, then ``transitions.retarget``): a ZV motion to 0.6 m, at 40 % a new goal that
  turns it, with one axis and with two (target: median <= 5 ms with two).
The one-axis figures compare with bench/plan_latency.py's of the same host. Prints one JSON object.

    .venv/bin/python bench/spatial.py [--repeats 25]
"""
import argparse
import json
import statistics
import sys
import time

REPEATS = 25
D, DY, T = 0.3, 0.2, 3.0


def varied(k: int) -> tuple[float, float]:
    """The k-th request's scale of the displacement and duration: never the same request twice in a row."""
    return 0.93 + 0.14 * (k % 5) / 4, 0.97 + 0.06 * (k % 7) / 6


def solves(method: str, options, params, bridge: float | None, repeats: int, cache) -> dict:
    from crane_planner.planning.compiled import wait_until_compiled
    from crane_planner.planning.dispatch import plan
    t0 = time.perf_counter()
    plan(method, D, T, params, options, variational=cache, bridge=bridge)
    first = time.perf_counter() - t0
    t0 = time.perf_counter()
    compiled = wait_until_compiled(300.0)
    compile_s = time.perf_counter() - t0
    times = []
    for k in range(repeats):
        s, r = varied(k)
        t0 = time.perf_counter()
        plan(method, D * s, T * r, params, options, variational=cache, bridge=None if bridge is None else bridge * s)
        times.append(time.perf_counter() - t0)
    return {'first_s': round(first, 3), 'compiled': compiled, 'compile_wait_s': round(compile_s, 2),
            'warm_ms': round(1e3 * statistics.median(times), 2)}


def handovers(params, cache, joints: tuple, repeats: int) -> dict:
    """ZV handovers of a running ZV motion to (0.6, 0) at 40 %, to (0.3, 0.4) (or 0.3 m along x alone)."""
    from crane_msgs_py.messages.names import BRIDGE_JOINT, CART_JOINT
    from crane_planner.planning import PlanOptions
    from crane_planner.planning.dispatch import plan
    from crane_planner.planning.signals import Swing
    from crane_planner.serving import transitions
    from crane_planner.serving.transitions import JointReading, Measurement, Running
    from crane_planner.streaming.knots import knot_columns, knot_times
    spatial = BRIDGE_JOINT in joints
    origin = 10_000_000_000
    p = plan('zv', 0.6, T, params, variational=cache, bridge=0.0 if spatial else None)
    t = knot_times(p)
    running = Running(joints, t, *knot_columns(p, t, [0.0] * len(joints)), origin, p)
    goal = {CART_JOINT: 0.3, **({BRIDGE_JOINT: 0.4} if spatial else {})}
    times = []
    for k in range(repeats):
        handover = origin + 1_200_000_000 + 1_000_000 * k  # a different tick each time
        measured_ns = handover - 60_000_000
        refs = running.at(measured_ns)
        swing = Swing.of((0.01, -0.002, 0.004, 0.0, 0.02, 0.0, 0.01, 0.0) if spatial else (0.01, -0.002, 0.02, 0.0),
                         spatial)
        measured = Measurement(measured_ns, {name: JointReading(refs[j][0][0], refs[j][1][0])
                                             for j, name in enumerate(joints)}, swing)
        t0 = time.perf_counter()
        state = transitions.handover_state(running, handover, measured, params)
        transitions.retarget(cache, running, handover, state, 'zv', goal, T, params, PlanOptions())
        times.append(time.perf_counter() - t0)
    return {'median_ms': round(1e3 * statistics.median(times), 2), 'max_ms': round(1e3 * max(times), 2)}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--repeats', type=int, default=REPEATS, help=f'solves per case (default {REPEATS})')
    args = ap.parse_args()
    from crane_msgs_py.crane.params import CraneParams
    from crane_planner.planning import PlanOptions
    from crane_planner.planning.dispatch import SolverCache
    params, cache = CraneParams(), SolverCache()
    result = {}
    for method, options in (('nvf', PlanOptions()), ('rvf', PlanOptions(robust=('L1',)))):
        one = solves(method, options, params, None, args.repeats, cache)
        two = solves(method, options, params, DY, args.repeats, cache)
        coupled = solves(method, options, params, DY, args.repeats, SolverCache(straight_moves_in_their_plane=False))
        ratio = two['warm_ms'] / one['warm_ms']
        result[method] = {'one_axis': one, 'two_axes': two, 'ratio_warm': round(ratio, 2),
                          'meets_target': ratio <= 3.0, 'two_axes_coupled': coupled,
                          'ratio_warm_coupled': round(coupled['warm_ms'] / one['warm_ms'], 2)}
    one = handovers(params, cache, ('cart',), args.repeats)
    two = handovers(params, cache, ('cart', 'bridge'), args.repeats)
    result['zv_handover'] = {'one_axis': one, 'two_axes': two, 'meets_target': two['median_ms'] <= 5.0}
    result['pass'] = all(v['meets_target'] for v in result.values() if isinstance(v, dict))
    json.dump(result, sys.stdout, indent=1)
    print()
    return 0


if __name__ == '__main__':
    sys.exit(main())
