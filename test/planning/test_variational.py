"""planning.variational: what the two NVF/RVF routes share (solver keys, request checks)."""
import pytest

from crane_msgs_py.crane.params import CraneParams
from crane_planner.planning import PlanError, PlanOptions
from crane_planner.planning.direct import DirectSolver
from crane_planner.planning.variational import VariationalSolver


def test_key_separates_structures_and_limit_values():
    k = VariationalSolver.key
    assert k('nvf', PlanOptions()) == k('nvf', PlanOptions(robust=('L2',)))  # robust set unused by NVF
    assert k('rvf', PlanOptions()) != k('rvf', PlanOptions(robust=('L2',)))
    assert k('nvf', PlanOptions(max_velocity=0.2)) != k('nvf', PlanOptions(max_velocity=0.3))
    assert k('nvf', PlanOptions()) != k('nvf', PlanOptions(solver='indirect'))
    hash(k('rvf', PlanOptions(robust=('L1', 'tau'), intervals=40)))


def test_a_request_the_limits_cannot_allow_is_refused_before_solving():
    solver = DirectSolver('nvf', PlanOptions(max_velocity=0.09))
    with pytest.raises(PlanError, match='max_velocity 0.09 m/s is too low'):
        solver.solve(0.3, 3.0, CraneParams())
    assert solver._transcriptions == {}  # nothing was built
