"""crane-plan: errors, JSON shape, files written; in this process through ``cli.main`` (``crane_plan_cli``),
and as the installed console script where the executable itself is what is checked."""
import argparse
import json
import subprocess
import sys
from pathlib import Path

import pytest
from crane_plan_cli import crane_plan as run
from identification.recordings import TABLE1, record, run_identify, write_csv

CRANE_PLAN = str(Path(sys.executable).parent / 'crane-plan')


def run_executable(*args, timeout=120):
    return subprocess.run([CRANE_PLAN, *args], capture_output=True, text=True, timeout=timeout)


TASK = ['--displacement', '0.3', '--duration', '3']


@pytest.mark.parametrize('args, needle', [
    (['plan', '--method', 'zv', '--displacement', '0.3', '--duration', '0'], 'duration must be > 0'),
    (['plan', '--method', 'zv', '--displacement', '0.3', '--duration', '-1'], 'duration must be > 0'),
    (['plan', '--method', 'zv', '--displacement', 'nan', '--duration', '3'], '--displacement'),
    (['plan', '--method', 'zv', '--displacement', '0.3', '--duration', 'inf'], '--duration'),
    (['plan', '--method', 'zv', *TASK, '--L1', 'nan'], '--L1'),
    (['plan', '--method', 'zv', *TASK, '--omega', '3.6', 'inf'], '--omega'),
    (['plan', '--method', 'zv', *TASK, '--L1', '0'], 'L1 must be > 0'),
    (['plan', '--method', 'zv', *TASK, '--L2', '-0.3'], 'L2 must be > 0'),
    (['plan', '--method', 'zv', *TASK, '--m1', '0'], 'm1 must be > 0'),
    (['plan', '--method', 'zv', *TASK, '--m2', '-1'], 'm2 must be > 0'),
    (['plan', '--method', 'zv', *TASK, '--tau', '-0.01'], 'tau must be >= 0'),
    (['plan', '--method', 'zv', *TASK, '--plant-L1', '-0.4'], 'L1 must be > 0'),
    (['plan', '--method', 'warp', *TASK], 'warp'),
    (['compare', *TASK, '--methods', 'zv,warp'], 'warp'),
    (['sweep', *TASK, '--methods', 'zv', '--points', '1'], 'at least 2 points'),
    (['plan', '--method', 'zvd', '--displacement', '0.3', '--duration', '2'], 'zvd'),
    (['plan', '--method', 'zv', *TASK, '--settle', '-1'], '--settle'),
    (['plan', '--method', 'zv', *TASK, '--max-velocity', '0.1'], 'exceeds max_velocity 0.1'),
    (['plan', '--method', 'nzv', *TASK, '--max-acceleration', '0.2'], 'exceeds max_acceleration 0.2'),
    (['plan', '--method', 'zv', *TASK, '--hoist', '0.47', '-0.1'], 'rope length must stay > 0'),
    (['plan', '--method', 'zv', *TASK, '--hoist', '0', '0.3'], 'L1_START must be > 0'),
    (['plan', '--method', 'zv', *TASK, '--hoist', '0.47'], '--hoist'),
    (['plan', '--method', 'zv', *TASK, '--hoist', '0.47', '0.27', '--max-hoist-velocity', '0.05'],
     'max_hoist_velocity 0.05'),
    (['plan', '--method', 'zv', *TASK, '--hoist', '0.47', '0.27', '--omega', '3', '9'], 'omega'),
    (['plan', '--method', 'zv', *TASK, '--hoist', '0.47', '0.27', '--hoist-shaper', 'late'], '--hoist-shaper'),
    (['plan', '--method', 'zv', '--displacement', '0.3', '--fastest', '--max-velocity', '1', '--hoist', '0.47',
      '0.27'], 'fastest shaped plan with a hoist'),
])
def test_bad_input_is_one_line_exit_2(args, needle):
    r = run(*args)
    stderr = r.stderr
    assert r.returncode == 2, stderr
    lines = stderr.strip().splitlines()
    assert len(lines) == 1, stderr
    assert 'Traceback' not in stderr
    assert needle in lines[0]
    assert lines[0].startswith('crane-plan: error:')


def test_the_executable_refuses_bad_input_in_one_line_with_exit_2():
    r = run_executable('plan', '--method', 'zv', '--displacement', '0.3', '--duration', '-1')
    assert r.returncode == 2 and 'Traceback' not in r.stderr, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and r.stderr.startswith('crane-plan: error:'), r.stderr


def test_help_exits_0():
    r = run_executable('plan', '--help')
    assert r.returncode == 0
    assert '--plant-L1' in r.stdout and '--omega' in r.stdout


def test_plan_json_csv_plot(tmp_path):
    csv_path, png_path = tmp_path / 'zv.csv', tmp_path / 'zv.png'
    r = run_executable('plan', '--method', 'zv', *TASK, '--tau', '0', '--json', '--csv', str(csv_path),
            '--plot', str(png_path))
    assert r.returncode == 0, r.stderr
    report = json.loads(r.stdout)
    assert report['method'] == 'zv' and report['displacement'] == 0.3 and report['duration'] == 3.0
    assert set(report['peak']) == {'velocity', 'acceleration', 'jerk', 'theta1', 'theta2'}
    assert set(report['rms']) == {'velocity', 'acceleration', 'theta1', 'theta2'}
    assert set(report['residual']) == {'theta1', 'theta2', 'load_mm'}
    # A rest-to-rest motion of D in T needs a mean speed D/T, so the peak is above it.
    assert report['peak']['velocity'] > 0.3 / 3
    assert report['residual']['load_mm'] < 0.5
    header = csv_path.read_text().splitlines()[0]
    assert header == 'time,position,velocity,acceleration,jerk,theta1,theta2'
    assert png_path.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'


def test_every_option_is_spelled_with_dashes_and_the_former_tau_hoist_still_works():
    """--tau-hoist as every other option (--plant-tau, --max-hoist-velocity); --tau_hoist, the former
    spelling, gives the same plan, says it is deprecated and is not shown by --help."""
    from crane_planner.tools.cli import build_parser
    parser = build_parser()
    options = [o for action in _actions(parser) if action.help != argparse.SUPPRESS for o in action.option_strings]
    assert options and not [o for o in options if '_' in o]
    assert '--tau-hoist' in options
    args = ('plan', '--method', 'zv', *TASK, '--hoist', '0.47', '0.27', '--json')
    new, old = run(*args, '--tau-hoist', '0.05'), run(*args, '--tau_hoist', '0.05')
    assert new.returncode == old.returncode == 0, old.stderr
    def residual(r):  # (the report's plan_time_s differs between runs)
        return json.loads(r.stdout)['residual']
    assert residual(old) == residual(new) != residual(run(*args))  # the plant follows tau_hoist
    assert '--tau_hoist is deprecated, use --tau-hoist' in old.stderr and 'deprecated' not in new.stderr
    assert '--tau_hoist' not in run('plan', '--help').stdout


def _actions(parser):
    """Every action of ``parser`` and of its subcommands' parsers."""
    for action in parser._actions:
        yield action
        for sub in getattr(action, 'choices', None) or {}:
            if isinstance(action.choices, dict):
                yield from _actions(action.choices[sub])


def test_plan_with_a_hoist_writes_the_hoists_columns_and_figures(tmp_path):
    """--hoist 0.47 0.27: the CSV's hoist columns go from 0.47 to 0.27 m at rest at both ends, the JSON
    names the hoist's peaks, and the adaptive ZV leaves no swing on its own plant (tau 0)."""
    csv_path = tmp_path / 'h.csv'
    r = run('plan', '--method', 'zv', *TASK, '--hoist', '0.47', '0.27', '--tau', '0', '--tau-hoist', '0',
            '--json', '--csv', str(csv_path))
    assert r.returncode == 0, r.stderr
    report = json.loads(r.stdout)
    assert report['hoist']['start'] == 0.47 and report['hoist']['goal'] == pytest.approx(0.27)
    assert report['hoist']['shaper_design'] == 'adaptive'
    # the hoist's quintic: peak velocity 15/8 |D|/T
    assert report['hoist']['peak']['velocity'] == pytest.approx(15 / 8 * 0.2 / 3.0, rel=1e-6)
    assert report['residual']['load_mm'] < 0.05
    lines = csv_path.read_text().splitlines()
    assert lines[0] == ('time,position,velocity,acceleration,jerk,theta1,theta2,hoist_position,hoist_velocity,'
                        'hoist_acceleration')
    rows = [[float(x) for x in line.split(',')] for line in lines[1:]]
    first, end = rows[0], next(row for row in rows if row[0] >= 3.0)
    assert first[7] == 0.47 and end[7] == pytest.approx(0.27, abs=1e-12)
    assert first[8] == end[8] == 0.0


def test_compare_and_sweep_json(tmp_path):
    r = run('compare', *TASK, '--methods', 'zv,nzv', '--json')
    assert r.returncode == 0, r.stderr
    assert [o['method'] for o in json.loads(r.stdout)] == ['zv', 'nzv']
    r = run('sweep', '--param', 'L1', '--span', '0.3', '--points', '5', *TASK, '--methods', 'zv,zvd',
            '--json', '--plot', str(tmp_path / 's.png'))
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out['param'] == 'L1' and len(out['values']) == 5
    assert out['values'][2] == pytest.approx(0.47)
    zv, zvd = out['methods']['zv']['load_mm'], out['methods']['zvd']['load_mm']
    # ZVD is the robust shaper: at +-30 % of L1 it must leave less swing than ZV.
    assert zvd[0] < zv[0] and zvd[-1] < zv[-1]


def test_progress_goes_to_stderr_as_plain_lines_and_json_stays_clean():
    """Not a terminal: one line per step on stderr; stdout holds the JSON alone (the executable's own
    streams: what IPOPT or CasADi might write natively would show here)."""
    r = run_executable('sweep', '--param', 'L1', '--points', '3', '--displacement', '0.3', '--duration', '3',
            '--methods', 'zv,nvf', '--json')
    assert r.returncode == 0, r.stderr
    json.loads(r.stdout)
    lines = r.stderr.strip().splitlines()
    assert lines == ['crane-plan: sweep 1/3 planned zv', 'crane-plan: sweep 2/3 planned nvf',
                     'crane-plan: sweep 3/3 simulated 2 x 3 runs']


def test_progress_on_a_terminal_is_a_bar_not_lines():
    """A stream that is a terminal gets tqdm's bar (carriage returns, a percentage), not one line per step."""
    import io

    from crane_planner.tools.progress import Progress

    class Terminal(io.StringIO):
        def isatty(self):
            return True
    term, log = Terminal(), io.StringIO()
    for stream in (term, log):
        with Progress(4, 'sweep', 'crane-plan', stream) as progress:
            for k in range(4):
                progress.step(f'step {k}')
    assert '\r' in term.getvalue() and '%' in term.getvalue() and 'crane-plan: sweep' not in term.getvalue()
    assert log.getvalue().splitlines() == [f'crane-plan: sweep {k + 1}/4 step {k}' for k in range(4)]


def test_cli_prints_json_writes_a_params_file_and_a_plot(tmp_path):
    truth = TABLE1.replace(L1=0.55, L2=0.3, tau=0.02, c1=0.003)
    write_csv(tmp_path / 'move.csv', record(truth, reference=True))
    out = run_identify('--csv', str(tmp_path / 'move.csv'), '--json', '--params-out', str(tmp_path / 'crane.yaml'),
              '--plot', str(tmp_path / 'fit.png'))
    assert out.returncode == 0, out.stderr
    data = json.loads(out.stdout)
    for key in ('L1', 'L2', 'mass_ratio', 'c1', 'c2', 'tau', 'omega1', 'omega2', 'zeta1', 'zeta2'):
        assert isinstance(data[key], float) and isinstance(data[f'{key}_std'], float) and data[f'{key}_std'] >= 0
    assert data['L1'] == pytest.approx(0.55, rel=0.01) and data['tau'] == pytest.approx(0.02, rel=0.02)
    assert 0 < data['rms_residual_rad'] < 2e-3
    text = (tmp_path / 'crane.yaml').read_text()
    assert 'ros__parameters:' in text and f'L1: {data["L1"]!r}' in text and 'tau:' in text
    assert (tmp_path / 'fit.png').stat().st_size > 10_000
    human = run_identify('--csv', str(tmp_path / 'move.csv'))
    assert human.returncode == 0 and 'mode 1: omega' in human.stdout and 'L1 (m)' in human.stdout


@pytest.mark.parametrize('content, needle', [
    ('t,cart,theta1\n0,0,0\n', 'lacks column(s) theta2'),
    ('t,cart,theta1,theta2\n' + ''.join(f'{k * 0.02},0,0,0\n' for k in range(30)) + '0.3,0,x,0\n', 'not a number'),
    ('t,cart,theta1,theta2\n' + ''.join(f'{k * 0.02},0,0,{k}\n' for k in range(30)) + '0.1,0,0,0\n',
     't must increase strictly'),
    ('t,cart,theta1,theta2\n' + ''.join(f'{k * 0.02},0,nan,0\n' for k in range(30)), 'theta1 is not finite'),
    ('', 'is empty'),
])
def test_cli_refuses_bad_recordings_in_one_line(tmp_path, content, needle):
    path = tmp_path / 'bad.csv'
    path.write_text(content)
    out = run_identify('--csv', str(path))
    assert out.returncode == 2 and needle in out.stderr and len(out.stderr.strip().splitlines()) == 1, out.stderr
    assert 'Traceback' not in out.stderr


def test_cli_refuses_a_too_short_recording_and_a_missing_file(tmp_path):
    write_csv(tmp_path / 'short.csv', record(TABLE1, after=1.0))
    out = run_identify('--csv', str(tmp_path / 'short.csv'))
    assert out.returncode == 2 and 'less than one period of the slow mode' in out.stderr
    out = run_identify('--csv', str(tmp_path / 'missing.csv'))
    assert out.returncode == 2 and 'cannot read' in out.stderr and 'Traceback' not in out.stderr


def test_cli_fastest_prints_the_duration_and_refuses_without_limits():
    out = run('plan', '--method', 'zv', '--displacement', '0.3', '--fastest', '--max-velocity', '0.25',
              '--max-acceleration', '0.5', '--json')
    assert out.returncode == 0, out.stderr
    data = json.loads(out.stdout)
    assert data['duration'] == pytest.approx(2.1427, abs=1e-3) and data['peak']['acceleration'] <= 0.5
    out = run('plan', '--method', 'zv', '--displacement', '0.3', '--fastest')
    assert out.returncode == 2 and 'needs max_velocity or max_acceleration' in out.stderr
