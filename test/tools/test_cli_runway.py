"""crane-plan runway (contract "Cranes sharing a runway", CLI): several cranes' moves planned together from a
YAML file, in this process through ``cli.main``: the example's waits and distances, the policy refuse, the
figure, and bad files refused in one line naming the place."""
import json
from pathlib import Path

import pytest
from crane_plan_cli import crane_plan as run

EXAMPLE = Path(__file__).resolve().parents[2] / 'examples' / 'runway.yaml'

TWO = """
cranes:
  - {name: a, runway_offset: [0.0, 0.0], start: {cart: 0.5, bridge: 1.0}}
  - {name: b, runway_offset: [0.0, 2.5], start: {cart: 0.5}}
moves:
  - {crane: a, method: zv, goal: {bridge: 0.0}, duration: 4.0}
  - {crane: b, method: zv, goal: {bridge: -1.8}, duration: 2.0, start: 0.1}
"""


def write(tmp_path, text: str) -> Path:
    path = tmp_path / 'runway.yaml'
    path.write_text(text)
    return path


def test_the_example_waits_where_a_move_would_come_too_close_and_keeps_every_crane_clear(tmp_path):
    png = tmp_path / 'runway.png'
    done = run('runway', EXAMPLE, '--json', '--plot', png)
    assert done.returncode == 0, done.stderr
    r = json.loads(done.stdout)
    assert r['cranes'] == ['a', 'b', 'c'] and r['refused'] == 0 and r['min_distance'] == 0.2
    moves = {m['move']: m for m in r['moves']}
    assert [m['move'] for m in r['moves']] == [1, 2, 3, 4]  # in order of publication (their starts)
    # b, following a faster into the space a leaves, waits for it; nobody else waits
    assert moves[2]['waited_for'] == 'a' and moves[2]['delay_s'] > 0.5
    assert moves[2]['start_s'] == pytest.approx(moves[2]['asked_s'] + moves[2]['delay_s'])
    assert all(m['delay_s'] == 0.0 and m['waited_for'] is None for k, m in moves.items() if k != 2)
    # every move's closest distance to every other crane: at least the minimum; b comes closest to a
    distances = [c['distance_m'] for m in r['moves'] for c in m['closest'].values()]
    assert min(distances) >= 0.2 and min(distances) == moves[2]['closest']['a']['distance_m'] < 0.25
    assert set(moves[1]['closest']) == {'b', 'c'} and set(moves[3]['closest']) == {'a', 'b'}
    # a's second move (its cart alone, at 5 s) ends last: waiting cost nothing here; the anchors' rule more
    assert r['total_s'] == pytest.approx(moves[4]['end_s']) == pytest.approx(r['alone_s'])
    assert r['anchors_rule_s'] > r['total_s']
    assert png.stat().st_size > 20_000
    assert done.stderr.strip() == f'wrote {png}'


def test_the_table_says_who_waited_for_whom_and_the_totals(tmp_path):
    done = run('runway', write(tmp_path, TWO))
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert lines[0].startswith('runway: 2 cranes, 2 moves; min distance 0.200 m, policy wait')
    b = next(line for line in lines if line.split()[:3] == ['2', 'b', 'zv'])
    assert b.split()[7] == 'a' and float(b.split()[4]) > 0  # its delay, the crane it waited for
    assert lines[-1].startswith('total ') and 'each crane alone' in lines[-1]


def test_with_the_policy_refuse_the_move_in_the_way_is_refused_naming_the_crane(tmp_path):
    done = run('runway', write(tmp_path, 'policy: refuse\n' + TWO), '--json')
    assert done.returncode == 0, done.stderr
    r = json.loads(done.stdout)
    b = r['moves'][1]
    assert b['crane'] == 'b' and "crane 'a'" in b['refused'] and b['in_the_way'] == 'a'
    assert r['refused'] == 1 and r['total_s'] == pytest.approx(4.0)  # a's move alone


@pytest.mark.parametrize('text, says', [
    ('cranes: [', 'not YAML (line'),
    ('cranes: \x00', 'not YAML: unacceptable character'),
    ('- a\n- b\n', 'the file must be a mapping of cranes, moves'),
    (TWO + 'speed: 3\n', 'unknown key(s) speed'),
    ('cranes: [{name: a}]\n', 'the file: missing moves'),
    ('cranes: []\nmoves: []\n', 'cranes must be a non-empty list'),
    (TWO.replace('name: b', 'name: a'), 'the name(s) a given more than once'),
    (TWO.replace('crane: b', 'crane: z'), "moves[1].crane: no crane named 'z'"),
    (TWO.replace('method: zv, goal: {bridge: -1.8}', 'method: fast, goal: {bridge: -1.8}'),
     'moves[1].method must be one of'),
    (TWO.replace('duration: 2.0', 'duration: -1'), 'moves[1].duration must be > 0, got -1'),
    (TWO.replace('start: 0.1', 'start: .nan'), 'moves[1].start must be finite'),
    (TWO.replace('start: 0.1', 'start: soon'), "moves[1].start must be a number, got 'soon'"),
    (TWO.replace('goal: {bridge: -1.8}', 'goal: {hoist: 0.3}'), 'moves[1].goal: unknown key(s) hoist'),
    (TWO.replace('goal: {bridge: -1.8}', 'goal: {}'), 'moves[1].goal must name at least one of cart, bridge'),
    (TWO.replace('runway_offset: [0.0, 2.5]', 'runway_offset: [2.5]'), 'cranes[1].runway_offset must be [x, y]'),
    (TWO.replace('start: {cart: 0.5}}', 'start: {cart: 0.5}, params: {L1: -1}}'), 'cranes[1].params: L1'),
    (TWO.replace('start: {cart: 0.5}}', 'start: {cart: 0.5}, shape: {load_half_size: -0.1}}'),
     'cranes[1].shape.load_half_size must be >= 0'),
    (TWO.replace('runway_offset: [0.0, 2.5]', 'runway_offset: [0.0, 1.1]'),
     "cranes 'a' and 'b' start 0.000 m apart"),
    ('min_distance: 0\n' + TWO, 'min_distance must be > 0'),
    ('policy: stop\n' + TWO, "policy must be one of wait, refuse, got 'stop'"),
    (TWO.replace('goal: {bridge: 0.0}', 'goal: {bridge: 1.0}'), "move 1 (crane 'a', zv): its goal is where"),
    (TWO.replace('method: zv, goal: {bridge: -1.8}', 'method: zvdd, goal: {bridge: -1.8}'),
     "move 2 (crane 'b', zvdd): zvdd needs a duration longer than its shaper"),
])
def test_a_bad_file_is_refused_in_one_line_naming_the_place(tmp_path, text, says):
    path = write(tmp_path, text)
    done = run('runway', path, '--json')
    assert done.returncode == 2 and done.stdout == ''
    assert done.stderr.count('\n') == 1 and done.stderr.startswith(f'crane-plan: error: {path}: '), done.stderr
    assert says in done.stderr, done.stderr


def test_a_missing_file_is_refused_in_one_line(tmp_path):
    done = run('runway', tmp_path / 'none.yaml')
    assert done.returncode == 2 and done.stderr.count('\n') == 1 and 'none.yaml' in done.stderr
