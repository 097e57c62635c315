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
