"""crane-demo's route case (``route_demo``, offline): NVF and RVF route past the wall and the column and through
the via point, measured on crane_sim's independent model (clearance by its own cable directions); ZV routes its
straight move with a shaped detour and is refused the via point as the planner refuses it; the figure is
written."""
import math

import pytest

from crane_planner.tools.route_demo import COLUMN, VIA, WALL, plot_routes, run_routes


@pytest.fixture(scope='module')
def routes():
    return run_routes(['nvf', 'rvf', 'zv'])


def test_nvf_and_rvf_route_every_move_keeping_the_margin_and_leaving_no_swing(routes):
    runs, _ = routes
    by = {(r.column, r.method): r for r in runs}
    for method in ('nvf', 'rvf'):
        assert by[(WALL, method)].route == 'over' and by[(COLUMN, method)].route == 'around'
        assert by[(VIA, method)].route == 'via' and math.isinf(by[(VIA, method)].clearance_mm)
        for column in (WALL, COLUMN):
            assert 20.0 <= by[(column, method)].clearance_mm < 40.0
        for column in (WALL, COLUMN, VIA):
            assert by[(column, method)].residual_mm <= 0.1


def test_zv_routes_past_the_wall_and_the_column_and_is_refused_the_via_point_saying_why(routes, tmp_path):
    """ZV goes its straight way with the hoist (wall) or the bridge (column) stepping aside and back, both legs
    shaped: the margin kept in crane_sim; the via point is off its straight path: refused as the planner
    refuses it."""
    runs, refused = routes
    by = {(r.column, r.method): r for r in runs}
    assert by[(WALL, 'zv')].route == 'over' and by[(COLUMN, 'zv')].route == 'around'
    for column in (WALL, COLUMN):
        assert by[(column, 'zv')].clearance_mm >= 20.0
    assert by[(COLUMN, 'zv')].residual_mm < 1.0  # the rope as designed for; over the wall it is shorter
    assert set(refused) == {(VIA, 'zv')}
    assert refused[(VIA, 'zv')].startswith('move.via: point 1 (cart 0.5, bridge 0 m)')
    assert plot_routes(runs, tmp_path / 'route.png').stat().st_size > 10_000
