"""The simulator with a hoist: the upper cable's length L1(t) moving while the cart travels.

References independent of the model under test: the simulator without a hoist
(L1 held), a load at rest under a pure hoisting motion, and the power balance
of the two masses computed from their Cartesian motion (Newton: only the
upper cable does work on them, through the cart and the hoist).
"""
import numpy as np
import pytest

from crane_msgs_py.crane.params import CraneParams
from crane_sim.dynamics import hoisting_accelerations, mass_positions
from crane_sim.simulator import HOIST_STATE_NAMES, STATE_NAMES, SimulationError, simulate

T = 3.0


def quintic_acceleration(t, D, T):
    s = np.clip(t / T, 0.0, 1.0)
    return D * (60 * s - 180 * s ** 2 + 120 * s ** 3) / T ** 2


@pytest.mark.parametrize('tau', [0.0, 0.01])
def test_a_held_hoist_reproduces_the_simulation_without_one(tau):
    p = CraneParams(tau=tau, tau_hoist=0.02, c1=0.001, c2=0.0005)
    t = np.linspace(0.0, T, 301)
    fixed = simulate(t, quintic_acceleration(t, 0.3, T), p, t_end=6.0)
    held = simulate(t, {'cart': quintic_acceleration(t, 0.3, T), 'hoist': np.zeros_like(t)}, p, t_end=6.0)
    for name in STATE_NAMES:
        assert np.max(np.abs(getattr(held, name) - getattr(fixed, name))) < 1e-9, name
    assert np.all(held.L1 == p.L1) and np.all(held.dL1 == 0.0)
    assert fixed.L1 is None


@pytest.mark.parametrize('tau_hoist', [0.0, 0.05])
def test_a_load_at_rest_stays_at_rest_while_only_the_hoist_moves(tau_hoist):
    p = CraneParams(tau_hoist=tau_hoist)
    t = np.linspace(0.0, T, 301)
    r = simulate(t, {'cart': np.zeros_like(t), 'hoist': quintic_acceleration(t, -0.2, T)}, p, t_end=5.0)
    assert np.max(np.abs(r.theta1)) == 0.0 and np.max(np.abs(r.theta2)) == 0.0
    assert r.L1[0, -1] == pytest.approx(0.27, abs=2e-4)  # the reference sampled every 10 ms, interpolated


def test_the_hoist_follows_its_servo_exactly():
    """tau_h L'' ' + L'' = a_ref from rest under a constant reference acceleration r: the closed form
    L'' = r (1 - exp(-t / tau_h)), L' = r (t - tau_h (1 - exp(-t / tau_h)))."""
    tau_h, r = 0.05, 0.4
    p = CraneParams(tau_hoist=tau_h)
    t = np.array([0.0, 1.0])
    sim = simulate(t, {'cart': np.zeros(2), 'hoist': np.full(2, r)}, p, dt=1e-3,
                   initial_state=np.r_[np.zeros(7), p.L1, 0.0, 0.0])
    e = np.exp(-sim.t / tau_h)
    assert np.max(np.abs(sim.ddL1[0] - r * (1 - e))) < 1e-12
    assert np.max(np.abs(sim.dL1[0] - r * (sim.t - tau_h * (1 - e)))) < 1e-12


def mass_motion(th1, th2, d1, d2, dd1, dd2, y, v, a, L, dL, ddL, L2):
    """Positions, velocities, accelerations (x, z) of m1 and m2 by differentiating Fig. 1's kinematics."""
    phi, dphi, ddphi = th1 + th2, d1 + d2, dd1 + dd2
    u1, du1 = np.array([-np.sin(th1), -np.cos(th1)]), np.array([-np.cos(th1), np.sin(th1)])
    u2, du2 = np.array([-np.sin(phi), -np.cos(phi)]), np.array([-np.cos(phi), np.sin(phi)])
    ex = np.array([1.0, 0.0])[:, None]
    p1 = np.array([y, 0 * y]) + L * u1
    v1 = v * ex + dL * u1 + L * d1 * du1
    a1 = a * ex + ddL * u1 + 2 * dL * d1 * du1 + L * dd1 * du1 - L * d1 ** 2 * u1
    p2, v2 = p1 + L2 * u2, v1 + L2 * dphi * du2
    a2 = a1 + L2 * ddphi * du2 - L2 * dphi ** 2 * u2
    return p1, v1, a1, p2, v2, a2, u1


def test_the_swing_energy_changes_by_the_work_the_cart_and_hoist_do():
    """E = kinetic + potential energy of the masses; its change equals the work of the upper cable's
    tension T1 on m1 (the lower cable's tension is internal, the cart and the hoist act only through the
    upper cable), T1 from the masses' accelerations along the cable. Hoisting 0.47 -> 0.27 m while the
    cart travels 0.3 m in 3 s, then 2 s of free swing, with servos."""
    p = CraneParams(tau=0.01, tau_hoist=0.02)
    t = np.linspace(0.0, T, 3001)
    sim = simulate(t, {'cart': quintic_acceleration(t, 0.3, T), 'hoist': quintic_acceleration(t, -0.2, T)}, p,
                   dt=5e-4, t_end=5.0)
    rows = {n: getattr(sim, n)[0] for n in STATE_NAMES + HOIST_STATE_NAMES}
    th1, th2, d1, d2 = rows['theta1'], rows['theta2'], rows['dtheta1'], rows['dtheta2']
    acc = hoisting_accelerations(np.stack((th1, th1 + th2)), np.stack((d1, d1 + d2)), rows['a'], rows['L1'],
                                 rows['dL1'], rows['ddL1'], p.L2, p.m1, p.m2, p.g)
    dd1, dd2 = acc[0], acc[1] - acc[0]
    p1, v1, a1, p2, v2, a2, u1 = mass_motion(th1, th2, d1, d2, dd1, dd2, rows['y'], rows['v'], rows['a'],
                                              rows['L1'], rows['dL1'], rows['ddL1'], p.L2)
    # the positions agree with crane_sim's own kinematics
    x1, z1, x2, z2 = mass_positions(rows['y'], th1, th2, rows['L1'], p.L2)
    assert np.allclose(p1, [x1, z1], atol=1e-15) and np.allclose(p2, [x2, z2], atol=1e-15)
    energy = (0.5 * p.m1 * np.sum(v1 ** 2, axis=0) + 0.5 * p.m2 * np.sum(v2 ** 2, axis=0)
              + p.g * (p.m1 * p1[1] + p.m2 * p2[1]))
    gravity = np.array([0.0, p.g])[:, None]
    tension = -np.sum((p.m1 * (a1 + gravity) + p.m2 * (a2 + gravity)) * u1, axis=0)
    power = -tension * np.sum(u1 * v1, axis=0)
    h = sim.t[1] - sim.t[0]
    work = np.concatenate([[0.0], np.cumsum(0.5 * h * (power[1:] + power[:-1]))])
    exchanged = np.max(np.abs(work))
    assert exchanged > 0.5  # lifting 0.39 kg by about 0.2 m: the check is not vacuous
    assert np.max(np.abs(energy - energy[0] - work)) < 1e-6 * exchanged
    # and the lower cable's tension is along it: m2's acceleration across the cable is gravity's alone
    u2p = np.array([-np.cos(th1 + th2), np.sin(th1 + th2)])
    assert np.max(np.abs(np.sum((a2 + gravity) * u2p, axis=0))) < 1e-9


def test_references_are_samples_of_the_same_times_of_known_axes_the_cart_among_them():
    t = np.linspace(0.0, 1.0, 11)
    with pytest.raises(SimulationError, match=r"references\['hoist'\]: reference must have shape"):
        simulate(t, {'cart': np.zeros(11), 'hoist': np.zeros(5)}, CraneParams())
    with pytest.raises(SimulationError, match=r"references\['cart'\] has 2 rows, another axis 3"):
        simulate(t, {'cart': np.zeros((2, 11)), 'hoist': np.zeros((3, 11))}, CraneParams())
    with pytest.raises(SimulationError, match='no axis trolley'):
        simulate(t, {'cart': np.zeros(11), 'trolley': np.zeros(11)}, CraneParams())
    with pytest.raises(SimulationError, match=r'references must be \[cart\]'):
        simulate(t, {'hoist': np.zeros(11)}, CraneParams())


def test_a_position_reference_moves_the_hoist_from_its_first_sample_as_the_acceleration_one_does():
    p = CraneParams(tau_hoist=0.02)
    t = np.arange(0.0, T + 1e-9, 1e-3)
    s = np.clip(t / T, 0.0, 1.0)
    length = 0.47 - 0.2 * (10 * s ** 3 - 15 * s ** 4 + 6 * s ** 5)  # the quintic of quintic_acceleration
    by_position = simulate(t, {'cart': 0.3 * (length[0] - length) / 0.2, 'hoist': length}, p, t_end=5.0,
                           source='position')
    by_acceleration = simulate(t, {'cart': quintic_acceleration(t, 0.3, T), 'hoist': quintic_acceleration(t, -0.2, T)},
                               p.replace(L1=0.47), t_end=5.0)
    assert by_position.L1[0, 0] == 0.47 and by_position.L1[0, -1] == pytest.approx(0.27, abs=1e-9)
    # the second differences are known a sample late (causal): the same motion one 1 ms step later
    assert np.max(np.abs(by_position.L1[0, 1:] - by_acceleration.L1[0, :-1])) < 1e-6
    assert np.max(np.abs(by_position.theta1[0, 1:] - by_acceleration.theta1[0, :-1])) < 1e-6


def test_the_real_time_simulator_steps_the_hoist_as_the_batch_simulation_does():
    from crane_sim.simulator import HOIST_JOINT_NAMES, CraneSimulator
    p = CraneParams(tau=0.01, tau_hoist=0.02)
    t = np.arange(0.0, 3.0 + 1e-9, 1e-3)
    a, h = quintic_acceleration(t, 0.3, T), quintic_acceleration(t, -0.2, T)
    batch = simulate(t, {'cart': a, 'hoist': h}, p, dt=1e-3)
    sim = CraneSimulator(p, dt=1e-3, axes=('cart', 'hoist'))
    for k in range(t.size - 1):
        sim.step((a[k], h[k]), (a[k + 1], h[k + 1]))
    assert sim.joint_names == HOIST_JOINT_NAMES
    positions, velocities = sim.joint_state()
    assert positions == pytest.approx([batch.y[0, -1], batch.L1[0, -1], batch.theta1[0, -1], batch.theta2[0, -1]],
                                      abs=1e-12)
    assert velocities[1] == pytest.approx(batch.dL1[0, -1], abs=1e-12)
    sim.reset()  # at rest where the rope is
    assert sim.L1 == pytest.approx(batch.L1[0, -1], abs=1e-12) and sim.axis_state('hoist')[1:] == (0.0, 0.0)
