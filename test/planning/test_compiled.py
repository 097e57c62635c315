"""Compiled per-point derivatives: the same numbers as interpreted, cached once per machine, and a solver
that swaps them in keeps solving; without a working compiler the interpreted ones stay."""
import logging
import time

import casadi as ca
import numpy as np
import pytest

from crane_msgs_py.crane.params import CraneParams
from crane_planner.planning import compiled
from crane_planner.planning.collocation import Transcription
from crane_planner.planning.problem import Form, Problem

needs_compiler = pytest.mark.skipif(compiled.compiler() is None, reason='no C compiler on this machine')


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv('CRANE_PLANNER_CACHE', str(tmp_path))
    monkeypatch.setattr(compiled, '_warned', set())
    return tmp_path


def small_function() -> ca.Function:
    x = ca.SX.sym('x', 3)
    return ca.Function('small_f', [x], [ca.vertcat(ca.sin(x[0]) * x[1], ca.exp(x[2]) / (1 + x[0] ** 2))])


@needs_compiler
def test_a_compiled_function_gives_the_interpreted_numbers_and_is_compiled_once(cache):
    fn = small_function()
    fast = compiled.compile_function(fn)
    assert fast is not None
    [library] = cache.glob('*.so')
    x = np.array([0.3, -1.2, 0.7])
    assert np.allclose(np.array(fast(x)), np.array(fn(x)), rtol=1e-14, atol=0)
    # the second time it comes from the cache: the same library, not written again
    stamp = library.stat().st_mtime_ns
    again = compiled.compile_function(fn)
    assert again is not None and np.allclose(np.array(again(x)), np.array(fn(x)), rtol=1e-14, atol=0)
    assert list(cache.glob('*.so')) == [library] and library.stat().st_mtime_ns == stamp


@needs_compiler
def test_a_library_that_does_not_load_is_compiled_again(cache):
    fn = small_function()
    assert compiled.compile_function(fn) is not None
    [library] = cache.glob('*.so')
    library.write_bytes(b'not a shared library')
    again = compiled.compile_function(fn)
    assert again is not None and np.allclose(np.array(again([0.1, 0.2, 0.3])), np.array(fn([0.1, 0.2, 0.3])))


def test_a_failing_compiler_leaves_the_function_interpreted_and_says_so_once(cache, monkeypatch, caplog):
    monkeypatch.setenv('CC', '/bin/false')
    with caplog.at_level(logging.WARNING, logger=compiled.__name__):
        assert compiled.compile_function(small_function()) is None
        assert compiled.compile_function(small_function()) is None
    assert len([r for r in caplog.records if 'compiling small_f failed' in r.getMessage()]) == 1
    assert list(cache.glob('*.so')) == []


def test_compiling_off_compiles_nothing(monkeypatch):
    monkeypatch.setenv('CRANE_PLANNER_CACHE', 'off')
    assert compiled.compile_function(small_function()) is None


@needs_compiler
@pytest.mark.parametrize('free_time', [False, True], ids=['fixed', 'free-time'])
def test_the_compiled_derivatives_are_the_interpreted_ones(cache, free_time):
    tr = Transcription(Problem(('L1',), Form.of(CraneParams(), False, False)), 6, True, free_time=free_time)
    points = tr._point_functions()
    slow = tr._derivatives_by_point(points)
    fast = tr._derivatives_by_point({k: compiled.compile_function(f) for k, f in points.items()})
    rng = np.random.default_rng(3)
    x, p, lam_g = rng.normal(size=tr.nw), 0.5 + rng.random(tr.nlp['p'].shape[0]), rng.normal(size=tr.ng)
    assert np.allclose(np.array(fast['jac_g'](x, p)[1]), np.array(slow['jac_g'](x, p)[1]), rtol=1e-12, atol=1e-12)
    assert np.allclose(np.array(fast['hess_lag'](x, p, 0.7, lam_g)), np.array(slow['hess_lag'](x, p, 0.7, lam_g)),
                       rtol=1e-12, atol=1e-12)


@needs_compiler
def test_a_solver_takes_the_compiled_derivatives_when_they_are_ready_and_keeps_its_plans(cache):
    from crane_planner.planning.dispatch import PlanOptions, SolverCache, plan
    params, solvers, options = CraneParams(), SolverCache(), PlanOptions(robust=('L1',))
    before = plan('rvf', 0.3, 3.0, params, options, variational=solvers)
    [tr] = [tr for s in solvers._solvers.values() for tr in s._transcriptions.values()]
    assert tr.generation == 0
    # compiled here too (the background compile, at a low priority, then takes them from the cache)
    assert all(compiled.compile_function(f) is not None for f in tr._point_functions().values())
    for _ in range(1200):
        if tr.generation:
            break
        time.sleep(0.1)
    assert tr.generation == 1, 'the compiled derivatives were not swapped in within 120 s'
    after = plan('rvf', 0.3, 3.0, params, options, variational=solvers)
    [inst] = [i for s in solvers._solvers.values() for i in s._instances.values()]
    assert inst.generation == 1  # the IPOPT instance was made again with them
    t = np.linspace(0.0, 3.0, 301)
    assert np.max(np.abs(after.evaluate(t).position - before.evaluate(t).position)) < 1e-8
