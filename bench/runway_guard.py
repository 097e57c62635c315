"""The runway guard's cost per tick in the streamer's 1 kHz loop (``streaming.runway_guard.RunwayGuard.watch``).

What the loop adds per tick with ``runway`` on: the other cranes' states taken from the inbox (each heard every 20
ms, as /runway/state comes), this crane's stopping envelope from the published setpoint and how its stop would
travel, and the guard's verdict. Two runs of 10 s each, timed tick by tick:

- ``operator``: operator mode, the stick at full speed (0.3 m/s) on the bridge towards a crane 2 m away (the
  guard stops it there, then refuses), the exact travel of the operator's stop asked each tick;
- ``trajectory``: a bridge motion of 1.2 m in 6 s streamed by the trajectory source (the reach of its stops looked
  up in the motion's ``StopTable``, whose making on the accepting thread is timed apart: ``stop_table_ms``), its
  own published occupancy (20 ms samples) followed, the others on their plans too: their footprints compared.

Each with 1 and 3 other cranes. Median, p99 and max in microseconds, and beside them the source's own sample
(``source_sample``: what the loop pays per tick anyway). Target: a median of at most 10 us. Prints one JSON object.
"""
import json
import statistics
import time

import numpy as np

from crane_msgs_py.crane.axes import AxisLimits
from crane_msgs_py.crane.params import CraneParams
from crane_planner.runway.config import RunwayConfig
from crane_planner.streaming.config import OPERATOR_LIMITS
from crane_planner.streaming.operator import OperatorStream
from crane_planner.streaming.reference_stream import ReferenceStream
from crane_planner.streaming.runway_guard import PlannedStop, RunwayGuard, first_period

TICK_NS = 1_000_000
MODEL = CraneParams()
LIMITS = AxisLimits(*OPERATOR_LIMITS['travel'])
JOINTS = ('cart', 'bridge')
TARGET_US = 10.0
SECONDS = 10.0


def guard() -> RunwayGuard:
    config = RunwayConfig(True, 'a', (0.0, 0.0), 0.2, 'wait', 0.5)
    return RunwayGuard(config, JOINTS, TICK_NS * 1e-9, PlannedStop(first_period(MODEL), 0.5, 5.0),
                       LIMITS.max_velocity, LIMITS.max_acceleration, LIMITS.max_jerk)


def summary(x) -> dict:
    x = sorted(x)
    return {'median_us': round(statistics.median(x), 2), 'p99_us': round(x[int(0.99 * len(x))], 2),
            'max_us': round(x[-1], 2)}


def run(source, sample, neighbours: int, own=None, motion=None) -> dict:
    g = guard()
    if own is not None:
        g.own(*own)
    table_ms = None
    if motion is not None:  # (its stops tabulated as the stream accepted it: the accepting thread's cost)
        t0 = time.perf_counter_ns()
        g.accepted(motion)
        table_ms = round((time.perf_counter_ns() - t0) * 1e-6, 2)
    others = [(f'c{k}', 1.95 + 3.0 * k, 2.05 + 3.0 * k) for k in range(neighbours)]
    watch, sampling, levels = [], [], set()
    for k in range(round(SECONDS * 1000)):
        stamp = k * TICK_NS
        for j, (name, low, high) in enumerate(others):
            if k % 20 == j:  # each heard every 20 ms (the executor's side: not timed)
                g.heard(name, low, high, stamp, (low, high), own is not None)
        t0 = time.perf_counter_ns()
        setpoint = sample(k)
        t1 = time.perf_counter_ns()
        g.watch(stamp, setpoint, source)
        t2 = time.perf_counter_ns()
        sampling.append((t1 - t0) * 1e-3)
        watch.append((t2 - t1) * 1e-3)
        levels.add(g.verdict.level.name.lower())
    result = {'watch': summary(watch), 'source_sample': summary(sampling), 'levels_seen': sorted(levels),
              'ticks': len(watch)}
    if table_ms is not None:
        result['stop_table_ms'] = table_ms
    return result


def operator(neighbours: int) -> dict:
    clock = [0.0]
    op = OperatorStream(TICK_NS * 1e-9, (0.0, 0.0), [LIMITS, LIMITS], 'zv', MODEL, clock=lambda: clock[0],
                        joints=JOINTS)

    def sample(k):
        clock[0] = k * 1e-3
        op.command(0.0, 0.3)
        return op.sample(k)
    return run(op, sample, neighbours)


def trajectory(neighbours: int) -> dict:
    stream = ReferenceStream(TICK_NS, (0.0, 0.0))
    tick = [0]
    assert stream.start(0, lambda: tick[0])
    t = np.linspace(0.0, 6.0, 13)
    s = t / 6.0
    p = 1.2 * s ** 3 * (10 - 15 * s + 6 * s * s)
    v = 1.2 / 6.0 * 30 * s ** 2 * (1 - s) ** 2
    a = 1.2 / 36.0 * 60 * s * (1 - 3 * s + 2 * s * s)
    zero = np.zeros_like(t)
    motion = stream.accept(t, *(np.column_stack([zero, x]) for x in (p, v, a)), 2 * TICK_NS, 0)

    def sample(k):
        tick[0] = k
        return stream.sample(k)
    samples = np.arange(0.0, 6.0 + 1e-9, 0.02)  # (its occupancy as the planner publishes it: every 20 ms)
    u = samples / 6.0
    own = (2 * TICK_NS, samples, 1.2 * u ** 3 * (10 - 15 * u + 6 * u * u))
    return run(stream, sample, neighbours, own, motion)


def main():
    result = {f'{mode.__name__}_{n}': mode(n) for mode in (operator, trajectory) for n in (1, 3)}
    worst = max(r['watch']['median_us'] for r in result.values())
    result.update(target_median_us=TARGET_US, worst_median_us=worst, meets_target=worst <= TARGET_US)
    print(json.dumps(result))


if __name__ == '__main__':
    main()
