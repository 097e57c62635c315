"""crane-demo's spatial case, run offline by its own function (no nodes): the cart and the bridge together.

One run of the case for the module (planning NVF and RVF on the spatial
model takes most of its ~25 s); the unshaped quintic, the shapers'
yardstick, is simulated here the same way.
"""
import pytest

from crane_msgs_py.crane.params import CraneParams
from crane_planner.planning.hoisting import quintic_axes_plan
from crane_planner.tools.evaluate import residual_load_mm, simulate_plans
from crane_planner.tools.spatial_demo import (
    COLUMNS,
    DIAGONAL,
    MOVE,
    NOMINAL,
    PER_PLANE,
    PERTURBED,
    SETTLE,
    diagonal_methods,
    plot_spatial,
    run_spatial,
)

METHODS = ('nvf', 'rvf', 'zv', 'nzv', 'zvd')  # the demo's


@pytest.fixture(scope='module')
def residuals():
    """{(column, method): residual mm} of one run of the spatial case, and its runs."""
    runs = run_spatial(METHODS, log=print)
    return {(r.column, r.method): r.residual_mm for r in runs}, runs


@pytest.fixture(scope='module')
def unshaped_mm():
    """The unshaped quintic of the 0.3 x 0.2 m move on the model's plant: about 11.6 mm."""
    DX, DY, T = MOVE
    return float(residual_load_mm(simulate_plans([quintic_axes_plan({'cart': DX, 'bridge': DY}, T)],
                                                 CraneParams(), SETTLE)[0])[0])


def test_every_column_and_method_has_a_row(residuals):
    mm, runs = residuals
    assert set(mm) == ({(c, m) for c in (NOMINAL, PERTURBED) for m in METHODS}
                       | {(DIAGONAL, m) for m in ('nvf', 'zv', PER_PLANE)})
    assert {r.column for r in runs} == set(COLUMNS)
    assert all(0.0 < r.peak_acceleration < 5.0 and r.plan_time_s >= 0.0 for r in runs)


def test_nvf_and_rvf_leave_no_swing_on_the_model_plant(residuals):
    mm, _ = residuals
    assert mm[NOMINAL, 'nvf'] <= 0.1 and mm[NOMINAL, 'rvf'] <= 0.1, mm


@pytest.mark.parametrize('method', ['zv', 'zvd'])
def test_zv_and_zvd_leave_a_twentieth_of_the_unshaped_quintic(residuals, unshaped_mm, method):
    mm, _ = residuals
    assert unshaped_mm > 5.0  # the move swings when unshaped: the comparison means something
    assert mm[NOMINAL, method] <= unshaped_mm / 20.0, (mm[NOMINAL, method], unshaped_mm)


def test_the_coupled_model_buys_the_diagonal(residuals):
    """1.0 x 0.8 m in 2.2 s: NVF on the spatial model leaves ~0.001 mm, two planar NVF plans ~3.9 mm."""
    mm, _ = residuals
    assert mm[DIAGONAL, 'nvf'] <= 0.1, mm
    assert mm[DIAGONAL, PER_PLANE] > 1.0, mm


def test_rvf_is_robust_to_a_shorter_upper_cable(residuals):
    """L1 -10 %, the planner's model nominal: RVF ~0.63 mm, NVF ~6.3 mm."""
    mm, _ = residuals
    assert mm[PERTURBED, 'rvf'] < mm[PERTURBED, 'nvf'], mm


def test_the_figure_is_written(residuals, tmp_path):
    _, runs = residuals
    path = plot_spatial(runs, tmp_path / 'demo_spatial.png')
    assert path.exists() and path.stat().st_size > 10_000


def test_the_diagonal_honours_the_methods_asked():
    assert diagonal_methods(METHODS) == ['nvf', 'zv', PER_PLANE]
    assert diagonal_methods(('zv', 'zvd')) == ['zv']
    assert diagonal_methods(('rvf', 'nvf', 'ei'), every=True) == ['rvf', 'nvf', 'ei', PER_PLANE]
