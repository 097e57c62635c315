"""A straight move of the spatial crane solved on its vertical plane (``planning.straight``).

References: the planar crane's mass positions (Fig. 1: x1 = x - L1 sin theta1, z1 = -L1 cos theta1) turned
about z, finite differences, the coupled NLP solved on the same request (``straight_moves_in_their_plane``
off), and crane_sim's independent spatial model replaying the plan.
"""
import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from crane_msgs_py.crane.params import CraneParams
from crane_planner.planning.continuation import first_period, problem_start
from crane_planner.planning.dispatch import PlanOptions, SolverCache, VariationalRequest, plan
from crane_planner.planning.dynamics import mass_positions
from crane_planner.planning.mass_path import solved_mass_path
from crane_planner.planning.problem import Weights
from crane_planner.planning.straight import Line, planar_start, spatial_angles
from crane_sim.simulator import SpatialSwing
from planning.test_spatial_continuation import HANDOVER, NOMINAL, Replay, T, assert_at_rest, handover
from planning.test_spatial_nvf import residual_mm

P = CraneParams()
IN_PLANE, COUPLED = SolverCache(), SolverCache(straight_moves_in_their_plane=False)


@settings(max_examples=200, deadline=None)
@given(st.floats(-1.2, 1.2), st.floats(-1.2, 1.2), st.floats(-np.pi, np.pi))
def test_the_angles_put_both_masses_where_the_planar_swing_turned_about_z_has_them(psi1, psi2, alpha):
    line = Line(1.0, np.cos(alpha), np.sin(alpha))
    a = spatial_angles(psi1, psi2, 0.0, 0.0, line)
    L1, L2 = 0.47, 0.39
    p1, p2 = (np.array(p).ravel() for p in mass_positions()(0.0, 0.0, L1, L2, a['theta1'], a['theta2'],
                                                            a['phi1'], a['phi2']))
    # the planar crane in its plane: offsets along the line, then turned
    r1, z1 = -L1 * np.sin(psi1), -L1 * np.cos(psi1)
    r2, z2 = r1 - L2 * np.sin(psi1 + psi2), z1 - L2 * np.cos(psi1 + psi2)
    assert p1 == pytest.approx([r1 * line.cos, r1 * line.sin, z1], abs=1e-12)
    assert p2 == pytest.approx([r2 * line.cos, r2 * line.sin, z2], abs=1e-12)


@pytest.mark.parametrize('alpha', [0.3, 2.0, -1.1])
def test_the_angle_rates_are_the_angles_derivatives(alpha):
    line = Line(1.0, np.cos(alpha), np.sin(alpha))
    t, h = np.linspace(0.0, 2.0, 41), 1e-6
    psi = lambda t: (0.8 * np.sin(2.1 * t), -0.5 * np.cos(3.3 * t))  # noqa: E731
    dpsi = lambda t: (1.68 * np.cos(2.1 * t), 1.65 * np.sin(3.3 * t))  # noqa: E731
    now = spatial_angles(*psi(t), *dpsi(t), line)
    ahead, behind = spatial_angles(*psi(t + h), 0.0, 0.0, line), spatial_angles(*psi(t - h), 0.0, 0.0, line)
    for name in ('theta1', 'theta2', 'phi1', 'phi2'):
        assert now['d' + name] == pytest.approx((ahead[name] - behind[name]) / (2 * h), abs=1e-7), name


@pytest.mark.parametrize('method, options, request_', [
    ('nvf', PlanOptions(intervals=24), dict(displacement=0.3, bridge=0.2)),
    ('rvf', PlanOptions(robust=('L1',), intervals=24), dict(displacement=-0.3, bridge=0.2)),
    ('nvf', PlanOptions(), dict(displacement=0.3, bridge=-0.2, hoist=(0.47, 0.27))),
])
def test_the_plan_in_the_plane_is_the_coupled_models_optimum(method, options, request_):
    """On the same mesh the coupled NLP and the planar one along the line find the same plan, and the same
    model path (each mass where the coupled NLP predicts it); crane_sim's model ends it without swing."""
    params = P.replace(L1=0.47) if 'hoist' in request_ else P
    a = plan(method, duration=3.0, params=params, options=options, variational=IN_PLANE, **request_)
    b = plan(method, duration=3.0, params=params, options=options, variational=COUPLED, **request_)
    assert a.info['solved_in_plane'] and 'solved_in_plane' not in b.info
    assert a.joint_names == b.joint_names
    t = np.linspace(0.0, 3.0, 301)
    for name in a.joint_names:
        sa, sb = a.axes[name].evaluate(t), b.axes[name].evaluate(t)
        assert sa.position == pytest.approx(sb.position, abs=1e-6), name
        assert sa.acceleration == pytest.approx(sb.acceleration, abs=1e-4), name
    ma, mb = solved_mass_path(a, params), solved_mass_path(b, params)
    assert ma.t == pytest.approx(mb.t)
    assert ma.m1 == pytest.approx(mb.m1, abs=1e-6) and ma.m2 == pytest.approx(mb.m2, abs=1e-6)
    assert residual_mm(a.axes, 3.0, params, starts=a.starts)[0] <= 0.1


@pytest.mark.parametrize('why, params, options, overrides', [
    ('joint damping', P.replace(c1=0.02), PlanOptions(), {}),
    ('an axis limit', P, PlanOptions(max_bridge_velocity=0.2), {}),
    ('the bridge weighed apart', P, PlanOptions(), dict(weights=Weights(bridge=2.0))),
    ('switched off', P, PlanOptions(), dict(straight_moves_in_their_plane=False)),
])
def test_where_the_symmetry_breaks_the_coupled_model_is_solved(why, params, options, overrides):
    p = plan('nvf', 0.3, 3.0, params, options, variational=SolverCache(**overrides), bridge=0.2)
    assert 'solved_in_plane' not in p.info, why
    assert residual_mm(p.axes, 3.0, params)[0] <= 0.1, why


def test_a_move_of_the_bridge_alone_and_one_of_length_zero():
    p = plan('nvf', 0.0, 3.0, P, variational=IN_PLANE, bridge=-0.25)
    assert p.info['solved_in_plane']
    assert p.axes['cart'].evaluate([1.5]).position == pytest.approx([0.0], abs=1e-12)
    assert p.axes['bridge'].evaluate([3.0]).position == pytest.approx([-0.25], abs=1e-9)
    assert residual_mm(p.axes, 3.0, P)[0] <= 0.1
    still = plan('nvf', 0.0, 3.0, P, variational=IN_PLANE, bridge=0.0)
    assert np.abs(still.axes['bridge'].evaluate(np.linspace(0, 3, 31)).position).max() < 1e-9


@settings(max_examples=200, deadline=None)
@given(st.floats(-0.5, 0.5), st.floats(-0.5, 0.5), st.floats(-2.0, 2.0), st.floats(-2.0, 2.0),
       st.floats(-np.pi, np.pi), st.floats(-1.0, 1.0), st.floats(-1.0, 1.0))
def test_a_start_in_one_vertical_plane_is_read_back_as_the_planar_state(psi1, psi2, dpsi1, dpsi2, alpha, v, a):
    """Travel states along the line at ``alpha`` and the swing of ``spatial_angles`` in its plane: the planar
    start is the projection and the planar swing; the same swing tipped out of the plane by 1e-6 rad is not."""
    assume(abs(v) > 1e-3)  # (a state at rest and still lies in every vertical plane)
    line = Line(1.0, np.cos(alpha), np.sin(alpha))
    start = {'y': 0.01 * v, 'v': v, 'a': a, 'a_ref': 1.1 * a}
    start = {**{c: k * line.cos for c, k in start.items()},
             **{b: k * line.sin for b, k in zip(('yb', 'vb', 'ab', 'ab_ref'), start.values(), strict=True)}}
    start.update(spatial_angles(psi1, psi2, dpsi1, dpsi2, line))
    moves = {'cart': 0.4 * v * line.cos, 'bridge': 0.4 * v * line.sin}
    got = planar_start(moves, start)
    assert got is not None
    back, request, planar = got
    sign = np.sign(back.cos * line.cos + back.sin * line.sin)  # (the line's direction: its length >= 0)
    assert (back.cos, back.sin) == pytest.approx((sign * line.cos, sign * line.sin), abs=1e-12)
    assert request['cart'] == pytest.approx(abs(0.4 * v), abs=1e-12)
    for name, value in (('v', v), ('a', a), ('a_ref', 1.1 * a)):
        assert planar[name] == pytest.approx(sign * value, abs=1e-12)
    # the planar swing is measured from the line's direction: mirrored with it
    assert [planar[n] for n in ('theta1', 'theta2', 'dtheta1', 'dtheta2')] == pytest.approx(
        [sign * x for x in (psi1, psi2, dpsi1, dpsi2)], abs=1e-9)
    tipped = dict(start, phi2=start['phi2'] + 1e-6)
    assert planar_start(moves, tipped) is None
    assert planar_start({'cart': moves['cart'] - 1e-6 * line.sin, 'bridge': moves['bridge'] + 1e-6 * line.cos},
                        start) is None  # (and a goal off the line)


@pytest.mark.parametrize('bridge', [0.0, 0.4], ids=['bridge alone', 'diagonal'])
def test_a_stop_from_a_state_in_one_vertical_plane_is_solved_there_and_is_the_coupled_stop(bridge):
    """A 0.6 x ``bridge`` m move (or the bridge's 0.6 m alone) stopped at 40 % from crane_sim's true state
    there: the free-end NVF stop solved in the plane is the coupled NLP's, and crane_sim ends it at rest
    without swing."""
    moves = dict(displacement=0.6, bridge=bridge) if bridge else dict(displacement=0.0, bridge=0.6)
    running = plan('nvf', duration=T, params=P, variational=IN_PLANE, **moves)
    period = first_period(P)

    def request(state, start, model):
        scale = {n: state.axis(n).velocity * period / 2 for n in ('cart', 'bridge')}
        return VariationalRequest('plan', 'nvf', scale, period, model, PlanOptions(), start, free_end=True)
    stops = {name: handover(solvers, P, running, HANDOVER, request)
             for name, solvers in (('in plane', IN_PLANE), ('coupled', COUPLED))}
    a, b = stops['in plane'][0], stops['coupled'][0]
    assert a.info['solved_in_plane'] and 'solved_in_plane' not in b.info
    assert abs(stops['in plane'][1].swing.phi1) > 0.005  # (swinging in the bridge's direction)
    t = np.linspace(0.0, period, 201)
    for name in ('cart', 'bridge'):
        sa, sb = a.axes[name].evaluate(t), b.axes[name].evaluate(t)
        assert sa.position == pytest.approx(sb.position, abs=1e-6), name
        assert sa.acceleration == pytest.approx(sb.acceleration, abs=1e-4), name
    assert_at_rest(a)
    assert 1e3 * stops['in plane'][2].settle() <= 0.5


def test_a_stop_from_a_state_out_of_its_plane_is_solved_coupled():
    """The load pushed across the line of a bridge travel (phi and theta both swinging): coupled."""
    running = plan('nvf', duration=3.0, params=P, variational=IN_PLANE, displacement=0.0, bridge=0.6)
    replay = Replay(NOMINAL, SpatialSwing(theta1=0.02))
    replay.play(running, 1.2)
    state = replay.state(running, 1.2)
    start, model = problem_start(state, P)
    assert planar_start({'cart': 0.0, 'bridge': 0.1}, start) is None
    period = first_period(P)
    scale = {n: state.axis(n).velocity * period / 2 for n in ('cart', 'bridge')}
    stop = IN_PLANE(VariationalRequest('plan', 'nvf', scale, period, model, PlanOptions(), start, free_end=True))
    assert 'solved_in_plane' not in stop.info
