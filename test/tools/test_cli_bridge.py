"""crane-plan with --bridge (contract "The spatial crane"), run in-process through ``cli.main``: the bridge's
columns and figures, residuals as the norm of the load's horizontal offset, refusals in one line."""
import csv
import json

import numpy as np
import pytest

from crane_planner.tools.cli import main

TASK = ['--displacement', '0.3', '--bridge', '0.2', '--duration', '3']
IDEAL = ['--tau', '0']


def run(capsys, *args):
    """(exit status, stdout, stderr) of ``crane-plan args``."""
    status = main(list(args))
    out = capsys.readouterr()
    return status, out.out, out.err


def read_csv(path) -> tuple[list, np.ndarray]:
    with open(path, newline='') as f:
        rows = list(csv.reader(f))
    return rows[0], np.array(rows[1:], dtype=float)


def test_plan_writes_the_bridges_columns_the_out_of_plane_swing_and_a_top_view(capsys, tmp_path):
    csv_path, png_path = tmp_path / 'zv.csv', tmp_path / 'zv.png'
    status, out, err = run(capsys, 'plan', '--method', 'zv', *TASK, *IDEAL, '--json', '--csv', str(csv_path),
                           '--plot', str(png_path))
    assert status == 0, err
    report = json.loads(out)
    assert report['bridge']['start'] == 0.0 and report['bridge']['goal'] == pytest.approx(0.2)
    # the bridge's share of the straight move: its peaks 2/3 of the cart's (those sampled at 1 ms, the bridge's exact)
    assert report['bridge']['peak']['velocity'] == pytest.approx(report['peak']['velocity'] * 2 / 3, rel=1e-6)
    for group in ('peak', 'rms', 'residual'):
        assert {'theta1', 'theta2', 'phi1', 'phi2'} <= set(report[group])
    assert report['peak']['phi1'] > 0.01  # the load swings across the rail during the move ...
    assert report['residual']['load_mm'] < 0.01  # ... and ZV leaves it at rest (measured 0.002 mm)
    header, rows = read_csv(csv_path)
    assert header == ['time', 'position', 'velocity', 'acceleration', 'jerk', 'theta1', 'theta2', 'bridge_position',
                      'bridge_velocity', 'bridge_acceleration', 'phi1', 'phi2']
    moving = (rows[:, 0] > 0.0) & (rows[:, 0] <= 3.0)
    assert np.max(np.abs(rows[moving, 7] / rows[moving, 1] - 2 / 3)) < 1e-9  # on the straight line
    end = rows[np.searchsorted(rows[:, 0], 3.0)]
    assert end[7] == pytest.approx(0.2, abs=1e-12) and end[8] == end[9] == 0.0
    assert np.abs(rows[:, 10]).max() == pytest.approx(report['peak']['phi1'])
    assert png_path.stat().st_size > 10_000


def test_the_residual_with_a_bridge_is_the_norm_of_the_loads_offset(capsys):
    """The same move along y alone and along x alone, on a plant whose L1 is 10 % off the model: the load swings
    as much either way (the swing's modes are the same in both directions), which only the norm sees."""
    reports = []
    for task in (['--displacement', '0', '--bridge', '0.3'], ['--displacement', '0.3']):
        status, out, err = run(capsys, 'plan', '--method', 'zv', *task, '--duration', '3', *IDEAL,
                               '--plant-L1', '0.517', '--json', '--settle', '5')
        assert status == 0, err
        reports.append(json.loads(out))
    across, along = reports
    assert along['residual']['load_mm'] > 5.0
    assert across['residual']['load_mm'] == pytest.approx(along['residual']['load_mm'], rel=1e-3)
    assert across['residual']['theta1'] < 1e-9 < across['residual']['phi1']


def test_compare_and_sweep_with_a_bridge(capsys, tmp_path):
    status, out, err = run(capsys, 'compare', *TASK, *IDEAL, '--methods', 'zv,zvd,nvf', '--json')
    assert status == 0, err
    reports = {r['method']: r for r in json.loads(out)}
    assert list(reports) == ['zv', 'zvd', 'nvf']
    for method, r in reports.items():  # NVF on the coupled spatial model, the shapers per axis
        assert r['bridge']['goal'] == pytest.approx(0.2), method
        assert r['residual']['load_mm'] < 0.05, method
    status, out, err = run(capsys, 'sweep', '--param', 'L1', '--span', '0.3', '--points', '5', *TASK,
                           '--methods', 'zv,zvd', '--json', '--settle', '5', '--plot', str(tmp_path / 's.png'))
    assert status == 0, err
    result = json.loads(out)
    zv, zvd = result['methods']['zv']['load_mm'], result['methods']['zvd']['load_mm']
    assert zvd[0] < zv[0] and zvd[-1] < zv[-1]  # ZVD's robustness holds across the rail too
    assert (tmp_path / 's.png').stat().st_size > 10_000


def test_fastest_and_choose_keep_the_bridge_within_its_limits(capsys):
    """The bridge limited to 0.1 m/s, the cart to 0.25 m/s: the bridge, moving 0.2 m of the 0.3 m, binds."""
    limits = ['--max-velocity', '0.25', '--max-acceleration', '0.5', '--max-bridge-velocity', '0.1',
              '--max-bridge-acceleration', '0.5']
    status, out, err = run(capsys, 'plan', '--method', 'zv', '--displacement', '0.3', '--bridge', '0.2',
                           '--fastest', *limits, '--json')
    assert status == 0, err
    report = json.loads(out)
    assert report['bridge']['peak']['velocity'] == pytest.approx(0.1, rel=1e-3)
    assert report['bridge']['peak']['velocity'] <= 0.1
    assert report['peak']['velocity'] <= 0.25 and report['bridge']['peak']['acceleration'] <= 0.5
    status, out, err = run(capsys, 'choose', '--displacement', '0.3', '--bridge', '0.2', *limits,
                           '--methods', 'zv,zvd', '--points', '3', '--json')
    assert status == 0, err
    rows = {m['method']: m for m in json.loads(out)['methods']}
    assert rows['zv']['duration'] == pytest.approx(report['duration'], rel=1e-9)
    for row in rows.values():
        assert row['axes']['bridge']['peak']['velocity'] <= 0.1 and row['peak_velocity'] <= 0.25
    assert rows['zvd']['worst_residual_mm'] < rows['zv']['worst_residual_mm']


def test_a_hoisting_move_with_a_bridge_has_every_axis_in_the_csv(capsys, tmp_path):
    csv_path = tmp_path / 'h.csv'
    status, out, err = run(capsys, 'plan', '--method', 'zv', *TASK, *IDEAL, '--tau-hoist', '0', '--hoist', '0.47',
                           '0.27', '--json', '--csv', str(csv_path))
    assert status == 0, err
    report = json.loads(out)
    assert report['hoist']['shaper_design'] == 'adaptive' and report['bridge']['goal'] == pytest.approx(0.2)
    assert report['residual']['load_mm'] < 0.05  # the adaptive shaper on both travel axes (measured 0.006 mm)
    header, rows = read_csv(csv_path)
    assert header[7:] == ['bridge_position', 'bridge_velocity', 'bridge_acceleration', 'hoist_position',
                          'hoist_velocity', 'hoist_acceleration', 'phi1', 'phi2']
    assert rows[0, 10] == 0.47 and rows[-1, 10] == pytest.approx(0.27, abs=1e-12)


@pytest.mark.parametrize('args, needle', [
    (['plan', '--method', 'zv', '--displacement', '0.3', '--bridge', 'nan', '--duration', '3'], '--bridge'),
    (['plan', '--method', 'zv', '--displacement', '0.3', '--bridge', '--duration', '3'], '--bridge'),
    (['plan', '--method', 'nvf', *TASK, '--solver', 'indirect'], 'does not plan the bridge'),
    (['plan', '--method', 'zv', *TASK, '--max-bridge-velocity', '0.05'], 'exceeds max_bridge_velocity 0.05'),
    (['plan', '--method', 'zv', '--displacement', '0.3', '--bridge', '0.2', '--fastest', '--max-jerk', '1',
      '--max-bridge-jerk', '1'], 'velocity or acceleration limit of a moving axis'),
    (['plan', '--method', 'zv', '--displacement', '0.3', '--bridge', '0.2', '--fastest', '--max-velocity', '1',
      '--hoist', '0.47', '0.27'], 'fastest shaped plan with a hoist'),
    (['choose', '--displacement', '0.3', '--bridge', '0.2'], "needs axis limits: --max-velocity and/or "
                                                             "--max-acceleration (or the bridge's)"),
])
def test_bad_input_with_a_bridge_is_one_line_exit_2(capsys, args, needle):
    status, _, err = run(capsys, *args)
    assert status == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith('crane-plan: error:') and needle in lines[0], err
