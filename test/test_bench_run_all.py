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
