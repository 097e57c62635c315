"""A horizontal disturbance acting on both masses (wind, gusts) in ``crane_sim.simulator``, and the push.

References independent of the code under test: the static equilibrium of a double pendulum in a uniform
field (both cables along g and the field's resultant), its linearized modes (``references``), the
equivalence of the field with the suspension point accelerating the other way (run through the axes with
the servo removed), and the energy of the uniform field's potential.
"""
import math

import numpy as np
import pytest
import scipy.linalg
from references import lagrangian_energy, lagrangian_linearization

from crane_msgs_py.crane.geometry import load_offset
from crane_msgs_py.crane.params import CraneParams
from crane_sim.dynamics import mass_positions
from crane_sim.simulator import CraneSimulator, SimulationError, SpatialSwing, simulate
from crane_sim.spatial import SpatialPendulum

P = CraneParams()  # undamped (c1 = c2 = 0)
SWING = ('theta1', 'theta2', 'dtheta1', 'dtheta2')


def test_a_steady_wind_from_rest_swings_about_the_static_deflection_with_the_first_mode_s_amplitude():
    """From hanging straight, a wind w along +x swings the load about theta1 = -atan(w/g), theta2 = 0 (the
    cables along g + w: the load blown towards +x, theta1 negative as it leads), each mode with the
    amplitude the linearized pendulum gives the start's offset from that equilibrium."""
    w = 0.05  # m/s^2: 5 mrad, small enough for the linear modes (their error ~ amplitude^2)
    r = simulate([0.0, 20.0], [0.0, 0.0], P, dt=1e-3, record_every=5, disturbance=(w, 0.0))
    M, K = lagrangian_linearization(P)
    lam, shapes = scipy.linalg.eigh(K, M)
    omega = np.sqrt(lam) * (1.0 + (w / P.g) ** 2) ** 0.25  # the field's resultant is stiffer by that much
    equilibrium = -math.atan(w / P.g)
    amplitudes = np.linalg.solve(shapes, [0.0 - equilibrium, 0.0])  # the start's offset, mode by mode
    # least squares: a mean and each mode's cosine and sine (at rest at the start: the sines vanish)
    t = r.t
    basis = np.column_stack([np.ones_like(t)] + [f(o * t) for o in omega for f in (np.cos, np.sin)])
    for row, name in enumerate(('theta1', 'theta2')):
        fit, *_ = np.linalg.lstsq(basis, getattr(r, name)[0], rcond=None)
        mean, (c1, s1, c2, s2) = fit[0], fit[1:]
        assert mean == pytest.approx(equilibrium if row == 0 else 0.0, abs=1e-4 * abs(equilibrium))
        assert c1 == pytest.approx(amplitudes[0] * shapes[row, 0], rel=1e-4)
        assert c2 == pytest.approx(amplitudes[1] * shapes[row, 1], abs=1e-4 * abs(equilibrium))
        assert abs(s1) < 1e-5 and abs(s2) < 1e-5
    assert r.y[0] == pytest.approx(0.0, abs=0.0)  # the cart is servo-driven: the wind does not move it


def test_the_wind_s_static_deflection_is_an_equilibrium_planar_and_spatial():
    """Hung along the field's resultant the load stays there: in the plane theta1 = -atan(w/g), and in
    space the cables along (wx, wy, -g): tan(theta1) = -wx/g, sin(phi1) = wy/|(wx, wy, g)|."""
    wx, wy = 1.5, -0.8
    theta = -math.atan(wx / P.g)
    r = simulate([0.0, 3.0], [0.0, 0.0], P, initial_state=[0.0, 0.0, 0.0, theta, 0.0, 0.0, 0.0],
                 disturbance=(wx, 0.0))
    assert np.abs(r.theta1[0] - theta).max() < 1e-12 and np.abs(r.theta2[0]).max() < 1e-12
    sim = CraneSimulator(P, axes=('cart', 'bridge'))
    phi = math.asin(wy / math.sqrt(wx * wx + wy * wy + P.g * P.g))
    sim.reset(swing=SpatialSwing(theta1=theta, phi1=phi))
    sim.disturbance = (wx, wy)
    for _ in range(3000):
        sim.step((0.0, 0.0))
    w = sim.swing
    assert (w.theta1, w.phi1) == pytest.approx((theta, phi), abs=1e-12)
    assert (w.theta2, w.phi2) == pytest.approx((0.0, 0.0), abs=1e-12)
    assert sim.axis_state('cart') == (0.0, 0.0, 0.0) and sim.axis_state('bridge') == (0.0, 0.0, 0.0)


def test_a_disturbance_swings_the_load_as_the_opposite_acceleration_of_servo_free_axes():
    """The field w and the suspension point accelerating by -w (tau = 0: the axes exactly at their
    reference) give the same swing, step by step: constant and ramped, planar and spatial, batch and
    real-time."""
    ideal = P.replace(tau=0.0)
    t = np.arange(0.0, 3.0 + 1e-9, 1e-3)
    # planar batch: a constant (to the bit) and a ramp (the reference's linear interpolation is exact on it)
    for field, cart, exact in (((0.7, 0.0), np.full_like(t, -0.7), True),
                               (lambda s: np.stack((0.4 * s, 0.0 * s)), -0.4 * t, False)):
        pushed = simulate(t, np.zeros_like(t), P, disturbance=field)
        driven = simulate(t, cart, ideal)
        for name in SWING:
            if exact:
                assert np.array_equal(getattr(pushed, name), getattr(driven, name))
            assert getattr(pushed, name) == pytest.approx(getattr(driven, name), rel=1e-12, abs=1e-15)
        assert np.abs(driven.theta1).max() > 0.01 and not np.any(pushed.y)
    # spatial batch, per plant, x and y ramps
    plants = [P, P.replace(L1=0.35)]
    field = lambda s: np.stack((np.stack((0.3 * s, -0.2 * s)), np.stack((0.5 * s, 0.1 * s))))  # noqa: E731
    pushed = simulate(t, {'cart': np.zeros((2, t.size)), 'bridge': np.zeros((2, t.size))}, plants,
                      disturbance=field)
    driven = simulate(t, {'cart': np.stack((-0.3 * t, 0.2 * t)), 'bridge': np.stack((-0.5 * t, -0.1 * t))},
                      [p.replace(tau=0.0) for p in plants])
    for name in (*SWING, 'phi1', 'phi2', 'dphi1', 'dphi2'):
        assert getattr(pushed, name) == pytest.approx(getattr(driven, name), rel=1e-12, abs=1e-14)
    # the real-time simulator, constant, both directions
    pushed, driven = CraneSimulator(P, axes=('cart', 'bridge')), CraneSimulator(ideal, axes=('cart', 'bridge'))
    pushed.disturbance = (0.6, -0.9)
    for _ in range(3000):
        pushed.step((0.0, 0.0))
        driven.step((-0.6, 0.9))
    assert pushed.swing == driven.swing and pushed.axis_state('cart') == (0.0, 0.0, 0.0)
    assert abs(driven.swing.phi1) > 0.01


def test_with_a_constant_field_energy_less_the_field_s_work_is_conserved():
    """Undamped, the cart at rest: E - w . (m1 p1 + m2 p2) (the uniform field's potential) is constant, in the
    batch's planar model and the spatial one, for a field that swings the load far from linear."""
    w = 2.0
    r = simulate([0.0, 10.0], [0.0, 0.0], P, dt=1e-3, record_every=10, disturbance=(w, 0.0),
                 initial_state=[0.0, 0.0, 0.0, 0.2, -0.3, 0.5, 0.0])
    x1, _, x2, _ = mass_positions(0.0, r.theta1[0], r.theta2[0], P.L1, P.L2)
    total = lagrangian_energy(r.theta1[0], r.theta2[0], r.dtheta1[0], r.dtheta2[0], P) - w * (P.m1 * x1 + P.m2 * x2)
    assert np.ptp(total) < 1e-8 and np.ptp(r.theta1[0]) > 0.5

    sim = CraneSimulator(P, axes=('cart', 'bridge'))
    sim.reset(swing=SpatialSwing(theta1=0.2, phi1=-0.1, phi2=0.3, dtheta1=0.4))
    field = (1.2, -1.7)
    sim.disturbance = field
    model = SpatialPendulum(P.L2, P.m1, P.m2, P.g)

    def total():
        s = sim.swing
        angles = (s.theta1, s.phi1, s.theta1 + s.theta2, s.phi1 + s.phi2)
        rates = (s.dtheta1, s.dphi1, s.dtheta1 + s.dtheta2, s.dphi1 + s.dphi2)
        p1, p2 = model.positions((0.0, 0.0, 0.0), angles, P.L1)
        work = sum(field[i] * (P.m1 * p1[i] + P.m2 * p2[i]) for i in range(2))
        return model.energy(angles, rates, P.L1) - work

    values, phi1 = [], []
    for _ in range(10_000):
        sim.step((0.0, 0.0))
        values.append(total())
        phi1.append(sim.swing.phi1)
    assert np.ptp(values) < 1e-9 and np.ptp(phi1) > 0.2


def test_the_real_time_disturbance_is_checked_kept_over_a_reset_and_none_when_zero():
    sim = CraneSimulator(P)
    assert sim.disturbance == (0.0, 0.0)
    with pytest.raises(SimulationError, match='bridge'):
        sim.disturbance = (0.1, 0.2)
    with pytest.raises(SimulationError, match='finite'):
        sim.disturbance = (math.nan, 0.0)
    sim.disturbance = (0.3, 0.0)
    sim.reset()
    assert sim.disturbance == (0.3, 0.0)
    sim.step(0.0)
    assert sim.state.theta1 < 0.0  # blown towards +x: the load leads
    sim.disturbance = (0.0, 0.0)
    sim.reset()
    sim.step(0.0)
    assert sim.state.theta1 == 0.0


def test_no_disturbance_is_the_run_without_one_to_the_bit():
    """Off is off: a zero field, or one set and taken back, steps exactly as a crane never given one (the
    node's defaults leave the sim as it was)."""
    t = np.arange(0.0, 2.0 + 1e-9, 1e-3)
    a = np.sin(3.0 * t)
    plain = simulate(t, {'cart': a, 'hoist': 0.1 * a}, [P, P.replace(L1=0.4)])
    zero = simulate(t, {'cart': a, 'hoist': 0.1 * a}, [P, P.replace(L1=0.4)], disturbance=(0.0, 0.0))
    assert all(np.array_equal(plain.states[name], zero.states[name]) for name in plain.states)
    never, taken_back = (CraneSimulator(P, axes=('cart', 'bridge')) for _ in range(2))
    taken_back.disturbance = (0.5, 0.5)
    taken_back.disturbance = (0.0, 0.0)
    for k in range(t.size - 1):
        for sim in (never, taken_back):
            sim.step((a[k], -a[k]), (a[k + 1], -a[k + 1]))
    assert never.joint_state() == taken_back.joint_state()


def test_a_batch_disturbance_of_a_wrong_shape_or_a_y_row_without_the_bridge_is_named():
    t = [0.0, 1.0]
    for disturbance, match in (((0.1, 0.2), 'bridge'), ((0.1,), 'constant'), ((math.inf, 0.0), 'finite'),
                               (lambda s: np.zeros(s.shape), r'disturbance\(t\)'),
                               (lambda s: np.stack((s, s)), 'bridge')):
        with pytest.raises(SimulationError, match=match):
            simulate(t, [0.0, 0.0], P, disturbance=disturbance)
    # one per plant: the second plant's field only
    r = simulate(t, [[0.0, 0.0], [0.0, 0.0]], P, disturbance=[[0.0, 0.5], [0.0, 0.0]])
    assert not np.any(r.theta1[0]) and r.theta1[1, -1] < 0.0


def test_a_push_displaces_the_load_along_x_and_y_with_the_cables_in_line_from_rest():
    sim = CraneSimulator(P, axes=('cart', 'bridge', 'hoist'))
    for _ in range(500):  # the axes moving: a push leaves them be
        sim.step((0.5, -0.3, 0.1))
    axes = [sim.axis_state(name) for name in sim.axes]
    sim.push(0.02, 0.03)
    w = sim.swing
    assert load_offset(w.theta1, w.theta2, w.phi1, w.phi2, sim.L1, P.L2) == pytest.approx((-0.02, -0.03), abs=1e-15)
    p1, p2 = sim.mass_positions()  # the cables in line: m1 on the line from the suspension point to the load
    s = sim.suspension
    assert [(p1[i] - s[i]) / sim.L1 for i in range(3)] == pytest.approx(
        [(p2[i] - s[i]) / (sim.L1 + P.L2) for i in range(3)], abs=1e-15)
    assert w.theta2 == 0.0 and w.phi2 == 0.0 and w.phi1 < 0.0 < w.theta1
    assert (w.dtheta1, w.dtheta2, w.dphi1, w.dphi2) == (0.0, 0.0, 0.0, 0.0)
    assert [sim.axis_state(name) for name in sim.axes] == axes
    assert sim.load_excursion == pytest.approx(math.hypot(0.02, 0.03), abs=1e-15)
    # along x alone the push of the crane without a bridge: in the plane
    sim.push(0.02)
    assert sim.swing.phi1 == 0.0 and sim.swing.theta1 == math.asin(0.02 / (sim.L1 + P.L2))


def test_a_push_along_y_without_the_bridge_or_past_the_cables_is_refused_naming_why():
    sim = CraneSimulator(P)
    with pytest.raises(SimulationError, match='along y .*needs the bridge'):
        sim.push(0.01, 0.02)
    spatial = CraneSimulator(P, axes=('cart', 'bridge'))
    with pytest.raises(SimulationError, match='less than the cables'):
        spatial.push(0.7, 0.7)
    with pytest.raises(SimulationError, match='less than the cables'):
        spatial.push(math.nan)
