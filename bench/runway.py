"""Cranes sharing a runway, offline: seeded scenarios planned together first published, first served
(``runway.together``), checked densely, timed against each crane alone and against the anchors' rule, and the
planning cost of a goal among published occupancies. Prints one JSON object.

Each scenario (seeded by its number): 2-4 cranes of the paper's model (Table 1, tau 0.01 s) on one runway,
their bridges 0.6-2.5 m apart (their ``runway_offset``), loads on 0.47 + 0.391 m cables, girders and loads
0.05 m in half-size, min distance 0.2 m, policy wait. Each crane makes one move: asked at a random time, within
0.3 s of the others' in half the scenarios (sent together), within 2 s in the others; by a method drawn among
the shapers ZV, NZV, ZVD, EI, MZV and NVF; its bridge to a random goal within 2.5 m of its start (0.05 m
grid), its cart to one within 0.2-1.2 m; in a duration drawn within 2.5 s above 1.25 s per metre of the
bridge's travel (at least 2 s, 3 s for ZVD and EI, which last 2.42 s themselves; 0.5 s grid). The goals keep
the cranes' order along the runway, each 0.35 m (girder to girder) from the goals published before it and
from where the cranes published after it stand then, so that every move has a start that keeps it clear
(first published, first served refuses a goal into a crane standing for good); 70 % of them as far as that
allows to one side (a crane following one that leaves, or coming up to one). Plans are cached by method,
displacements and duration (NVF is the slow one to solve).

- ``violations`` (a): scenarios where two cranes come closer than the min distance, checked every 1 ms
  independently of the occupancies' samples and the schedule's: each move's masses predicted again on the
  planning model at 1 ms steps (``planning.mass_path.predict_mass_path``) until 12 s after its motion (a load
  left swinging swings on), its girder on the bridge's reference, each crane on its latest move from its start
  on, with its nominal shape.
- ``vs_alone`` (b): the time from the first start asked for to the end of the last motion, against the same
  moves with each crane alone on the runway (none delayed), over the scenarios where no move was refused: the
  sums and their ratio (target <= 1.15), and the ratio per scenario (median, p95, max, how many over 1.15).
- ``vs_anchors`` (c): the same against the anchors' rule on the same moves (``runway.anchors``: a move waits
  until the other has finished whenever it would come within the min distance plus both cranes' braking
  distances at their speeds then), over the scenarios where neither refused a move: both sums and their ratio
  (target < 1), and how many scenarios took longer or shorter.
- ``planning`` (d): a goal (the paper's crane, its bridge 1.75-1.85 m in 2.5 s) planned, its occupancy
  predicted and scheduled (``dispatch.plan`` + ``prediction.plan_occupancy`` + ``schedule.schedule``) against three
  published occupancies (one of them in its way: it waits) and against none, alternated in one run (which of
  the two goes first alternating too): medians per method (ZV, NVF), their ratio (target <= 2) and the
  schedule's own share.
- ``worst``: the scenarios with the largest ratios and the smallest dense distances, with their moves.

    nice -n 19 .venv/bin/python bench/runway.py [--scenarios 1000] [--seed 0] [--repeats 30]
"""
import argparse
import json
import math
import statistics
import sys
import time

import numpy as np

SCENARIOS, REPEATS = 1000, 30
MIN_DISTANCE = 0.2
METHODS = ('zv', 'nzv', 'zvd', 'ei', 'mzv', 'nvf')
#: The shortest duration (s) drawn per method: ZVD and EI last two periods of the slow mode (2.42 s) themselves.
SHORTEST = {'zv': 2.0, 'nzv': 2.0, 'zvd': 3.0, 'ei': 3.0, 'mzv': 2.0, 'nvf': 2.0}
#: Girder to girder (m) a goal keeps from where another crane stands when it is published and from earlier goals.
REST_GAP = 0.35
#: Half the scenarios' moves are asked within TOGETHER s of each other (sent together), the others' within APART s.
TOGETHER, APART = 0.3, 2.0
#: The share of goals drawn as far as the others allow (to one side, within 0.3 m of the bound).
AS_FAR = 0.7
DENSE_STEP = 1e-3
#: How long (s) after its motion the dense check follows each move's masses: past the end of any scenario, well
#: beyond the occupancies' own 2 s (a load a plan leaves swinging swings on).
DENSE_SETTLE = 12.0
TARGETS = {'violations': 0, 'vs_alone': 1.15, 'vs_anchors_below': 1.0, 'planning_ratio': 2.0}


def grid(value: float, step: float) -> float:
    return round(round(value / step) * step, 6)


def draw(number: int, seed: int = 0):
    """Scenario ``number``: (cranes, moves) as ``runway.together`` takes them."""
    from crane_planner.runway.together import Crane, Move, Scenario
    rng = np.random.default_rng([seed, number])
    n = int(rng.integers(2, 5))
    ys = np.cumsum([0.0, *rng.uniform(0.6, 2.5, n - 1)]).round(3)
    spread = TOGETHER if rng.uniform() < 0.5 else APART
    starts = rng.uniform(0.0, spread, n).round(2)  # crane c (c0, c1, ... along y) asks at starts[c]
    order = sorted(range(n), key=lambda c: (starts[c], f'c{c}'))  # who is published first (Scenario.order)
    for _ in range(1000):  # a crane hemmed in within 0.2 m of its start: all drawn again
        goals = _goals(rng, ys, order)
        if goals is not None:
            break
    else:
        raise RuntimeError(f'scenario {number}: no goals found')
    cranes, moves = [], []
    for c in range(n):
        name = f'c{c}'
        cart0 = grid(rng.uniform(0.2, 1.2), 0.05)
        cranes.append(Crane(name, (0.0, float(ys[c])), {'cart': cart0, 'bridge': 0.0}))
        dy, method = goals[c] - ys[c], str(rng.choice(METHODS))
        shortest = max(SHORTEST[method], 1.25 * abs(dy))
        moves.append(Move(name, method, {'cart': grid(rng.uniform(0.2, 1.2), 0.05), 'bridge': grid(dy, 0.05)},
                          grid(rng.uniform(shortest, shortest + 2.5), 0.5), float(starts[c])))
    return Scenario(tuple(cranes), tuple(moves), MIN_DISTANCE, 'wait')


def _goals(rng, ys, order) -> list:
    """Bridge goals (runway y), drawn in order of publication: each keeps the cranes' order, ``REST_GAP`` from
    the goals published before it and from where the cranes published after it stand; most (``AS_FAR``) as
    far as that allows to one side (within 0.3 m of the bound: a crane following one that leaves, or coming
    up to one), the others anywhere within it; each at least 0.2 m from its start."""
    n, goals = len(ys), [None] * len(ys)
    for k, c in enumerate(order):
        lo, hi = ys[c] - 2.5, ys[c] + 2.5
        for o in range(n):
            if o != c:
                there = goals[o] if o in order[:k] else ys[o]
                lo, hi = (max(lo, there + REST_GAP), hi) if o < c else (lo, min(hi, there - REST_GAP))
        for _ in range(100):
            if rng.uniform() < AS_FAR:
                goal = rng.uniform(hi - 0.3, hi) if rng.uniform() < 0.5 else rng.uniform(lo, lo + 0.3)
            else:
                goal = rng.uniform(lo, hi)
            goal = float(ys[c] + grid(min(max(goal, lo), hi) - ys[c], 0.05))
            if lo - 1e-9 <= goal <= hi + 1e-9 and abs(goal - ys[c]) >= 0.2:
                goals[c] = goal
                break
        else:
            return None
    return goals


class Plans:
    """Plans (and their masses predicted every 1 ms) cached by method, displacements and duration."""

    def __init__(self):
        from crane_planner.runway.together import default_planner
        self.make, self.plans, self.paths, self.solved, self.hits = default_planner(), {}, {}, 0, 0

    def __call__(self, method, cart, bridge, duration, params):
        key = (method, round(cart, 6), None if bridge is None else round(bridge, 6), duration)
        if key not in self.plans:
            self.plans[key] = self.make(method, cart, bridge, duration, params)
            self.solved += 1
        else:
            self.hits += 1
        return self.plans[key]

    def dense(self, plan, params):
        """The plan's masses every 1 ms from its start until ``DENSE_SETTLE`` s after it (origin 0): (t, m1, m2)
        in ``crane_base``."""
        from crane_planner.planning.mass_path import predict_mass_path
        key = id(plan)
        if key not in self.paths:
            path = predict_mass_path(plan, params, {}, DENSE_SETTLE, step=DENSE_STEP)
            self.paths[key] = (path.t, path.m1[:, :2], path.m2[:, :2])
        return self.paths[key]


def dense_min_distance(together, plans: Plans) -> float:
    """The least distance between any two cranes, every 1 ms from 0 to the end of the last settle window:
    each crane on its latest move from its start on (masses predicted at 1 ms steps, girder on the bridge's
    reference), at rest where it starts before."""
    from crane_planner.runway.occupancy import Footprint, separation
    s = together.scenario
    end = max(p.occupancy.end_ns for p in together.moved) * 1e-9 if together.moved else 0.0
    t = np.arange(0.0, end + DENSE_STEP, DENSE_STEP)
    tracks = {}
    for crane in s.cranes:
        rest = crane.at_rest(crane.start)
        girder, masses = np.full(len(t), rest.girder[0]), np.repeat(rest.masses, len(t), axis=0)
        for p in sorted((p for p in together.moved if p.move.crane == crane.name), key=lambda p: p.start):
            k = t >= p.start - 1e-12
            rel = t[k] - p.start
            tp, m1, m2 = plans.dense(p.plan, crane.params)
            shift = np.array([crane.offset[0] + p.origin['cart'], crane.offset[1] + p.origin['bridge']])
            for m, path in enumerate((m1, m2)):
                masses[k, m] = np.stack([np.interp(rel, tp, path[:, c]) for c in range(2)], axis=-1) + shift
            bridge = (p.plan.evaluate_axis('bridge', np.minimum(rel, p.plan.duration)).position
                      if 'bridge' in getattr(p.plan, 'axes', {}) else 0.0)
            girder[k] = crane.offset[1] + p.origin['bridge'] + bridge
        tracks[crane.name] = (Footprint(girder, masses), crane.shape)
    names = list(tracks)
    return min((float(separation(*tracks[a], *tracks[b]).min()) for i, a in enumerate(names) for b in names[i + 1:]),
               default=math.inf)


def describe(scenario, together, rule) -> list:
    starts = {m.index: m.start for m in rule.timed}
    return [{'crane': p.move.crane, 'method': p.move.method, 'bridge_m': p.move.goal['bridge'],
             'duration_s': p.move.duration, 'asked_s': p.asked, 'delay_s': round(p.delay, 3),
             'waited_for': p.waited_for or None, 'refused': p.refused or None,
             'anchors_start_s': starts.get(p.index)} for p in together.placed]


def scenarios(count: int, seed: int = 0, progress: bool = False) -> dict:
    """Criteria (a)-(c) over ``count`` scenarios (see the module docstring)."""
    from crane_planner.runway.anchors import anchors_rule
    from crane_planner.runway.together import plan_together
    plans = Plans()
    rows, t0 = [], time.perf_counter()
    for k in range(count):
        scenario = draw(k, seed)
        together = plan_together(scenario, plans)
        rule = anchors_rule(together)
        refused = sum(1 for p in together.placed if p.refused)
        anchors_refused = sum(1 for m in rule.timed if m.refused)
        total, alone = together.total(), together.alone()
        rows.append({'scenario': k, 'cranes': len(scenario.cranes), 'total_s': total, 'alone_s': alone,
                     'anchors_s': rule.total, 'refused': refused, 'anchors_refused': anchors_refused,
                     'delayed': sum(1 for p in together.moved if p.delay > 0),
                     'anchors_delayed': sum(1 for m in rule.timed if m.start > scenario.moves[m.index].start + 1e-9),
                     'dense_min_m': dense_min_distance(together, plans),
                     'moves': describe(scenario, together, rule)})
        if progress and (k + 1) % 50 == 0:
            print(f'[runway] {k + 1}/{count} scenarios, {time.perf_counter() - t0:.0f} s', file=sys.stderr,
                  flush=True)
    return summarize(rows, plans, time.perf_counter() - t0)


def summarize(rows: list, plans: Plans, seconds: float) -> dict:
    """(a) over every scenario; (b) over those where no move was refused; (c) over those where neither the
    planners nor the anchors' rule refused one."""
    placed = [r for r in rows if r['refused'] == 0]
    both = [r for r in placed if r['anchors_refused'] == 0]
    for r in placed:
        r['vs_alone'] = r['total_s'] / r['alone_s']
    for r in both:
        r['vs_anchors'] = r['total_s'] / r['anchors_s']

    def spread(values):
        return {'median': statistics.median(values), 'p95': float(np.percentile(values, 95)), 'max': max(values)}

    def worst(among, key, reverse=True, n=3):  # ties: the scenario with more moves delayed first
        return sorted(among, key=lambda r: (r[key], r['delayed'] if reverse else -r['delayed']), reverse=reverse)[:n]

    ours, alone = sum(r['total_s'] for r in placed), sum(r['alone_s'] for r in placed)
    ours_both, anchors = sum(r['total_s'] for r in both), sum(r['anchors_s'] for r in both)
    vs_alone, vs_anchors = [r['vs_alone'] for r in placed], [r['vs_anchors'] for r in both]
    return {
        'scenarios': len(rows), 'cranes': {n: sum(1 for r in rows if r['cranes'] == n) for n in (2, 3, 4)},
        'moves': sum(len(r['moves']) for r in rows), 'min_distance_m': MIN_DISTANCE,
        'refused_moves': sum(r['refused'] for r in rows),
        'anchors_refused_moves': sum(r['anchors_refused'] for r in rows),
        'delayed_moves': sum(r['delayed'] for r in rows),
        'anchors_delayed_moves': sum(r['anchors_delayed'] for r in rows),
        'violations': sum(1 for r in rows if r['dense_min_m'] < MIN_DISTANCE),
        'dense_min_m': min(r['dense_min_m'] for r in rows),
        'vs_alone': {'scenarios': len(placed), 'total_s': ours, 'alone_s': alone, 'ratio': ours / alone,
                     'per_scenario': spread(vs_alone), 'over_1_15': sum(1 for v in vs_alone if v > 1.15),
                     'longer': sum(1 for v in vs_alone if v > 1.0 + 1e-9)},
        'vs_anchors': {'scenarios': len(both), 'total_s': ours_both, 'anchors_s': anchors,
                       'ratio': ours_both / anchors, 'per_scenario': spread(vs_anchors),
                       'longer': sum(1 for v in vs_anchors if v > 1.0 + 1e-9),
                       'shorter': sum(1 for v in vs_anchors if v < 1.0 - 1e-9)},
        'plans_solved': plans.solved, 'plans_reused': plans.hits, 'seconds': seconds,
        'worst': {'vs_alone': worst(placed, 'vs_alone'), 'vs_anchors': worst(both, 'vs_anchors'),
                  'closest': worst(rows, 'dense_min_m', reverse=False)},
    }


def planning_cost(repeats: int) -> dict:
    """(d): a goal scheduled against three published occupancies and against none, alternated; medians by
    method and their ratio."""
    from crane_msgs_py.crane.params import CraneParams
    from crane_planner.planning.dispatch import PlanOptions, SolverCache, plan
    from crane_planner.runway.occupancy import Shape
    from crane_planner.runway.prediction import plan_occupancy
    from crane_planner.runway.schedule import schedule
    params, shape, options, cache = CraneParams(), Shape(), PlanOptions(), SolverCache()

    def occupancy(name, method, dy, duration, y, start=0):
        p = plan(method, 0.0, duration, params, options, cache, bridge=dy)
        return plan_occupancy(name, p, params, {'cart': 0.5, 'bridge': 0.0}, (0.0, y), start, 0, shape)

    # a leaves slowly ahead of the goal's crane b (b, faster, would catch it up: it waits); c and d elsewhere
    published = [occupancy('a', 'nvf', -1.0, 4.0, 1.0), occupancy('c', 'zv', 0.8, 3.0, 4.5),
                 occupancy('d', 'zv', -0.5, 3.0, -3.0)]

    def goal(method, k, others):
        dy = -1.8 * (0.97 + 0.06 * (k % 5) / 4)  # the goal varied: k and k + 1 differ
        t0 = time.perf_counter()
        mine = occupancy('b', method, dy, 2.5, 2.5)
        t1 = time.perf_counter()
        s = schedule(mine, others, MIN_DISTANCE)
        t2 = time.perf_counter()
        return t2 - t0, t2 - t1, s

    out = {}
    for method in ('zv', 'nvf'):
        goal(method, 0, published)  # warm: the solver built, the code loaded
        times = {'none': [], 'three': []}
        schedules, delays = [], set()
        for k in range(repeats):
            # in turn first: a solve right after the same request starts warmer, whichever case it is
            for case in (('none', 'three') if k % 2 else ('three', 'none')):
                dt, ds, s = goal(method, k, published if case == 'three' else [])
                times[case].append(dt)
                if case == 'three':
                    schedules.append(ds)
                    delays.add((round(s.delay, 3), s.waited_for))
        a, b = (statistics.median(times[case]) * 1e3 for case in ('none', 'three'))
        out[method] = {'none_ms': a, 'three_ms': b, 'ratio': b / a,
                       'schedule_ms': statistics.median(schedules) * 1e3,
                       'delays': sorted([d, w] for d, w in delays)}
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--scenarios', type=int, default=SCENARIOS, help=f'scenarios to run (default {SCENARIOS})')
    ap.add_argument('--seed', type=int, default=0, help='the seed the scenarios are drawn from (default 0)')
    ap.add_argument('--repeats', type=int, default=REPEATS,
                    help=f'requests per method and case of the planning cost (default {REPEATS}; 0: skip it)')
    args = ap.parse_args()
    if args.scenarios < 1:
        ap.error(f'--scenarios must be >= 1, got {args.scenarios}')
    result = {'seed': args.seed, **scenarios(args.scenarios, args.seed, progress=True)}
    if args.repeats > 0:
        result['planning'] = planning_cost(args.repeats)
    checks = {'violations': result['violations'] == TARGETS['violations'],
              'vs_alone': result['vs_alone']['ratio'] <= TARGETS['vs_alone'],
              'vs_anchors': result['vs_anchors']['ratio'] < TARGETS['vs_anchors_below']}
    if 'planning' in result:
        checks['planning'] = all(m['ratio'] <= TARGETS['planning_ratio'] for m in result['planning'].values())
    result.update(targets=TARGETS, meets_target=checks, **{'pass': all(checks.values())})
    print(json.dumps(result, indent=2))
    return 0


if __name__ == '__main__':
    sys.exit(main())
