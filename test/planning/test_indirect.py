"""The paper's indirect route (Eqs. 16-17, solve_bvp) against the direct solver (collocation + IPOPT).

The two discretize different things (the necessary conditions with adaptive
4th-order collocation, the problem itself with fixed Radau collocation), so
their agreement checks both.
"""
import numpy as np
import pytest

from crane_msgs_py.crane.params import CraneParams
from crane_planner.planning import PlanError, PlanOptions
from crane_planner.planning.direct import DirectSolver
from crane_planner.planning.dispatch import variational_solver
from crane_planner.planning.indirect import IndirectSolver

MODEL = CraneParams()  # Table 1, tau = 0.01 s
D = 0.3


@pytest.fixture(scope='module')
def solvers():
    return {(m, kind): variational_solver(m, PlanOptions(solver=kind))
            for m in ('nvf', 'rvf') for kind in ('direct', 'indirect')}


def peaks(samples):
    return np.array([np.abs(x).max() for x in (samples.velocity, samples.acceleration, samples.jerk)])


@pytest.mark.parametrize('method', ['nvf', 'rvf'])
@pytest.mark.parametrize('duration', [3.0, 2.5])
def test_direct_and_indirect_agree(solvers, method, duration):
    direct = solvers[method, 'direct'].solve(D, duration, MODEL)
    indirect = solvers[method, 'indirect'].solve(D, duration, MODEL)
    assert indirect.info['solver'] == 'indirect' and direct.info['solver'] == 'direct'
    t = np.linspace(0.0, duration, 20001)
    a, b = direct.evaluate(t), indirect.evaluate(t)
    assert np.abs(a.position - b.position).max() < 1e-5
    np.testing.assert_allclose(peaks(a), peaks(b), rtol=2e-3)
    assert direct.info['objective'] == pytest.approx(indirect.info['objective'], rel=1e-4)


def test_ideal_tracking_agrees_and_both_starts_converge_to_it():
    """tau = 0 (jerk as the input); the indirect solver started from the linearized problem
    and from the direct solution (costates from IPOPT's multipliers) reach the same solution."""
    ideal = CraneParams(tau=0.0)
    direct = DirectSolver('rvf', PlanOptions()).solve(D, 3.0, ideal)
    t = np.linspace(0.0, 3.0, 3001)
    starts = {'linearized': None, 'direct': DirectSolver('rvf', PlanOptions())}
    for start, start_solver in starts.items():
        plan = IndirectSolver('rvf', PlanOptions(solver='indirect'), start=start_solver).solve(D, 3.0, ideal)
        assert plan.info['start'] == start
        assert np.abs(plan.evaluate(t).position - direct.evaluate(t).position).max() < 1e-6
        np.testing.assert_allclose(peaks(plan.evaluate(t)), peaks(direct.evaluate(t)), rtol=1e-3)


def test_costates_from_ipopt_multipliers_match_the_tpbvp():
    """lambda(t) of Eq. 17 equals the collocation multipliers over the quadrature weights."""
    ideal = CraneParams(tau=0.0)
    s = IndirectSolver('nvf', PlanOptions(solver='indirect'))
    plan = s.solve(D, 3.0, ideal)
    times, _, lam = DirectSolver('nvf', PlanOptions()).costates(D, 3.0, ideal, s.mesh(3.0, ideal))
    exact = plan.solution.sol(times)[s.problem(False).nx:]
    for est, ref in zip(lam, exact):
        assert np.abs(est - ref)[1:].max() < 1e-3 * np.abs(ref).max()


def test_indirect_refuses_axis_limits():
    with pytest.raises(PlanError, match='indirect'):
        variational_solver('nvf', PlanOptions(solver='indirect', max_velocity=0.2)).solve(D, 3.0, MODEL)
