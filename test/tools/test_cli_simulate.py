"""``crane-plan simulate``: a plan run open and closed loop on the plant, with the sim's sensor and disturbances.
The residuals against ``tools.closed_loop`` run directly, and the bad input refused in one line (exit 2)."""
import csv
import json

import pytest
from crane_plan_cli import crane_plan as run

PERTURBED = ['--method', 'zv', '--displacement', '0.3', '--duration', '2.5', '--plant-L1', '0.42', '--settle', '2']


def test_the_perturbed_crane_open_and_closed_loop_side_by_side(tmp_path):
    out = run('simulate', *PERTURBED, '--feedback', '--json', '--csv', tmp_path / 'run.csv',
              '--plot', tmp_path / 'run.png')
    assert out.returncode == 0, out.stderr
    report = json.loads(out.stdout)
    runs = report['runs']
    assert runs['open']['residual_settled_mm'] > 8.0 and runs['open']['peak_correction_mm'] == 0.0
    assert runs['closed']['residual_settled_mm'] < 0.5 and 0.5 < runs['closed']['peak_correction_mm'] < 20.0
    rows = list(csv.reader(open(tmp_path / 'run.csv')))
    assert rows[0] == ['time', 'open_reference', 'open_correction', 'open_swing', 'closed_reference',
                       'closed_correction', 'closed_swing']
    assert len(rows) - 1 == round((2.5 + 2 * 2.0) / 1e-3)
    assert (tmp_path / 'run.png').stat().st_size > 10_000


def test_a_push_with_a_late_noisy_camera_is_damped_and_the_table_says_so():
    out = run('simulate', '--method', 'nvf', '--displacement', '0.3', '--duration', '3', '--settle', '3',
              '--feedback', '--push', '1.2:0.03', '--latency', '0.05', '--noise', '0.0005', '--dropout', '0.1')
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    open_row = next(line for line in lines if line.startswith('open')).split()
    closed_row = next(line for line in lines if line.startswith('closed')).split()
    assert float(open_row[2]) > 10.0 and float(closed_row[2]) < 2.0


@pytest.mark.parametrize('args, needle', [
    (['--push', '1.2'], 'argument --push'),
    (['--push', 'a:b'], 'argument --push'),
    (['--dropout', '1.5'], 'argument --dropout'),
    (['--latency', '-1'], 'argument --latency'),
    (['--wind', 'x'], 'argument --wind'),
    (['--hoist', '0.47', '0.4'], 'argument --hoist'),
])
def test_bad_input_is_one_line_exit_2(args, needle):
    out = run('simulate', *PERTURBED, *args)
    assert out.returncode == 2 and needle in out.stderr and len(out.stderr.strip().splitlines()) == 1, out.stderr
