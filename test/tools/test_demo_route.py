"""crane-demo's route case (``route_demo``, offline): NVF and RVF route past the wall and the column and through
the via point, measured on crane_sim's independent model (clearance by its own cable directions); a shaper is
refused each time as the planner refuses it, saying why; the figure is written."""
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


def test_a_shaper_is_refused_on_each_move_saying_why(routes, tmp_path):
    runs, refused = routes
    assert not [r for r in runs if r.method == 'zv']
    assert 'shapers do not route past boxes' in refused[(WALL, 'zv')]
    assert 'keep_out box 1 (x 0.25..0.35, y -0.1..0.1' in refused[(COLUMN, 'zv')]
    assert refused[(VIA, 'zv')].startswith('move.via: point 1 (cart 0.5, bridge 0 m)')
    assert plot_routes(runs, tmp_path / 'route.png').stat().st_size > 10_000
