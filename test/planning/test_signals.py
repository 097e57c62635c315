"""The swing as a record: its angles by name, and the one conversion to and from the model's order."""
import math

import pytest

from crane_planner.planning.dynamics import crane_ode
from crane_planner.planning.plan import PlanError
from crane_planner.planning.signals import SPATIAL_SWING_STATES, SWING_STATES, Swing, swing_names, swing_rates


def test_the_names_are_the_models_swing_states_in_its_order():
    for spatial in (False, True):
        ode = crane_ode(True, bridge=spatial)
        assert ode.swing_states == swing_names(spatial)
        assert ode.states[-len(swing_names(spatial)):] == swing_names(spatial)
    assert swing_rates(False) == ('dtheta1', 'dtheta2') and swing_rates(True) == SPATIAL_SWING_STATES[4:]


def test_values_in_the_models_order_round_trip():
    planar = Swing(0.01, -0.02, 0.3, -0.4)
    assert planar.values() == (0.01, -0.02, 0.3, -0.4) and not planar.spatial and planar.phi is None
    assert Swing.of(planar.values(), spatial=False) == planar
    assert Swing.of(planar.states(), spatial=False) == planar and tuple(planar.states()) == SWING_STATES
    spatial = Swing.of((0.01, 0.002, -0.02, 0.003, 0.1, 0.2, -0.3, 0.4), spatial=True)
    assert (spatial.phi1, spatial.phi2, spatial.dtheta1, spatial.dphi2) == (-0.02, 0.003, 0.1, 0.4)
    assert spatial.spatial and spatial.phi == (-0.02, 0.003)
    assert Swing.of(spatial.states(), spatial=True) == spatial
    # the planar swing is the spatial one with phi = 0
    assert planar.angles() == (0.01, -0.02, 0.0, 0.0) and planar.rates() == (0.3, -0.4, 0.0, 0.0)
    assert spatial.angles() == (0.01, 0.002, -0.02, 0.003) and spatial.rates() == (0.1, 0.2, -0.3, 0.4)


def test_at_rest():
    assert Swing.rest().values() == (0.0,) * 4 and Swing.rest(spatial=True).values() == (0.0,) * 8
    assert Swing.rest(spatial=True).still and not Swing(dtheta2=1e-6).still


def test_bad_swings_are_refused():
    with pytest.raises(PlanError, match='finite'):
        Swing(theta1=math.nan)
    with pytest.raises(PlanError, match='all of phi1'):
        Swing(phi1=0.1)
    with pytest.raises(PlanError, match='dtheta2'):
        Swing.of((0.0, 0.0), spatial=False)
