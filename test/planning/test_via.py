"""Via points (contract "Routes and protected areas"): the reference passes each in order without stopping.

The contract's case on the paper's rig (tau 0): (0, 0) -> (0.6, 0.4) via (0.5, 0.0) in 4 s with a bridge:
NVF's reference passes within 1 mm of the via point, moving (>= 0.02 m/s), and leaves at most 0.1 mm of swing
replayed in crane_sim's independent spatial model; the via's time is where the straight path's quintic
timing reaches its share of the polyline's length.
"""
import numpy as np
import pytest

from crane_msgs_py.crane.params import CraneParams
from crane_planner.planning import PlanOptions
from crane_planner.planning.dispatch import VariationalRequest, variational_solver
from crane_planner.planning.plan import PlanError
from crane_planner.tools.evaluate import simulate_plan

NOMINAL = CraneParams().replace(tau=0.0)
MOVES = {'cart': 0.6, 'bridge': 0.4}
VIA = {'cart': 0.5, 'bridge': 0.0}


def passes(p, via, duration):
    """(smallest distance (m) of the reference to ``via``, when (s), the speed there (m/s)) at 0.1 ms."""
    t = np.linspace(0.0, duration, int(duration / 1e-4) + 1)
    x, y = p.axes['cart'].evaluate(t), p.axes['bridge'].evaluate(t)
    d = np.hypot(x.position - via['cart'], y.position - via['bridge'])
    k = int(np.argmin(d))
    return d[k], t[k], float(np.hypot(x.velocity[k], y.velocity[k]))


@pytest.mark.parametrize('method', ['nvf', 'rvf'])
def test_the_reference_passes_the_via_point_moving_and_leaves_no_swing(method):
    request = VariationalRequest('plan', method, MOVES, 4.0, NOMINAL, PlanOptions(), origin={}, vias=(VIA,))
    p = request.run(variational_solver(method, PlanOptions()))
    distance, when, speed = passes(p, VIA, 4.0)
    assert distance < 1e-3 and speed >= 0.02 and p.info['route'] == 'via'
    # the polyline's first leg is 0.5 of 0.5 + 0.566 m: the quintic reaches that share at 2.13 s
    assert when == pytest.approx(p.info['via_times_s'][0], abs=1e-3) and 1.9 < when < 2.3
    assert simulate_plan(p, NOMINAL, settle=4.0).metrics[0]['residual']['load_mm'] <= 0.1
    end = {name: one.evaluate(np.array([4.0])).position[0] for name, one in p.axes.items()}
    assert end == pytest.approx(MOVES, abs=1e-9)


def test_two_via_points_are_passed_in_order():
    vias = ({'cart': 0.3, 'bridge': -0.1}, {'cart': 0.6, 'bridge': 0.1})
    request = VariationalRequest('plan', 'nvf', MOVES, 5.0, NOMINAL, PlanOptions(), origin={}, vias=vias)
    p = request.run(variational_solver('nvf', PlanOptions()))
    (d1, t1, _), (d2, t2, _) = (passes(p, via, 5.0) for via in vias)
    assert d1 < 1e-3 and d2 < 1e-3 and t1 < t2


def test_too_many_via_points_for_the_mesh_are_refused():
    vias = tuple({'cart': 0.6 * k / 200, 'bridge': 0.0} for k in range(1, 200))
    request = VariationalRequest('plan', 'nvf', MOVES, 4.0, NOMINAL, PlanOptions(), origin={}, vias=vias)
    with pytest.raises(PlanError, match='the via points are too many or too near the goal'):
        request.run(variational_solver('nvf', PlanOptions()))
