"""crane-plan with --keep-out and --margin (contract "Routes and protected areas"), in-process through
``cli.main``: a plan through a box refused in one line naming it, one past it with its clearance, bad boxes
refused naming the option."""
import json

import pytest

from crane_planner.tools.cli import main

TASK = ['--displacement', '0.6', '--duration', '4', '--tau', '0']
#: The contract's wall, 0.10 m above the hanging load (at -0.861 m): -inf as a shell user types it.
WALL = ['--keep-out', '0.25', '0.35', '-inf', 'inf', '-2', '-0.76']


def run(capsys, *args):
    status = main(list(args))
    out = capsys.readouterr()
    return status, out.out, out.err


def test_a_plan_through_the_wall_is_refused_in_one_line_naming_it(capsys):
    status, out, err = run(capsys, 'plan', '--method', 'zv', *TASK, *WALL)
    assert status == 2 and out == '' and err.count('\n') == 1
    assert err.startswith('crane-plan: error: the zv plan does not keep out: the load (m2) comes 50.0 mm into '
                          'keep_out box 1 (x 0.25..0.35, y -inf..inf, z -2..-0.76 m)')


def test_a_plan_above_the_wall_reports_its_clearance_in_json_and_in_the_table(capsys):
    status, out, err = run(capsys, 'plan', '--method', 'nvf', *TASK, '--L1', '0.32', *WALL, '--json')
    assert status == 0, err
    assert json.loads(out)['min_clearance'] == pytest.approx(0.049, abs=1e-4)
    status, out, err = run(capsys, 'plan', '--method', 'zv', *TASK, '--L1', '0.32', *WALL, '--margin', '0.05')
    assert status == 2 and 'passes 49.0 mm from keep_out box 1' in err and '(margin 50 mm)' in err
    status, out, err = run(capsys, 'compare', '--methods', 'zv,nvf', *TASK, '--L1', '0.32', *WALL)
    assert status == 0 and 'clear mm' in out and out.count('49.0') == 2


def test_compare_skips_each_method_that_does_not_keep_out_saying_why(capsys):
    status, out, err = run(capsys, 'compare', *TASK, *WALL)
    assert status == 2 and out == ''
    assert 'crane-plan: skipped zv: the zv plan does not keep out: the load (m2) comes' in err
    assert 'crane-plan: skipped nvf: the nvf plan does not keep out' in err
    assert err.endswith('crane-plan: error: no method could make this plan\n')


@pytest.mark.parametrize('args, words', [
    (['--keep-out', '0.35', '0.25', '0', '1', '0', '1'], 'argument --keep-out: box 1: x min 0.35 > max 0.25'),
    (['--keep-out', '0', '1', 'nan', '1', '0', '1'], 'argument --keep-out: must be a number or +-inf, got nan'),
    ([*WALL, '--margin', '-0.1'], 'argument --margin: must be finite and >= 0 m, got -0.1'),
    ([*WALL[:-1]], 'argument --keep-out: expected 6 arguments'),
])
def test_a_bad_box_or_margin_is_refused_naming_the_option(capsys, args, words):
    status, out, err = run(capsys, 'plan', '--method', 'zv', *TASK, *args)
    assert status == 2 and err == f'crane-plan: error: {words}\n'


def test_a_goal_inside_a_box_is_refused_naming_it(capsys):
    status, out, err = run(capsys, 'plan', '--method', 'zv', '--displacement', '0.3', '--duration', '4', *WALL)
    assert status == 2 and 'the goal: the load (m2) at rest there, at (0.300, 0.000, -0.861) m, is inside ' \
                           'keep_out box 1' in err


def test_nvf_with_a_hoist_held_routes_over_the_wall_and_reports_its_clearance(capsys, tmp_path):
    png = tmp_path / 'wall.png'
    status, out, err = run(capsys, 'plan', '--method', 'nvf', *TASK, '--hoist', '0.47', '0.47', *WALL, '--json',
                           '--plot', str(png))
    assert status == 0, err
    assert png.stat().st_size > 20_000  # with the side and top views of the boxes and the masses' paths
    report = json.loads(out)
    assert 0.02 <= report['min_clearance'] < 0.04 and report['residual']['load_mm'] < 0.1
    assert report['hoist']['goal'] == pytest.approx(0.47, abs=1e-9)


def test_via_points_nvf_passes_them_a_shaper_off_its_line_is_refused_naming_the_point(capsys):
    task = ['--displacement', '0.6', '--bridge', '0.4', '--duration', '4', '--tau', '0']
    status, out, err = run(capsys, 'plan', '--method', 'nvf', *task, '--via', '0.5,0.0', '--json')
    assert status == 0 and json.loads(out)['residual']['load_mm'] < 0.1, err
    status, out, err = run(capsys, 'plan', '--method', 'zv', *task, '--via', '0.5,0.0')
    assert status == 2 and err.startswith("crane-plan: error: argument --via: point 1 (cart 0.5, bridge 0 m) is "
                                          "277 mm from the zv plan's straight path, beyond via_tolerance 10 mm")
    status, out, err = run(capsys, 'plan', '--method', 'zv', *task, '--via', '0.3,0.2')  # on its line
    assert status == 0, err
    status, out, err = run(capsys, 'plan', '--method', 'nvf', *task, '--via', '0.5')
    assert status == 2 and err == ('crane-plan: error: argument --via: point 1: 1 value(s) for 2 joint(s) '
                                   '(cart, bridge)\n')
    status, out, err = run(capsys, 'plan', '--method', 'nvf', *task, '--via', '0.5,x')
    assert status == 2 and err == "crane-plan: error: argument --via: '0.5,x' is not comma-separated numbers\n"
