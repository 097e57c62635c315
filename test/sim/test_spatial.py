"""The simulator's spatial crane (``crane_sim.spatial``, stepped by ``CraneSimulator`` with a bridge).

References independent of it: the planar model of Eqs. 18-19 (``crane_sim.dynamics``, derived
separately and stepped by the batch simulator), the conservation of energy, the closed-form
linear modes of the double pendulum, and the rotational symmetry of the physics about the
vertical (a straight move at 45 degrees swings as the planar crane does along it).
"""
import math

import numpy as np
import pytest

from crane_msgs_py.crane.params import CraneParams
from crane_sim.dynamics import hoisting_accelerations
from crane_sim.simulator import CraneSimulator, SpatialSwing, simulate
from crane_sim.spatial import SpatialPendulum

P = CraneParams()  # the paper's rig: L1 0.47, L2 0.391, m1 0.192, m2 0.201
DAMPED = P.replace(c1=0.002, c2=0.003)


def quintic(t, d, T):
    """Rest-to-rest quintic of ``d`` in ``T``: position and acceleration at ``t``."""
    s = np.clip(t / T, 0.0, 1.0)
    return d * (10 * s**3 - 15 * s**4 + 6 * s**5), d * (60 * s - 180 * s**2 + 120 * s**3) / T**2


def model(p=P):
    return SpatialPendulum(p.L2, p.m1, p.m2, p.g, p.c1, p.c2)


def test_in_the_x_z_plane_the_spatial_model_is_the_planar_one_hoisting_and_damped():
    rng = np.random.default_rng(3)
    m = model(DAMPED)
    for _ in range(50):
        th1, phi, d1, dphi, a, dL1, ddL1 = rng.normal(scale=0.5, size=7)
        L1 = rng.uniform(0.2, 0.6)
        planar = hoisting_accelerations(np.array([th1, phi]), np.array([d1, dphi]), a, L1, dL1, ddL1, DAMPED.L2,
                                        DAMPED.m1, DAMPED.m2, DAMPED.g, DAMPED.c1, DAMPED.c2)
        dda1, ddb1, dda2, ddb2 = m.accelerations((th1, 0.0, phi, 0.0), (d1, 0.0, dphi, 0.0), a, 0.0, L1, dL1, ddL1)
        assert (dda1, dda2) == pytest.approx(tuple(planar), rel=1e-12, abs=1e-12)
        assert ddb1 == 0.0 and ddb2 == 0.0


def test_the_spatial_simulator_without_bridge_motion_follows_the_planar_batch_simulation():
    t = np.arange(0.0, 3.0 + 1e-9, 1e-3)
    _, a = quintic(t, 0.4, 2.0)
    _, h = quintic(t, -0.15, 2.0)
    batch = simulate(t, {'cart': a, 'hoist': h}, DAMPED, dt=1e-3)
    sim = CraneSimulator(DAMPED, dt=1e-3, axes=('cart', 'bridge', 'hoist'))
    for k in range(t.size - 1):
        sim.step((a[k], 0.0, h[k]), (a[k + 1], 0.0, h[k + 1]))
    w = sim.swing
    assert w.phi1 == 0.0 and w.phi2 == 0.0 and sim.axis_state('bridge') == (0.0, 0.0, 0.0)
    for name in ('theta1', 'theta2', 'dtheta1', 'dtheta2'):
        assert getattr(w, name) == pytest.approx(getattr(batch, name)[0, -1], abs=1e-9)
    assert sim.L1 == pytest.approx(batch.L1[0, -1], abs=1e-12)
    assert sim.load_excursion == pytest.approx(abs(batch.load_excursion[0, -1]), abs=1e-9)


def test_free_spatial_swing_conserves_energy_over_10_s():
    sim = CraneSimulator(P, dt=1e-3, axes=('cart', 'bridge'))
    swing = SpatialSwing(theta1=0.25, theta2=-0.3, phi1=0.2, phi2=0.35, dtheta1=0.4, dphi1=-0.6, dphi2=0.8)
    sim.reset(swing=swing)
    m = model()

    def energy():
        w = sim.swing
        angles = (w.theta1, w.phi1, w.theta1 + w.theta2, w.phi1 + w.phi2)
        rates = (w.dtheta1, w.dphi1, w.dtheta1 + w.dtheta2, w.dphi1 + w.dphi2)
        return m.energy(angles, rates, P.L1)

    e0, lowest = energy(), []
    for _ in range(10_000):
        sim.step((0.0, 0.0))
        lowest.append(sim.mass_positions()[1][2])
    assert abs(energy() - e0) < 1e-6
    # it did swing in both directions and exchange energy between the cables
    assert sim.swing.phi1 != pytest.approx(swing.phi1, abs=1e-2) and np.ptp(lowest) > 0.05


def test_the_linearization_about_rest_has_the_planar_frequencies_in_both_planes():
    m, eps = model(), 1e-7
    jac = np.zeros((8, 8))
    for i in range(8):
        x = np.zeros(8)
        x[i] = eps
        jac[:4, i] = x[4:] / eps
        jac[4:, i] = np.array(m.accelerations(x[:4], x[4:], 0.0, 0.0, P.L1)) / eps
    omegas = np.sort(np.abs(np.linalg.eigvals(jac).imag))
    # closed form: the double pendulum's mass and stiffness matrices in the absolute angles
    mt = P.m1 + P.m2
    M = np.array([[mt * P.L1 ** 2, P.m2 * P.L1 * P.L2], [P.m2 * P.L1 * P.L2, P.m2 * P.L2 ** 2]])
    K = np.diag([mt * P.g * P.L1, P.m2 * P.g * P.L2])
    planar = np.sqrt(np.sort(np.linalg.eigvals(np.linalg.solve(M, K)).real))
    assert planar == pytest.approx([3.642, 8.990], abs=1e-3)
    assert omegas == pytest.approx(np.repeat(planar, 4), rel=1e-6)


def test_a_straight_move_at_45_degrees_swings_as_the_planar_crane_along_it():
    T, d = 2.0, 0.5
    t = np.arange(0.0, 4.0 + 1e-9, 1e-3)
    _, a = quintic(t, d, T)
    planar = simulate(t, a, P, dt=1e-3).load_excursion[0]
    sim = CraneSimulator(P, dt=1e-3, axes=('cart', 'bridge'))
    along = a / math.sqrt(2.0)
    excursion = [0.0]
    for k in range(t.size - 1):
        sim.step((along[k], along[k]), (along[k + 1], along[k + 1]))
        excursion.append(sim.load_excursion)
    assert np.abs(planar).max() > 0.01  # it did swing
    assert np.array(excursion) == pytest.approx(np.abs(planar), abs=1e-8)
    w = sim.swing  # the swing stays in the vertical plane of the move
    p1, p2 = sim.mass_positions()
    assert p2[0] - sim.axis_state('cart')[0] == pytest.approx(p2[1] - sim.axis_state('bridge')[0], abs=1e-9)
    assert w.phi1 != 0.0 and w.theta1 != 0.0


def test_the_batch_simulation_with_a_bridge_steps_each_plant_as_the_real_time_simulator():
    t = np.arange(0.0, 2.5 + 1e-9, 1e-3)
    _, a = quintic(t, 0.3, 2.0)
    _, b = quintic(t, -0.2, 2.0)
    plants = [DAMPED, DAMPED.replace(L1=0.4, tau=0.02)]
    batch = simulate(t, {'cart': a, 'bridge': b}, plants, dt=1e-3, t_end=3.5, rest_dt=5e-3)
    assert batch.phi1.shape == batch.theta1.shape == (2, batch.t.size)
    for i, plant in enumerate(plants):
        sim = CraneSimulator(plant, dt=1e-3, axes=('cart', 'bridge'))
        for k in range(t.size - 1):
            sim.step((a[k], b[k]), (a[k + 1], b[k + 1]))
        k = np.searchsorted(batch.t, t[-1])
        assert batch.t[k] == pytest.approx(t[-1])
        w = sim.swing
        for name in ('theta1', 'theta2', 'phi1', 'phi2', 'dphi2'):
            assert getattr(batch, name)[i, k] == pytest.approx(getattr(w, name), abs=1e-12)
        assert batch.yb[i, k] == pytest.approx(sim.axis_state('bridge')[0], abs=1e-12)
        assert batch.load_excursion[i, k] == pytest.approx(sim.load_excursion, abs=1e-12)
    assert batch.yb[0, -1] == pytest.approx(-0.2, abs=1e-6) and batch.load_excursion.max() > 0.01
