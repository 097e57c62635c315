"""Independent references the tests share (not part of the product): computed here, from crane_sim alone."""
import numpy as np

from crane_sim.dynamics import swing_accelerations


def linearized_modes(p):
    """(omega, zeta) per mode, slow first, from the eigenvalues of the simulator's Eqs. 18-19 (with
    joint damping) linearized at rest by central finite differences: independent of the planning
    model's analytic linearization (``model.modal_properties``)."""
    A = np.zeros((4, 4))
    A[0, 2] = A[1, 3] = 1.0
    h = 1e-7
    for j in range(4):
        dx = np.zeros(4)
        dx[j] = h
        up = swing_accelerations(*dx, 0.0, p.L1, p.L2, p.m1, p.m2, p.g, p.c1, p.c2)
        down = swing_accelerations(*-dx, 0.0, p.L1, p.L2, p.m1, p.m2, p.g, p.c1, p.c2)
        A[2:, j] = (np.array(up) - np.array(down)) / (2 * h)
    lam = np.linalg.eigvals(A)
    lam = sorted(lam[lam.imag > 0], key=abs)
    return [abs(x) for x in lam], [-x.real / abs(x) for x in lam]


def lagrangian_linearization(p):
    """(M, K): the mass and stiffness matrices of the double pendulum linearized at rest, in the relative angles
    (theta1, theta2), from the Lagrangian written here independently of the code under test:
    T = m1/2 (L1 th1')^2 + m2/2 (L1 th1' + L2 (th1' + th2'))^2,
    V = -m1 g L1 cos th1 - m2 g (L1 cos th1 + L2 cos(th1 + th2))."""
    m1, m2, L1, L2, g = p.m1, p.m2, p.L1, p.L2, p.g
    M = np.array([[m1 * L1**2 + m2 * (L1 + L2)**2, m2 * L2 * (L1 + L2)],
                  [m2 * L2 * (L1 + L2), m2 * L2**2]])
    K = np.array([[(m1 + m2) * g * L1 + m2 * g * L2, m2 * g * L2],
                  [m2 * g * L2, m2 * g * L2]])
    return M, K


def lagrangian_energy(th1, th2, d1, d2, p):
    """Kinetic plus potential energy of the two masses, cart at rest (Fig. 1 kinematics).

    x_m1 = -L1 sin th1, z_m1 = -L1 cos th1, x_m2 = x_m1 - L2 sin(th1+th2),
    z_m2 = z_m1 - L2 cos(th1+th2); potential measured from the hanging rest.
    """
    phi, dphi = th1 + th2, d1 + d2
    vx1, vz1 = -p.L1 * np.cos(th1) * d1, p.L1 * np.sin(th1) * d1
    vx2, vz2 = vx1 - p.L2 * np.cos(phi) * dphi, vz1 + p.L2 * np.sin(phi) * dphi
    z1 = -p.L1 * np.cos(th1)
    z2 = z1 - p.L2 * np.cos(phi)
    kinetic = 0.5 * p.m1 * (vx1**2 + vz1**2) + 0.5 * p.m2 * (vx2**2 + vz2**2)
    rest = -p.g * (p.m1 * p.L1 + p.m2 * (p.L1 + p.L2))
    return kinetic + p.g * (p.m1 * z1 + p.m2 * z2) - rest


def peak_swing_at_rest(sim, seconds: float) -> float:
    """The largest load swing (m; the norm with a bridge) of a ``crane_sim.simulator.CraneSimulator`` stepped
    ``seconds`` on with every axis's reference acceleration at 0: the residual after a motion."""
    worst = 0.0
    rest = [0.0] * len(sim.axes)
    for _ in range(int(round(seconds / sim.dt))):
        sim.step(rest)
        worst = max(worst, abs(sim.load_excursion))
    return worst
