"""Quintic Hermite interpolation of trajectory knots (crane_planner.streaming.hermite)."""
import numpy as np
import pytest
from numpy.polynomial import Polynomial

from crane_planner.streaming.hermite import QuinticHermite


def knots_of(poly, t):
    return t, poly(t), poly.deriv(1)(t), poly.deriv(2)(t)


def test_exact_on_a_quintic_with_irregular_knots():
    rng = np.random.default_rng(3)
    poly = Polynomial(rng.normal(size=6))
    t = np.cumsum(rng.uniform(0.05, 0.4, size=12)) - 0.3
    interp = QuinticHermite(*knots_of(poly, t))
    tq = np.linspace(t[0], t[-1], 2001)
    p, v, a = interp(tq)
    scale = np.abs(poly(tq)).max()
    assert np.allclose(p, poly(tq), atol=1e-11 * scale)
    assert np.allclose(v, poly.deriv(1)(tq), atol=1e-9 * scale)
    assert np.allclose(a, poly.deriv(2)(tq), atol=1e-7 * scale)


def test_knots_are_matched_and_sixth_order_convergence_on_a_smooth_function():
    def err(h):
        t = np.arange(0.0, 2.0 + h / 2, h)
        interp = QuinticHermite(t, np.sin(3 * t), 3 * np.cos(3 * t), -9 * np.sin(3 * t))
        p, v, a = interp(t)
        assert np.allclose(p, np.sin(3 * t), atol=1e-14)
        assert np.allclose(a, -9 * np.sin(3 * t), atol=1e-12)
        tq = np.linspace(0.0, t[-1], 5001)
        return np.abs(interp(tq)[0] - np.sin(3 * tq)).max()

    e1, e2 = err(0.1), err(0.05)
    # quintic Hermite error is O(h^6): halving h divides it by about 2^6 = 64
    assert 40.0 < e1 / e2 < 90.0


def test_end_states_are_held_outside_the_knots():
    interp = QuinticHermite([0.0, 1.0], [0.2, 0.5], [0.0, 0.0], [0.0, 0.0])
    p, v, a = interp([-1.0, 2.0, 5.0])
    assert p.tolist() == [0.2, 0.5, 0.5] and v.tolist() == [0.0] * 3 and a.tolist() == [0.0] * 3
    single = QuinticHermite([0.0], [0.7], [0.0], [0.0])
    assert single([0.0, 3.0])[0].tolist() == [0.7, 0.7]


def test_rest_to_rest_quintic_matches_closed_form_between_two_knots():
    # D (10 s^3 - 15 s^4 + 6 s^5), s = t/T: two knots at rest reproduce it exactly.
    D, T = 0.3, 1.789
    interp = QuinticHermite([0.0, T], [0.0, D], [0.0, 0.0], [0.0, 0.0])
    t = np.linspace(0.0, T, 101)
    s = t / T
    assert np.allclose(interp(t)[0], D * (10 * s**3 - 15 * s**4 + 6 * s**5), atol=1e-15)
    assert np.isclose(interp(T / 2)[1][0], 1.875 * D / T)  # the quintic's peak velocity


@pytest.mark.parametrize('t, p', [([0.0, 0.0], [0.0, 1.0]), ([0.0, 1.0], [0.0, np.nan]), ([], [])])
def test_bad_knots_are_refused(t, p):
    with pytest.raises(ValueError):
        QuinticHermite(t, p, np.zeros(len(p)), np.zeros(len(p)))
