"""The spatial crane's CasADi model (``dynamics.spatial_swing``, ``crane_ode(bridge=True)``) against references.

References: the planar models of the planner (Eqs. 18-19 and the hoisting
Lagrangian ``hoisting_swing``) in the x-z plane, and crane_sim's spatial
pendulum, derived independently (Newton's law projected across the cables,
absolute angles).
"""
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from crane_msgs_py.crane.params import CraneParams
from crane_planner.planning.dynamics import (
    BRIDGE_STATES,
    PARAMETERS,
    SPATIAL_SWING_STATES,
    augment,
    crane_ode,
    hoisting_swing,
    sensitivity_states,
    spatial_swing,
    swing_accelerations,
)
from crane_sim.spatial import SpatialPendulum

P = CraneParams()
angles = st.floats(-1.2, 1.2)
rates = st.floats(-3.0, 3.0)


def pvec(p: CraneParams) -> np.ndarray:
    return np.array([getattr(p, q) for q in PARAMETERS])


def spatial(th1, th2, ph1, ph2, d1, d2, e1, e2, ax, ay, L1, dL1, ddL1, L2, m1, m2, c1=0.0, c2=0.0) -> np.ndarray:
    return np.array([float(x) for x in spatial_swing()(th1, th2, ph1, ph2, d1, d2, e1, e2, ax, ay, L1, dL1, ddL1,
                                                        L2, m1, m2, 9.81, c1, c2)])


@settings(max_examples=200, deadline=None)
@given(angles, angles, rates, rates, st.floats(-5, 5), st.floats(0.1, 1.5), st.floats(-1.0, 1.0),
       st.floats(-3.0, 3.0), st.floats(0.1, 1.5), st.floats(0.05, 2.0), st.floats(0.05, 2.0),
       st.floats(0.0, 0.05), st.floats(0.0, 0.05))
def test_in_the_plane_the_spatial_model_is_the_hoisting_one(th1, th2, d1, d2, a, L1, dL1, ddL1, L2, m1, m2, c1, c2):
    """phi1 = phi2 = 0, no bridge motion: the theta rows are ``hoisting_swing``'s, the phi rows zero."""
    planar = [float(x) for x in hoisting_swing()(th1, th2, d1, d2, a, L1, dL1, ddL1, L2, m1, m2, 9.81, c1, c2)]
    mine = spatial(th1, th2, 0.0, 0.0, d1, d2, 0.0, 0.0, a, 0.0, L1, dL1, ddL1, L2, m1, m2, c1, c2)
    scale = 1.0 + np.abs(planar).max()
    np.testing.assert_allclose(mine, [*planar, 0.0, 0.0], rtol=0, atol=1e-9 * scale)


@settings(max_examples=100, deadline=None)
@given(angles, angles, rates, rates, st.floats(-20, 20))
def test_with_the_length_held_in_the_plane_it_is_eqs_18_19(th1, th2, d1, d2, a):
    p = P
    eqs = [float(x) for x in swing_accelerations(th1, th2, d1, d2, a, p.L1, p.L2, p.m1, p.m2, p.g, p.c1, p.c2)]
    mine = spatial(th1, th2, 0.0, 0.0, d1, d2, 0.0, 0.0, a, 0.0, p.L1, 0.0, 0.0, p.L2, p.m1, p.m2, p.c1, p.c2)
    np.testing.assert_allclose(mine, [*eqs, 0.0, 0.0], rtol=0, atol=1e-9 * (1.0 + np.abs(eqs).max()))


@settings(max_examples=300, deadline=None)
@given(angles, angles, angles, angles, rates, rates, rates, rates, st.floats(-10, 10), st.floats(-10, 10),
       st.floats(0.1, 1.5), st.floats(-1.0, 1.0), st.floats(-3.0, 3.0), st.floats(0.1, 1.5), st.floats(0.05, 2.0),
       st.floats(0.05, 2.0), st.sampled_from([0.0, 0.003, 0.05]), st.sampled_from([0.0, 0.002, 0.04]))
def test_the_lagrangian_model_agrees_with_the_simulators_newton_form(th1, th2, ph1, ph2, d1, d2, e1, e2, ax, ay,
                                                                      L1, dL1, ddL1, L2, m1, m2, c1, c2):
    """Two derivations of the spatial crane: CasADi from the Lagrangian with relative angles (planner), Newton's
    law projected across the cables with absolute angles (crane_sim), at random spatial states."""
    mine = spatial(th1, th2, ph1, ph2, d1, d2, e1, e2, ax, ay, L1, dL1, ddL1, L2, m1, m2, c1, c2)
    sim = SpatialPendulum(L2, m1, m2, 9.81, c1, c2).accelerations(
        (th1, ph1, th1 + th2, ph1 + ph2), (d1, e1, d1 + d2, e1 + e2), ax, ay, L1, dL1, ddL1)
    theirs = np.array([sim[0], sim[2] - sim[0], sim[1], sim[3] - sim[1]])
    np.testing.assert_allclose(mine, theirs, rtol=1e-9, atol=1e-9 * (1.0 + np.abs(theirs).max()))


def test_the_planar_forms_of_crane_ode_are_unchanged_by_the_bridge():
    """Without a bridge every form keeps its states; with one the bridge's states follow the cart's."""
    assert crane_ode(True).states == ('y', 'v', 'a', 'a_ref', 'theta1', 'theta2', 'dtheta1', 'dtheta2')
    ode = crane_ode(True, hoist=True, hoist_servo=True, bridge=True)
    assert ode.states == ('y', 'v', 'a', 'a_ref', *BRIDGE_STATES, 'h', 'hv', 'ha', 'ha_ref', *SPATIAL_SWING_STATES)
    assert ode.u.shape[0] == 3
    assert crane_ode(False, bridge=True).states == ('y', 'v', 'a', 'yb', 'vb', 'ab', *SPATIAL_SWING_STATES)


def test_crane_ode_with_a_bridge_and_hoist_is_the_spatial_swing_driven_by_its_axes():
    rng = np.random.default_rng(3)
    p = P.replace(tau=0.02, tau_hoist=0.05)
    ode = crane_ode(True, hoist=True, hoist_servo=True, bridge=True)
    f = ode.function()
    for _ in range(20):
        x = rng.uniform(-0.5, 0.5, len(ode.states))
        u = rng.uniform(-10, 10, 3)
        s = dict(zip(ode.states, x))
        xdot = dict(zip(ode.states, np.array(f(x, u, pvec(p))).ravel()))
        for (y, v, a, a_ref), tau, uk in ((('y', 'v', 'a', 'a_ref'), p.tau, u[0]), (BRIDGE_STATES, p.tau, u[1]),
                                          (('h', 'hv', 'ha', 'ha_ref'), p.tau_hoist, u[2])):
            assert xdot[y] == s[v] and xdot[v] == s[a] and xdot[a_ref] == uk
            assert np.isclose(xdot[a], (s[a_ref] - s[a]) / tau, rtol=1e-14)
        swing = spatial(*(s[n] for n in SPATIAL_SWING_STATES), s['a'], s['ab'], p.L1 + s['h'], s['hv'], s['ha'],
                        p.L2, p.m1, p.m2, p.c1, p.c2)
        np.testing.assert_allclose([xdot[n] for n in SPATIAL_SWING_STATES],
                                   [*(s[n] for n in SPATIAL_SWING_STATES[4:]), *swing], rtol=1e-12, atol=1e-12)


def test_the_sensitivities_of_the_spatial_crane_are_its_four_angles_and_rates():
    ode = crane_ode(False, bridge=True)
    assert sensitivity_states(ode, 'L1') == SPATIAL_SWING_STATES
    assert sensitivity_states(crane_ode(True, bridge=True), 'tau') == ('a', 'ab')
    assert augment(ode, ('L1', 'L2')).robust == ('L1',)
