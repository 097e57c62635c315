"""crane_sim.dynamics against the paper's Eqs. 18-19 and the Lagrangian energy."""
import numpy as np
import pytest
from references import lagrangian_energy, linearized_modes

from crane_msgs_py.crane.geometry import load_excursion
from crane_msgs_py.crane.params import CraneParams
from crane_sim.dynamics import swing_accelerations
from crane_sim.simulator import simulate

P = CraneParams()


def eq18_eq19_residuals(th1, th2, d1, d2, dd1, dd2, a, p):
    """Eqs. 18-19 exactly as printed in the paper, left minus right side."""
    mt = p.m1 + p.m2
    r18 = (mt * (p.L1 * dd1 + p.g * np.sin(th1))
           + p.m2 * p.L2 * ((dd1 + dd2) * np.cos(th2) - (d1 + d2) ** 2 * np.sin(th2))
           - a * mt * np.cos(th1))
    r19 = (p.L2 * (dd1 + dd2) + p.g * np.sin(th1 + th2)
           + p.L1 * (d1 ** 2 * np.sin(th2) + dd1 * np.cos(th2))
           - a * np.cos(th1 + th2))
    return r18, r19


def test_accelerations_satisfy_eqs_18_19():
    rng = np.random.default_rng(7)
    th1, th2 = rng.uniform(-1.2, 1.2, (2, 500))
    d1, d2 = rng.uniform(-3.0, 3.0, (2, 500))
    a = rng.uniform(-5.0, 5.0, 500)
    for p in (P, CraneParams(L1=0.2, L2=0.9, m1=1.5, m2=0.05, g=3.7)):
        dd1, dd2 = swing_accelerations(th1, th2, d1, d2, a, p.L1, p.L2, p.m1, p.m2, p.g)
        r18, r19 = eq18_eq19_residuals(th1, th2, d1, d2, dd1, dd2, a, p)
        assert np.abs(r18).max() < 1e-11
        assert np.abs(r19).max() < 1e-11


def test_accelerations_broadcast():
    L1 = np.array([0.3, 0.47, 0.6])
    dd1, dd2 = swing_accelerations(0.1, -0.2, 0.3, 0.0, 1.0, L1, P.L2, P.m1, P.m2, P.g)
    assert dd1.shape == dd2.shape == (3,)
    for i, L in enumerate(L1):
        s1, s2 = swing_accelerations(0.1, -0.2, 0.3, 0.0, 1.0, L, P.L2, P.m1, P.m2, P.g)
        assert dd1[i] == pytest.approx(float(s1), rel=1e-13)
        assert dd2[i] == pytest.approx(float(s2), rel=1e-13)
    # a column of plants against a row of states gives the outer product of shapes
    dd1, _ = swing_accelerations(np.zeros(4), 0.0, 0.0, 0.0, 1.0, L1[:, None], P.L2, P.m1, P.m2, P.g)
    assert dd1.shape == (3, 4)


def test_cart_acceleration_makes_the_load_lag():
    """From rest, a positive cart acceleration swings the upper cable back (theta1'' = a / L1 > 0).

    The lower mass hangs on a vertical cable, so at first its absolute angle
    does not accelerate: theta1'' + theta2'' = 0.
    """
    dd1, dd2 = swing_accelerations(0.0, 0.0, 0.0, 0.0, 1.0, P.L1, P.L2, P.m1, P.m2, P.g)
    assert dd1 == pytest.approx(1.0 / P.L1, rel=1e-14)
    assert dd1 + dd2 == pytest.approx(0.0, abs=1e-14)


def test_load_excursion_is_the_kinematic_offset():
    th1, th2 = 0.2, -0.35
    x_m2 = -P.L1 * np.sin(th1) - P.L2 * np.sin(th1 + th2)  # cart at 0
    assert load_excursion(th1, th2, P.L1, P.L2) == pytest.approx(-x_m2, rel=1e-15)
    assert load_excursion(0.1, 0.0, P.L1, P.L2) > 0.0


def test_unforced_energy_is_conserved():
    """Cart held at rest: the Lagrangian energy stays constant over 20 s at 1 ms.

    Two releases in one batch: theta1 = 0.3 alone, and both angles and rates nonzero.
    """
    starts = np.array([[0.0, 0.0, 0.0, 0.3, 0.0, 0.0, 0.0],
                       [0.0, 0.0, 0.0, 0.3, -0.6, 0.5, -1.0]])
    r = simulate([0.0, 20.0], [0.0, 0.0], [P, P], dt=1e-3, record_every=10, initial_state=starts)
    assert r.t[-1] == pytest.approx(20.0)
    assert np.all(r.y == 0.0) and np.all(r.v == 0.0) and np.all(r.a == 0.0)
    for i in range(2):
        e = lagrangian_energy(r.theta1[i], r.theta2[i], r.dtheta1[i], r.dtheta2[i], P)
        assert np.abs(r.theta1[i]).max() > 0.25          # it really swings
        assert np.abs(r.theta2[i]).max() > 0.05
        drift = np.abs(e - e[0]).max() / e[0]
        assert drift < 1e-6, f'start {i}: relative energy drift {drift:.2e}'


def test_joint_damping_dissipates_exactly_the_rayleigh_power():
    """Cart at rest, damped joints: dE/dt = -(c1 theta1'^2 + c2 theta2'^2) at every state.

    dE/dt from the energy of Fig. 1's kinematics along the accelerations (a
    central difference of E along the state's velocity), against the power of
    the two joint torques: independent of how the damping enters Eqs. 18-19.
    """
    rng = np.random.default_rng(3)
    p = CraneParams(c1=0.02, c2=0.011)
    for _ in range(200):
        th1, th2 = rng.uniform(-1.0, 1.0, 2)
        d1, d2 = rng.uniform(-2.0, 2.0, 2)
        dd1, dd2 = swing_accelerations(th1, th2, d1, d2, 0.0, p.L1, p.L2, p.m1, p.m2, p.g, p.c1, p.c2)
        h = 1e-6
        up = lagrangian_energy(th1 + h * d1, th2 + h * d2, d1 + h * dd1, d2 + h * dd2, p)
        down = lagrangian_energy(th1 - h * d1, th2 - h * d2, d1 - h * dd1, d2 - h * dd2, p)
        power = -(p.c1 * d1 ** 2 + p.c2 * d2 ** 2)
        assert (up - down) / (2 * h) == pytest.approx(power, abs=1e-7)


def test_damped_modes_from_linearizing_the_simulator_match_the_planning_model():
    """Eigenvalues of a finite-difference linearization of the numpy model at rest vs model.modal_properties."""
    from crane_planner.planning.model import modal_properties
    p = CraneParams(L1=0.52, L2=0.35, m1=0.25, m2=0.18, c1=0.012, c2=0.004)
    reference_omega, reference_zeta = linearized_modes(p)
    omega, zeta = modal_properties(p)
    for k in range(2):
        assert omega[k] == pytest.approx(reference_omega[k], rel=1e-6)
        assert zeta[k] == pytest.approx(reference_zeta[k], rel=1e-5)
    assert 0.005 < zeta[0] < 0.2 and 0.005 < zeta[1] < 0.2  # both modes really damped
