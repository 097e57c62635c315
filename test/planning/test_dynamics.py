"""crane_planner.planning.dynamics (CasADi, Eqs. 6, 18-19 and 14) against independent references.

References: crane_sim's numpy implementation of Eqs. 18-19, energy conservation
in the uniformly accelerated cart frame, the linearized matrices of
crane_planner.planning.model, and finite differences of perturbed simulations for the
sensitivity equations.
"""
import casadi as ca
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from crane_msgs_py.crane.params import CraneParams
from crane_planner.planning.dynamics import (
    PARAMETERS,
    SWING_STATES,
    augment,
    crane_ode,
    sensitivity_states,
    swing_accelerations,
)
from crane_planner.planning.model import linearized_matrices
from crane_sim import dynamics as sim_dynamics

P = CraneParams()


def pvec(p: CraneParams) -> np.ndarray:
    return np.array([getattr(p, q) for q in PARAMETERS])


angle = st.floats(-1.2, 1.2)
rate = st.floats(-3.0, 3.0)


@settings(max_examples=300, deadline=None)
@given(angle, angle, rate, rate, st.floats(-20, 20), st.floats(0.1, 2.0), st.floats(0.1, 2.0),
       st.floats(0.05, 5.0), st.floats(0.05, 5.0), st.sampled_from([0.0, 0.003, 0.05]),
       st.sampled_from([0.0, 0.002, 0.04]))
def test_swing_accelerations_match_crane_sim(th1, th2, d1, d2, a, L1, L2, m1, m2, c1, c2):
    mine = swing_accelerations(th1, th2, d1, d2, a, L1, L2, m1, m2, 9.81, c1, c2)
    theirs = sim_dynamics.swing_accelerations(th1, th2, d1, d2, a, L1, L2, m1, m2, 9.81, c1, c2)
    scale = (1.0 + abs(a) + (d1 ** 2 + d2 ** 2) * max(L1, L2) / min(L1, L2) + 9.81 / min(L1, L2)
             + (c1 + c2) * (abs(d1) + abs(d2)) / (min(m1, m2) * min(L1, L2) ** 2))
    np.testing.assert_allclose(np.array(mine, dtype=float), theirs, rtol=0, atol=1e-12 * scale)


def test_ode_matches_crane_sim_at_random_states():
    rng = np.random.default_rng(7)
    f = crane_ode(servo=False).function()
    for _ in range(50):
        x = rng.uniform(-1, 1, 7) * [1, 1, 5, 1, 1, 2, 2]
        u = rng.uniform(-10, 10)
        xdot = np.array(f(x, u, pvec(P))).ravel()
        dd1, dd2 = sim_dynamics.swing_accelerations(*x[3:7], x[2], P.L1, P.L2, P.m1, P.m2, P.g)
        np.testing.assert_allclose(xdot, [x[1], x[2], u, x[5], x[6], dd1, dd2], rtol=1e-12, atol=1e-12)


def simulate_ode(ode, p: CraneParams, t, x0=None, u=lambda time: 3.0 * ca.sin(3.0 * time) + 2.0 * ca.cos(7.0 * time)):
    """States at times ``t`` (columns) from ``x0`` (default rest) under the input u(t) (CVODES, tight tolerances)."""
    time = ca.SX.sym('t')
    f = ca.substitute(ca.substitute(ode.f, ode.u, u(time)), ode.p, ca.DM(pvec(p)))
    integ = ca.integrator('sim', 'cvodes', {'t': time, 'x': ode.x, 'ode': f}, t[0], t[1:],
                          {'abstol': 1e-13, 'reltol': 1e-12})
    x0 = np.zeros(len(ode.states)) if x0 is None else np.asarray(x0, dtype=float)
    return np.hstack([x0[:, None], np.array(integ(x0=x0)['xf'])])


def accelerated_frame_energy(x, a, p):
    """Energy of the masses in the cart frame under constant cart acceleration a.

    In that frame the masses feel gravity (-a, -g) in (x, z), so
    E = kinetic + sum m_i (g z_i + a x_i) is conserved, with (Fig. 1)
    x_m1 = -L1 sin th1, z_m1 = -L1 cos th1, x_m2 = x_m1 - L2 sin(th1+th2), z_m2 = z_m1 - L2 cos(th1+th2).
    """
    th1, th2, d1, d2 = x
    phi, dphi = th1 + th2, d1 + d2
    x1, z1 = -p.L1 * np.sin(th1), -p.L1 * np.cos(th1)
    x2, z2 = x1 - p.L2 * np.sin(phi), z1 - p.L2 * np.cos(phi)
    vx1, vz1 = -p.L1 * np.cos(th1) * d1, p.L1 * np.sin(th1) * d1
    vx2, vz2 = vx1 - p.L2 * np.cos(phi) * dphi, vz1 + p.L2 * np.sin(phi) * dphi
    kinetic = 0.5 * p.m1 * (vx1 ** 2 + vz1 ** 2) + 0.5 * p.m2 * (vx2 ** 2 + vz2 ** 2)
    return kinetic + p.m1 * (p.g * z1 + a * x1) + p.m2 * (p.g * z2 + a * x2)


@pytest.mark.parametrize('a', [0.0, 2.5, -4.0])
def test_energy_is_conserved_under_constant_cart_acceleration(a):
    """Checks Eqs. 18-19 including the sign of the cart coupling (load lags a positive a)."""
    ode = crane_ode(servo=False)
    t = np.linspace(0, 5, 200)
    x = simulate_ode(ode, P, t, x0=[0, 0, a, 0.6, -0.4, 0.5, -1.0], u=lambda time: 0)
    e = accelerated_frame_energy(x[3:], a, P)
    assert np.ptp(e) < 1e-8 * (abs(e[0]) + 1e-3)
    # and with a positive a from rest the pendulum swings back (theta1 grows)
    if a > 0:
        rest = np.array(ode.function()(np.zeros(7) + np.eye(7)[2] * a, 0.0, pvec(P))).ravel()
        assert rest[5] > 0


@pytest.mark.parametrize('servo', [False, True])
def test_linearization_matches_model_matrices(servo):
    ode = crane_ode(servo)
    A = ca.Function('A', [ode.x, ode.u, ode.p], [ca.jacobian(ode.f, ode.x)])(np.zeros(len(ode.states)), 0, pvec(P))
    A = np.array(A)
    M, K, b = linearized_matrices(P)
    sw = [ode.index(n) for n in SWING_STATES]
    ia = ode.index('a')
    # rows of theta1'', theta2'': -M^-1 K on the angles, M^-1 b on the cart acceleration
    np.testing.assert_allclose(A[np.ix_(sw[2:], sw[:2])], -np.linalg.solve(M, K), rtol=1e-12)
    np.testing.assert_allclose(A[sw[2:], ia], np.linalg.solve(M, b), rtol=1e-12)
    if servo:  # Eq. 6: a' = (a_ref - a)/tau
        assert A[ia, ia] == pytest.approx(-1 / P.tau)
        assert A[ia, ode.index('a_ref')] == pytest.approx(1 / P.tau)


def test_sensitivity_states():
    ideal, servo = crane_ode(False), crane_ode(True)
    for q in ('L1', 'L2', 'm1', 'm2'):
        assert sensitivity_states(ideal, q) == SWING_STATES
        assert sensitivity_states(servo, q) == SWING_STATES
    # y and v do not feed back; the swing's end sensitivities to tau follow from the acceleration's
    assert sensitivity_states(servo, 'tau') == ('a',)
    assert augment(servo, ('m2', 'tau', 'L1')).robust == ('m2', 'tau')
    with pytest.raises(ValueError, match='tau'):
        augment(ideal, ('tau',))


@pytest.mark.parametrize('servo,q', [(False, 'L1'), (False, 'm2'), (True, 'L2'), (True, 'tau')])
def test_sensitivity_equations_match_finite_differences(servo, q):
    """Eq. 14 integrated alongside the model equals d x / d q of perturbed simulations."""
    aug = augment(crane_ode(servo), (q,))
    base = crane_ode(servo)
    t = np.linspace(0, 2.0, 41)
    xs = simulate_ode(aug, P, t)
    h = 1e-5 * getattr(P, q)
    plus = simulate_ode(base, P.replace(**{q: getattr(P, q) + h}), t)
    minus = simulate_ode(base, P.replace(**{q: getattr(P, q) - h}), t)
    fd = (plus - minus) / (2 * h)
    n = len(base.states)
    for k, name in enumerate(aug.states[n:]):
        state = name[1:].split('/d')[0]
        i = base.index(state)
        np.testing.assert_allclose(xs[n + k], fd[i], rtol=1e-5, atol=1e-6 * np.abs(fd[i]).max())
        assert np.abs(fd[i]).max() > 1e-3  # the test would notice a zero sensitivity
