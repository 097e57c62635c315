"""A plan's occupancy (runway.prediction) sampled on its grid whatever its length: a plan and settle window whose
end falls on the grid by rounding (1.3 s + 1.0 s = 2.3000000000000003 s: 115 steps of 0.02 s) keeps its times
increasing, as an occupancy needs."""
import numpy as np
import pytest

from crane_msgs_py.crane.params import CraneParams
from crane_planner.planning.dispatch import plan
from crane_planner.runway.occupancy import OCCUPANCY_STEP, Shape
from crane_planner.runway.prediction import plan_occupancy


def test_an_occupancy_ending_on_its_grid_by_rounding_keeps_its_times_increasing():
    p = plan('nvf', 0.0, 1.3, CraneParams(), bridge=0.5)  # (its solved path ends at 1.3 + 1.0, rounded up)
    occupancy = plan_occupancy('a', p, CraneParams(), {'cart': 0.0, 'bridge': 0.0}, (0.0, 0.0), 0, 0, Shape(), 1.0)
    steps = np.diff(occupancy.t)
    assert occupancy.t[-1] == pytest.approx(2.3) and np.all(steps > 1e-6) and steps.max() <= OCCUPANCY_STEP + 1e-12
