"""Concurrent NVF/RVF solving: spawned solvers, the time budget and the planner's pools (real CasADi/IPOPT)."""
import threading
import time

import numpy as np
import pytest

from crane_msgs_py.crane.params import CraneParams, ParameterError
from crane_planner.planning import PlanError, PlanOptions
from crane_planner.planning.direct import DirectSolver
from crane_planner.planning.dispatch import VariationalRequest
from crane_planner.planning.indirect import IndirectSolver
from crane_planner.planning.variational import VariationalSolver
from crane_planner.serving import Planner
from crane_planner.serving.planner import SPARE_LIMITS, toggled_limits

MODEL = CraneParams()
REQUESTS = [(0.3, 3.0), (-0.6, 4.4), (1.0, 2.6), (0.2, 8.0)]
#: No plan exists that a solver finds in a second: 10 m in half a second.
HOPELESS = (10.0, 0.5)


def test_spawned_solvers_share_the_nlp_and_solve_side_by_side_exactly_as_alone():
    seed = DirectSolver('rvf', PlanOptions())
    seed.solve(0.3, 3.0, MODEL)
    built = seed.transcription(True).build_time
    solvers = [seed.spawn() for _ in REQUESTS]
    assert all(s.transcription(True) is seed.transcription(True) for s in solvers)
    alone = [seed.spawn().solve(D, T, MODEL) for D, T in REQUESTS]  # cold starts, one at a time
    together = [None] * len(REQUESTS)

    def solve(k):
        together[k] = solvers[k].solve(*REQUESTS[k], MODEL)

    threads = [threading.Thread(target=solve, args=(k,)) for k in range(len(REQUESTS))]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    for a, b in zip(alone, together):
        assert np.array_equal(a.coef, b.coef) and np.array_equal(a.start, b.start)
    assert seed.transcription(True).build_time == built  # the NLP and its derivatives were built once


def test_a_spawn_with_other_limits_or_budget_shares_but_another_structure_does_not():
    seed = DirectSolver('nvf', PlanOptions(max_velocity=0.2))
    seed.solve(0.3, 3.0, MODEL)
    same = seed.spawn(PlanOptions(max_velocity=0.3, max_solve_time=2.0))
    other = seed.spawn(PlanOptions(intervals=20))
    assert same.transcription(True) is seed.transcription(True)
    assert same.limits.max_velocity == 0.3 and same.max_solve_time == 2.0
    assert other.transcription(True) is not seed.transcription(True)


def test_a_request_beyond_max_solve_time_is_refused_naming_the_budget():
    solver = DirectSolver('rvf', PlanOptions(max_solve_time=0.3))
    solver.solve(0.3, 3.0, MODEL)
    t0 = time.perf_counter()
    # IPOPT's own wall-time limit stopped it (the message says so only for Maximum_WallTime_Exceeded),
    # having run to the budget
    with pytest.raises(PlanError, match=r'rvf: no plan for D=10 m, T=0.5 s within max_solve_time 0.3 s '
                                        r'\(IPOPT stopped after \d+ iterations\)'):
        solver.solve(*HOPELESS, MODEL)
    assert time.perf_counter() - t0 >= 0.3
    assert solver.solve(0.3, 3.0, MODEL).info['status'] == 'Solve_Succeeded'  # and it still serves


def test_the_planner_serves_requests_for_the_same_method_while_a_hopeless_one_runs():
    planner = Planner(pool_size=3)
    options = PlanOptions(max_solve_time=4.0)  # long beside the typical ones' seconds on a loaded host
    planner.plan('rvf', 0.3, 3.0, MODEL, options)  # the first instance built
    errors = []
    hopeless = threading.Thread(
        target=lambda: errors.append(pytest.raises(PlanError, planner.plan, 'rvf', *HOPELESS, MODEL, options)))
    hopeless.start()
    time.sleep(0.05)
    plans = [planner.plan('rvf', D, T, MODEL, options) for D, T in REQUESTS]
    assert hopeless.is_alive(), 'the typical requests waited for the hopeless one'
    hopeless.join()
    assert 'max_solve_time 4 s' in str(errors[0].value)
    assert all(p.evaluate(p.duration).position[0] == pytest.approx(D, abs=1e-9)
               for p, (D, _) in zip(plans, REQUESTS))


def test_the_indirect_route_refuses_a_time_budget_it_cannot_keep():
    with pytest.raises(PlanError, match='cannot bound its solve time'):
        IndirectSolver('nvf', PlanOptions(solver='indirect', max_solve_time=1.0)).solve(0.3, 3.0, MODEL)


def test_pool_size_must_be_a_positive_integer():
    with pytest.raises(ParameterError, match='solver_pool_size'):
        Planner(pool_size=0)


def test_the_twins_of_a_configuration_toggle_its_limits_and_so_its_nlp_structure():
    """Without limits: a plan and a fastest plan with SPARE_LIMITS; with some: the plan without any.
    Plans from a state, stops and hoisting moves get no twin."""
    free = PlanOptions(max_solve_time=1.0)
    plain = VariationalRequest('plan', 'rvf', 0.3, 3.0, MODEL, free)
    from_state = VariationalRequest('plan', 'nvf', 0.3, 3.0, MODEL, free, {'theta1': 0.01}, True)
    hoisting = VariationalRequest('plan', 'nvf', (0.3, -0.05), 3.0, MODEL, free)
    twins = toggled_limits([plain, from_state, hoisting])
    assert [t.operation for t in twins] == ['plan', 'fastest'] and twins[1].duration is None
    for twin in twins:
        assert (twin.options.max_velocity, twin.options.max_acceleration) == tuple(SPARE_LIMITS.values())
        assert twin.options.max_solve_time == 1.0 and twin.method == 'rvf'
        assert VariationalSolver.structure_of('rvf', twin.options) != VariationalSolver.structure_of('rvf', free)
    limited = PlanOptions(max_velocity=0.2, max_hoist_velocity=0.1, base='limits')
    (cleared,) = toggled_limits([VariationalRequest('plan', 'nvf', 0.3, 3.0, MODEL, limited)])
    assert not any(limits.any for limits in cleared.options.limits) and cleared.options.base == 'quintic'


def test_the_pool_size_changes_the_pools_made_already_and_those_to_come():
    planner = Planner(pool_size=2)
    planner.plan('nvf', 0.3, 3.0, MODEL)
    planner.pool_size = 3
    assert planner.pool_size == 3 and [p.size for p in planner.threads.pools.values()] == [3]
    with pytest.raises(ParameterError, match='solver_pool_size'):
        planner.pool_size = 0
