"""Quintic Hermite interpolation of trajectory knots (crane_planner.streaming.hermite)."""
import numpy as np
import pytest
from numpy.polynomial import Polynomial

from crane_planner.streaming.hermite import QuinticHermite, extends, splice


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


def _rest_to_rest(p0, p1, duration, knots):
    """A rest-to-rest quintic sampled at ``knots`` (closed form), as its Hermite interpolant."""
    s = np.asarray(knots) / duration
    d = p1 - p0
    return QuinticHermite(knots, p0 + d * s**3 * (10 - 15 * s + 6 * s * s), d / duration * 30 * s**2 * (1 - s)**2,
                          d / duration**2 * 60 * s * (1 - 3 * s + 2 * s * s))


@pytest.mark.parametrize('shift_ns', [0, 400_000, 7_000_000])
def test_a_spliced_handover_is_the_old_motion_plus_the_delayed_change_exactly(shift_ns):
    ns = 1_000_000_000
    old = _rest_to_rest(0.0, 0.3, 2.0, np.linspace(0.0, 2.0, 5))  # streamed from 10 s
    t_h = 0.83  # s into old: new continues it there (its first knot is old's state) to rest at 0.5 m
    base = _rest_to_rest(0.0, 0.2, 2.5, np.linspace(0.0, 2.5, 7))
    knots = np.union1d(np.linspace(0.0, 2.5, 7), old.t[old.t > t_h] - t_h)
    new = QuinticHermite(knots, *(x + y for x, y in zip(old(t_h + knots), base(knots))))
    at = 10 * ns + round(t_h * 1e9) + shift_ns
    joined = splice(old, 10 * ns, new, 10 * ns + round(t_h * 1e9), at)
    assert extends(old, 10 * ns, new, 10 * ns + round(t_h * 1e9))
    assert joined.t[0] == 0.0 and joined.t[-1] == pytest.approx(2.5, abs=1e-12)
    # the closed form: old at that time plus the added quintic, delayed by the shift
    tau = np.linspace(0.0, 2.5, 2001)
    t_old = t_h + shift_ns * 1e-9 + tau
    s = np.clip(tau / 2.5, 0.0, 1.0)
    exact = (np.where(t_old < 2.0, 0.3 * np.clip(t_old / 2.0, 0, 1)**3 * (10 - 15 * np.clip(t_old / 2.0, 0, 1)
                                                                         + 6 * np.clip(t_old / 2.0, 0, 1)**2), 0.3)
             + 0.2 * s**3 * (10 - 15 * s + 6 * s * s))
    assert np.abs(joined(tau)[0] - exact).max() < 1e-12
    # continuous with the old motion where it takes over, and at rest at 0.5 m at its end
    here, start = old(t_h + shift_ns * 1e-9), joined(0.0)
    for x, y in zip(here, start):
        assert y[0] == pytest.approx(x[0], abs=1e-12)
    assert [float(x[0]) for x in joined(2.5)] == pytest.approx([0.5, 0.0, 0.0], abs=1e-12)


def test_a_stop_ending_before_the_motion_does_not_extend_it():
    old = _rest_to_rest(0.0, 0.3, 2.0, np.linspace(0.0, 2.0, 5))
    stop = QuinticHermite([0.0, 0.5], [0.1, 0.15], [0.2, 0.0], [0.0, 0.0])
    assert not extends(old, 0, stop, 1_000_000_000)  # ends at 1.5 s, old at 2 s
    assert extends(old, 0, stop, 1_500_000_000)
