"""bench/run_all.py reads every benchmark's JSON: on one line, indented, or after lines it logged."""
import importlib.util
from pathlib import Path

_spec = importlib.util.spec_from_file_location('run_all', Path(__file__).parents[1] / 'bench' / 'run_all.py')
run_all = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(run_all)


def test_indented_json_is_read_whole():
    assert run_all.read_result('{\n  "median_ms": 1.5,\n  "cases": [\n    1\n  ]\n}\n') == {'median_ms': 1.5,
                                                                                        'cases': [1]}


def test_one_line_json_after_logged_lines_is_read_from_the_last_line():
    assert run_all.read_result('building...\n{"a": 1}\n') == {'a': 1}


def test_no_json_object_is_none():
    assert run_all.read_result('') is None
    assert run_all.read_result('Traceback ...\n') is None
    assert run_all.read_result('[1, 2]\n') is None


def test_the_runway_guard_bench_runs_and_prints_its_figures():
    """A quick benchmark run whole (the guard's signature once changed under it unnoticed): its JSON, every run's
    figures; no bound on the times (the host's), only that they are times."""
    import subprocess
    import sys
    bench = Path(__file__).parents[1] / 'bench' / 'runway_guard.py'
    done = subprocess.run([sys.executable, str(bench)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-1000:]
    result = run_all.read_result(done.stdout)
    assert {'operator_1', 'operator_3', 'trajectory_1', 'trajectory_3'} <= set(result)
    assert all(result[k]['watch']['median_us'] > 0 and result[k]['ticks'] == 10000 for k in ('operator_1',
                                                                                            'trajectory_3'))
    assert 'stop' in result['operator_1']['levels_seen']  # the operator driven into the other crane: stopped
