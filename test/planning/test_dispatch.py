"""planning.dispatch: one request's checks and route, the same for the CLI, the node and every worker."""
import math

import numpy as np
import pytest

from crane_msgs_py.crane.params import CraneParams, ParameterError
from crane_planner.planning import dispatch
from crane_planner.planning.dispatch import PlanOptions, SolverCache, VariationalRequest
from crane_planner.planning.plan import PlanError

MODEL = CraneParams()


def refuse_to_solve(request):
    raise AssertionError(f'a solver was asked: {request}')


@pytest.mark.parametrize('method, D, T, message', [
    ('xyz', 0.3, 3.0, "unknown method 'xyz'"),
    ('nvf', math.nan, 3.0, 'displacement must be finite'),
    ('rvf', 0.3, math.inf, 'duration must be finite'),
    ('nvf', 0.3, 0.0, 'duration must be > 0'),
    ('rvf', 0.3, -1.0, 'duration must be > 0'),
    ('nvf', 'a', 3.0, 'must be numbers'),
])
def test_a_bad_request_is_refused_before_any_solver_is_asked(method, D, T, message):
    with pytest.raises(PlanError, match=message):
        dispatch.plan(method, D, T, MODEL, variational=refuse_to_solve)


def test_shapers_are_planned_here_and_variational_methods_go_to_the_variational_callable():
    asked = []
    shaped = dispatch.plan('zv', 0.3, 3.0, MODEL, variational=refuse_to_solve)
    assert shaped.method == 'zv' and shaped.evaluate(3.0).position[0] == pytest.approx(0.3, abs=1e-12)
    sentinel = object()
    assert dispatch.plan('rvf', 0.3, 3.0, MODEL, variational=lambda r: asked.append(r) or sentinel) is sentinel
    assert asked == [VariationalRequest('plan', 'rvf', 0.3, 3.0, MODEL, PlanOptions())]
    dispatch.fastest('nvf', 0.3, MODEL, PlanOptions(max_velocity=0.2), variational=asked.append)
    assert asked[-1].operation == 'fastest' and asked[-1].duration is None


def test_a_shaper_plans_the_bridge_here_too_and_checks_every_axis():
    """A shaped move with a bridge is an AxesPlan of both travel axes, planned without a solver; the bridge's
    limits are checked as the cart's are."""
    both = dispatch.plan('zv', 0.3, 3.0, MODEL, variational=refuse_to_solve, bridge=-0.2)
    assert both.joint_names == ('cart', 'bridge') and both.starts == {'cart': 0.0, 'bridge': 0.0}
    assert both.evaluate_axis('bridge', 3.0).position[0] == pytest.approx(-0.2, abs=1e-12)
    fastest = dispatch.fastest('zvd', 0.3, MODEL, PlanOptions(max_bridge_acceleration=0.2),
                               variational=refuse_to_solve, bridge=0.2)
    assert fastest.axes['bridge'].peaks()[1] <= 0.2
    with pytest.raises(PlanError, match='zv plan exceeds max_bridge_jerk 0.1 m/s'):
        dispatch.plan('zv', 0.3, 3.0, MODEL, PlanOptions(max_bridge_jerk=0.1), variational=refuse_to_solve,
                      bridge=0.2)


def test_a_fastest_request_without_a_velocity_or_acceleration_limit_asks_no_solver():
    with pytest.raises(PlanError, match='needs max_velocity or max_acceleration'):
        dispatch.fastest('rvf', 0.3, MODEL, PlanOptions(max_jerk=2.0), variational=refuse_to_solve)
    with pytest.raises(PlanError, match='needs the direct solver'):
        dispatch.fastest('rvf', 0.3, MODEL, PlanOptions(max_velocity=0.2, solver='indirect'),
                         variational=refuse_to_solve)


def test_a_shaped_plan_beyond_an_axis_limit_is_refused_naming_it():
    with pytest.raises(PlanError, match='zv plan exceeds max_velocity 0.1 m/s'):
        dispatch.plan('zv', 0.3, 3.0, MODEL, PlanOptions(max_velocity=0.1), variational=refuse_to_solve)


def test_a_solver_cache_keeps_one_solver_per_key_and_answers_as_a_new_solver_does():
    cache = SolverCache()
    first = dispatch.plan('nvf', 0.3, 3.0, MODEL, variational=cache)
    again = dispatch.plan('nvf', 0.3, 3.0, MODEL, variational=cache)
    fresh = dispatch.plan('nvf', 0.3, 3.0, MODEL)  # the default: a new solver
    assert len(cache._solvers) == 1
    assert again.info['iterations'] < first.info['iterations']  # warm: the kept solver's last solution
    t = np.linspace(0.0, 3.0, 301)
    assert np.max(np.abs(again.evaluate(t).position - fresh.evaluate(t).position)) < 1e-8


@pytest.mark.parametrize('method, options', [('rvf', PlanOptions(robust=('L1',), max_velocity=0.3)),
                                             ('nvf', PlanOptions(intervals=12))])
def test_plans_made_without_a_cache_share_their_nlp_and_are_the_plan_a_newly_built_solver_gives(method, options):
    """``plan`` with no ``variational``: each call's solver starts cold, as one built for it alone does, so
    the plans are exactly that solver's; their NLP (most of a build) is built once per structure."""
    from crane_planner.planning.dispatch import VariationalRequest, variational_solver
    request = VariationalRequest('plan', method, 0.3, 3.0, MODEL, options)
    alone = request.run(variational_solver(method, options))
    first = dispatch.plan(method, 0.3, 3.0, MODEL, options)
    other = dispatch.plan(method, 0.28, 2.9, MODEL, options)  # its solver's warm start would have been first's
    again = dispatch.plan(method, 0.3, 3.0, MODEL, options)
    t = np.linspace(0.0, 3.0, 301)
    for plan in (first, again):
        assert np.array_equal(plan.evaluate(t).position, alone.evaluate(t).position)
        assert plan.info['iterations'] == alone.info['iterations']
    assert other.evaluate(2.9).position[0] == pytest.approx(0.28, abs=1e-9)
    structure = variational_solver(method, options).structure
    [(transcriptions, _)] = [v for k, v in dispatch._SHARED_NLPS.items() if k == structure]
    assert len(transcriptions) == 1  # one model form, one NLP, whatever the calls


@pytest.mark.parametrize('budget', [0.0, -1.0, float('nan')])
def test_max_solve_time_must_be_positive(budget):
    with pytest.raises(ParameterError, match='max_solve_time'):
        PlanOptions(max_solve_time=budget)
