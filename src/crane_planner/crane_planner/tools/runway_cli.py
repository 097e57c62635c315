"""``crane-plan runway FILE.yaml``: several cranes' moves on one runway planned together offline, first
published, first served (``runway.together``), beside each crane alone and the anchors' rule
(``runway.anchors``); a runway view with ``--plot``. No ROS.

The file (docs/cli.md, examples/runway.yaml)::

    min_distance: 0.2            # m (runway_min_distance), > 0; default 0.2
    policy: wait                 # wait | refuse (runway_policy); default wait
    cranes:
      - name: a
        runway_offset: [0.0, 0.0]          # m, crane_base in runway; default [0, 0]
        start: {cart: 0.5, bridge: 1.0}    # m, in crane_base; default 0 each
        params: {L1: 0.47, tau: 0.01}      # the planning model (Table 1 by default)
        shape: {girder_half_width: 0.05, load_half_size: 0.05}
    moves:
      - {crane: a, method: nvf, goal: {bridge: 0.0}, duration: 4.0, start: 0.0}
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from crane_msgs_py.crane.params import PARAMETER_NAMES, CraneParams, ParameterError
from crane_planner.planning import METHODS

from ..runway.anchors import anchors_rule
from ..runway.config import POLICIES
from ..runway.occupancy import Shape, separation
from ..runway.together import AXES, Crane, Move, Scenario, Together, nearest_of, plan_together

#: The keys each part of the file may have (the first of each tuple is required for moves and cranes).
TOP_KEYS = ('cranes', 'moves', 'min_distance', 'policy')
CRANE_KEYS = ('name', 'runway_offset', 'start', 'params', 'shape')
MOVE_KEYS = ('crane', 'method', 'goal', 'duration', 'start')
SHAPE_KEYS = ('girder_half_width', 'load_half_size')


class ScenarioError(ValueError):
    """A runway file that is not what ``crane-plan runway`` reads: the message names the file, the place and
    the problem."""


def add_options(p) -> None:
    p.add_argument('file', metavar='FILE.yaml', help='the cranes and their moves (see docs/cli.md)')
    p.add_argument('--json', action='store_true', help='print the moves, the closest distances and the totals as '
                                                       'one JSON object')
    p.add_argument('--plot', metavar='FILE', help='write a PNG: y along the runway against time per crane (girder '
                                                  'strip, load band) and a top view where two cranes come closest')


def _number(where: str, value, low: float | None = None, strict: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ScenarioError(f'{where} must be a number, got {value!r}')
    v = float(value)
    if not math.isfinite(v):
        raise ScenarioError(f'{where} must be finite, got {v}')
    if low is not None and (v <= low if strict else v < low):
        raise ScenarioError(f'{where} must be {">" if strict else ">="} {low:g}, got {v:g}')
    return v


def _mapping(where: str, value, keys: tuple, required: tuple = ()) -> dict:
    if not isinstance(value, dict):
        raise ScenarioError(f'{where} must be a mapping of {", ".join(keys)}, got {value!r}')
    unknown = [str(k) for k in value if k not in keys]
    if unknown:
        raise ScenarioError(f'{where}: unknown key(s) {", ".join(unknown)}; known: {", ".join(keys)}')
    missing = [k for k in required if k not in value]
    if missing:
        raise ScenarioError(f'{where}: missing {", ".join(missing)}')
    return value


def _list(where: str, value) -> list:
    if not isinstance(value, list) or not value:
        raise ScenarioError(f'{where} must be a non-empty list, got {value!r}')
    return value


def _axes(where: str, value, required: bool) -> dict:
    value = _mapping(where, value, AXES)
    if required and not value:
        raise ScenarioError(f'{where} must name at least one of {", ".join(AXES)}')
    return {axis: _number(f'{where}.{axis}', v) for axis, v in value.items()}


def _crane(where: str, value) -> Crane:
    c = _mapping(where, value, CRANE_KEYS, ('name',))
    name = c['name']
    if not isinstance(name, str) or not name.strip():
        raise ScenarioError(f'{where}.name must be a non-empty string, got {name!r}')
    offset = c.get('runway_offset', [0.0, 0.0])
    if not isinstance(offset, list) or len(offset) != 2:
        raise ScenarioError(f'{where}.runway_offset must be [x, y] (m), got {offset!r}')
    offset = tuple(_number(f'{where}.runway_offset[{k}]', v) for k, v in enumerate(offset))
    start = {'cart': 0.0, 'bridge': 0.0, **_axes(f'{where}.start', c.get('start', {}), False)}
    params = _mapping(f'{where}.params', c.get('params', {}), PARAMETER_NAMES)
    try:
        model = CraneParams().replace(**{k: _number(f'{where}.params.{k}', v) for k, v in params.items()})
    except ParameterError as e:
        raise ScenarioError(f'{where}.params: {e}') from None
    shape = _mapping(f'{where}.shape', c.get('shape', {}), SHAPE_KEYS)
    shape = Shape(**{k: _number(f'{where}.shape.{k}', v, 0.0) for k, v in shape.items()})
    return Crane(name, offset, start, model, shape)


def _move(where: str, value, names: tuple) -> Move:
    m = _mapping(where, value, MOVE_KEYS, MOVE_KEYS[:4])
    if m['crane'] not in names:
        raise ScenarioError(f'{where}.crane: no crane named {m["crane"]!r}; the cranes: {", ".join(names)}')
    if m['method'] not in METHODS:
        raise ScenarioError(f'{where}.method must be one of {", ".join(METHODS)}, got {m["method"]!r}')
    return Move(m['crane'], m['method'], _axes(f'{where}.goal', m['goal'], True),
                _number(f'{where}.duration', m['duration'], 0.0, strict=True),
                _number(f'{where}.start', m.get('start', 0.0), 0.0))


def scenario_of(data) -> Scenario:
    """The scenario a runway file's ``data`` (parsed YAML) describes; ScenarioError naming the place."""
    top = _mapping('the file', data, TOP_KEYS, ('cranes', 'moves'))
    cranes = tuple(_crane(f'cranes[{k}]', c) for k, c in enumerate(_list('cranes', top['cranes'])))
    names = tuple(c.name for c in cranes)
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise ScenarioError(f'cranes: the name(s) {", ".join(twice)} given more than once')
    moves = tuple(_move(f'moves[{k}]', m, names) for k, m in enumerate(_list('moves', top['moves'])))
    min_distance = _number('min_distance', top.get('min_distance', 0.2), 0.0, strict=True)
    policy = top.get('policy', 'wait')
    if policy not in POLICIES:
        raise ScenarioError(f'policy must be one of {", ".join(POLICIES)}, got {policy!r}')
    for k, a in enumerate(cranes):
        for b in cranes[k + 1:]:
            gap = float(separation(a.at_rest(a.start), a.shape, b.at_rest(b.start), b.shape)[0])
            if gap < min_distance:
                raise ScenarioError(f'cranes {a.name!r} and {b.name!r} start {gap:.3f} m apart (girders and loads), '
                                    f'closer than min_distance {min_distance:g} m: check their runway_offset '
                                    'and start')
    return Scenario(cranes, moves, min_distance, policy)


def read_scenario(path: str) -> Scenario:
    """The scenario in the YAML file ``path``; ScenarioError (or OSError) naming the file and the problem."""
    import yaml
    try:
        data = yaml.safe_load(Path(path).read_bytes())
    except yaml.YAMLError as e:
        mark = getattr(e, 'problem_mark', None)
        where = f' (line {mark.line + 1})' if mark is not None else ''
        why = getattr(e, 'problem', None) or str(e).splitlines()[0]
        raise ScenarioError(f'{path}: not YAML{where}: {why}') from None
    try:
        return scenario_of(data)
    except ScenarioError as e:
        raise ScenarioError(f'{path}: {e}') from None


def report(together: Together) -> dict:
    """The JSON object of ``--json``."""
    s = together.scenario
    rule = anchors_rule(together)
    moves = []
    for p in together.placed:
        entry = {'move': p.index + 1, 'crane': p.move.crane, 'method': p.move.method, 'duration_s': p.move.duration,
                 'asked_s': p.asked, 'refused': p.refused or None}
        if p.refused:
            entry['in_the_way'] = p.refused_by
        else:
            entry.update(delay_s=p.delay, start_s=p.start, end_s=p.end, waited_for=p.waited_for or None,
                         closest={name: {'distance_m': c.distance, 't_s': c.stamp_ns * 1e-9}
                                  for name, c in together.closest(p).items()})
        moves.append(entry)
    total, alone = together.total(), together.alone()
    return {'min_distance': s.min_distance, 'policy': s.policy, 'cranes': [c.name for c in s.cranes],
            'moves': moves, 'total_s': total, 'alone_s': alone, 'anchors_rule_s': rule.total,
            'refused': sum(1 for p in together.placed if p.refused)}


def print_report(r: dict) -> None:
    print(f'runway: {_count(len(r["cranes"]), "crane")}, {_count(len(r["moves"]), "move")}; min distance '
          f'{r["min_distance"]:.3f} m, policy {r["policy"]}')
    print(f'{"move":>4} {"crane":<8}{"method":<7}{"asked s":>8}{"delay s":>8}{"start s":>8}{"end s":>8}  '
          f'{"waited for":<11}closest m (at s)')
    for m in r['moves']:
        head = f'{m["move"]:>4} {m["crane"]:<8}{m["method"]:<7}{m["asked_s"]:>8.3f}'
        if m['refused']:
            print(f'{head}  refused: {m["refused"]}')
            continue
        near = '  '.join(f'{name} {c["distance_m"]:.3f} ({c["t_s"]:.2f})' for name, c in m['closest'].items())
        print(f'{head}{m["delay_s"]:>8.3f}{m["start_s"]:>8.3f}{m["end_s"]:>8.3f}  {m["waited_for"] or "-":<11}'
              f'{near}')
    alone, rule = r['alone_s'], r['anchors_rule_s']
    print(f'total {r["total_s"]:.3f} s: each crane alone {alone:.3f} s'
          + (f' ({r["total_s"] / alone:.3f}x)' if alone > 0 else '')
          + f', keeping the anchors\' speed-dependent distance {rule:.3f} s'
          + (f' ({r["total_s"] / rule:.3f}x)' if rule > 0 else ''))


def _count(n: int, what: str) -> str:
    return f'{n} {what}' + ('s' if n != 1 else '')


def cmd_runway(args, say) -> int:
    """``crane-plan runway``: ``say`` prints a note (to stderr with ``--json``)."""
    scenario = read_scenario(args.file)
    try:
        together = plan_together(scenario)
    except ValueError as e:  # a move its method cannot plan (named by plan_together)
        raise ScenarioError(f'{args.file}: {e}') from None
    r = report(together)
    if args.json:
        print(json.dumps(r))
    else:
        print_report(r)
    if args.plot:
        say(f'wrote {plot_runway(together, args.plot)}')
    return 0


def plot_runway(together: Together, path: str) -> str:
    """A PNG at ``path``: each crane's girder strip and load band (y along the runway) against time, the
    waits marked; beside it the cranes from above where two of them come closest."""
    from .figures import plt, save_figure
    s = together.scenario
    end = max([o.end_ns for o in together.timelines.values()] + [1]) * 1e-9
    t = np.linspace(0.0, end, 1001)
    stamps = np.round(t * 1e9).astype(np.int64)
    fig, (view, top) = plt.subplots(1, 2, figsize=(13, 5.5), gridspec_kw={'width_ratios': (2.2, 1)})
    colours = plt.rcParams['axes.prop_cycle'].by_key()['color']
    for k, crane in enumerate(s.cranes):
        f, c = together.timelines[crane.name].at(stamps), colours[k % len(colours)]
        g, h = crane.shape.girder_half_width, crane.shape.load_half_size
        view.fill_between(t, f.girder - g, f.girder + g, color=c, alpha=0.8, lw=0, label=f'{crane.name}: girder')
        ys = f.masses[:, :, 1]
        view.fill_between(t, ys.min(axis=1) - h, ys.max(axis=1) + h, color=c, alpha=0.3, lw=0,
                          label=f'{crane.name}: load')
    for p in together.moved:
        if p.delay > 0:
            y = float(together.timelines[p.move.crane].at(np.array([round(p.start * 1e9)])).girder[0])
            view.annotate('', xy=(p.start, y), xytext=(p.asked, y), arrowprops={'arrowstyle': '->', 'lw': 1.2})
            view.text(p.asked, y, f' waits {p.delay:.2f} s for {p.waited_for}', va='bottom', fontsize=8)
    near = nearest_of({(p.index, name): c for p in together.moved for name, c in together.closest(p).items()})
    at = near.stamp_ns if near is not None else 0
    view.axvline(at * 1e-9, color='k', lw=0.7, ls=':')
    view.set_xlabel('time (s)')
    view.set_ylabel('y along the runway (m)')
    view.grid(True, alpha=0.3)
    view.legend(fontsize=7, ncol=2, loc='best')
    view.set_title('the runway: girders and loads over time')
    _top_view(top, together, at, colours)
    top.set_ylim(view.get_ylim())
    if near is not None:
        top.set_title(f'from above at {at * 1e-9:.2f} s: {near.distance:.3f} m apart (min {s.min_distance:g} m)')
    return save_figure(fig, path)


def _top_view(ax, together: Together, at_ns: int, colours) -> None:
    from matplotlib.patches import Circle
    s = together.scenario
    xs = []
    for k, crane in enumerate(s.cranes):
        f, c = together.timelines[crane.name].at(np.array([at_ns])), colours[k % len(colours)]
        g, h = crane.shape.girder_half_width, crane.shape.load_half_size
        ax.axhspan(f.girder[0] - g, f.girder[0] + g, color=c, alpha=0.8, lw=0)
        m = f.masses[0]
        ax.plot(m[:, 0], m[:, 1], color='k', lw=0.8)
        for x, y in m:
            ax.add_patch(Circle((x, y), h, color=c, alpha=0.5))
        ax.text(m[1, 0], m[1, 1], f' {crane.name}', va='center', fontsize=9)
        xs += list(m[:, 0])
    ax.set_xlim(min(xs) - 1.0, max(xs) + 1.0)
    ax.set_aspect('equal', adjustable='box')
    ax.set_xlabel('x along the trolleys\' rails (m)')
    ax.grid(True, alpha=0.3)
