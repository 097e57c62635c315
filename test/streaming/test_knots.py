"""Knots of returned plans (crane_planner.streaming.knots): few, and exact under the streamer's interpolation.

The reference is each plan's own dense evaluation (``Plan.evaluate``): the
streamer's quintic Hermite interpolation of the knots must stay within 1 um in
position and 0.1 % of the plan's peak acceleration of it, for every method.
"""
import math

import numpy as np
import pytest

from crane_msgs_py.crane.params import CraneParams
from crane_planner.planning import METHODS, SHAPER_METHODS
from crane_planner.planning.model import modal_frequencies
from crane_planner.planning.plan import Plan
from crane_planner.planning.shaped import shaped_plan
from crane_planner.serving import Planner
from crane_planner.streaming.hermite import QuinticHermite
from crane_planner.streaming.knots import knot_times

REQUESTS = [(0.3, 3.0, 0.01), (-0.6, 2.6, 0.05), (1.0, 8.0, 0.0), (0.05, 5.0, 0.01)]


@pytest.fixture(scope='module')
def planner():
    return Planner()


def interpolation_error(plan, t):
    """Largest position error (m) and acceleration error (fraction of the peak) of the
    Hermite interpolant of the knots ``t`` against 200 001 exact samples."""
    k = plan.evaluate(t)
    dense = np.linspace(0.0, plan.duration, 200_001)
    exact = plan.evaluate(dense)
    p, _, a = QuinticHermite(t, k.position, k.velocity, k.acceleration)(dense)
    peak = np.max(np.abs(exact.acceleration))
    return np.max(np.abs(p - exact.position)), np.max(np.abs(a - exact.acceleration)) / peak


@pytest.mark.parametrize('method', METHODS)
@pytest.mark.parametrize('displacement, duration, tau', REQUESTS)
def test_knots_reproduce_the_plan_within_1um_and_0p1_percent(planner, method, displacement, duration, tau):
    try:
        plan = planner.plan(method, displacement, duration, CraneParams(tau=tau))
    except ValueError as exc:  # a shaper longer than the duration
        assert 'longer than its shaper' in str(exc)
        return
    t = knot_times(plan)
    assert t[0] == 0.0 and t[-1] == duration and np.all(np.diff(t) > 0.0)
    assert np.max(np.abs(t * 1e9 - np.rint(t * 1e9))) < 1e-3  # on the nanosecond grid of ROS stamps
    breaks = plan.breakpoints()
    assert np.all(np.min(np.abs(breaks[:, None] - t[None, :]), axis=1) <= 0.5e-9)  # every breakpoint a knot
    dp, da = interpolation_error(plan, t)
    assert dp <= 1e-6 and da <= 1e-3, (dp, da)
    if method in SHAPER_METHODS:  # a quintic between breakpoints: nothing else needed
        assert len(t) == len(breaks)
        assert dp < 1e-9
    else:
        assert len(t) <= 2 * len(breaks)  # about one knot per collocation interval
    assert len(t) < duration / 0.01 / 4  # far fewer than 10 ms knots


class SineStep(Plan):
    """A rest-to-rest cycloid D (s - sin(2 pi s) / 2 pi), s = t / T: not a polynomial anywhere."""

    def _evaluate(self, t):
        w = 2.0 * math.pi / self.duration
        D = self.displacement
        return (D * (t / self.duration - np.sin(w * t) / (2 * math.pi)), D / self.duration * (1 - np.cos(w * t)),
                D / self.duration * w * np.sin(w * t), D / self.duration * w * w * np.cos(w * t))


@pytest.mark.parametrize('tol', [1e-6, 1e-8, 1e-10])
def test_a_smooth_plan_without_breakpoints_is_refined_until_within_tolerance(tol):
    plan = SineStep('cycloid', 0.3, 3.0)
    t = knot_times(plan, position_tol=tol, acceleration_tol=1.0)
    dp, _ = interpolation_error(plan, t)
    assert dp <= tol
    # few: at most twice as many segments as the fewest uniform ones that meet the tolerance
    fewest = next(n for n in range(1, 10_000)
                  if interpolation_error(plan, np.linspace(0.0, 3.0, n + 1))[0] <= tol)
    assert len(t) - 1 <= 2 * fewest


def test_acceleration_tolerance_is_relative_to_the_peak():
    plan = SineStep('cycloid', 0.3, 3.0)
    loose = knot_times(plan, position_tol=1.0, acceleration_tol=1e-2)
    tight = knot_times(plan, position_tol=1.0, acceleration_tol=1e-4)
    assert interpolation_error(plan, loose)[1] <= 1e-2 and interpolation_error(plan, tight)[1] <= 1e-4
    assert len(tight) > len(loose)
    # the same in other units: scaling D scales nothing relative
    big = SineStep('cycloid', 300.0, 3.0)
    assert np.array_equal(knot_times(big, position_tol=1e9, acceleration_tol=1e-4), tight)


@pytest.mark.parametrize('duration', [3.0000000002, 2.9999999998, 3.0])
def test_knots_are_a_stamp_apart_when_the_duration_is_off_the_nanosecond_grid(duration):
    """The end of the last shifted base is a breakpoint at T; rounded to the nanosecond it fell just
    below an off-grid T and made a second end knot 0.2 ns before it: one stamp for two poses."""
    plan = shaped_plan('zv', 0.3, duration, modal_frequencies(CraneParams()), 0.0)
    t = knot_times(plan)
    assert t[0] == 0.0 and t[-1] == duration
    assert np.diff(t).min() >= 1e-9 * (1 - 1e-6)
    assert t.size == 8  # the breakpoints of ZV's four shifted quintics: 0, 3 inside starts, 3 inside ends, T


@pytest.mark.parametrize('off', [3e-10, -3e-10])
def test_knots_of_several_axes_are_a_stamp_apart_when_one_axis_ends_off_the_grid_at_anothers_knot(off):
    """A shaper's change of the bridge during its motion with the cart held: the held cart's plan ended at the
    running motion's end, 1.398 s off the nanosecond grid, where a knot of the bridge's lies: two knots 0.3 ns
    apart, one stamp for two poses (the handover's trajectory refused, the goal failed)."""
    from crane_planner.planning.plan import AxesPlan
    w = modal_frequencies(CraneParams())
    bridge = shaped_plan('zv', 0.3, 3.0, w, 0.0)
    breakpoint_ = float(knot_times(bridge)[3])
    cart = shaped_plan('zv', 0.0, breakpoint_ + off, w, 0.0)  # (ends off the grid, at the bridge's knot)
    plan = AxesPlan('zv', 0.0, 3.0, {}, axes={'cart': cart, 'bridge': bridge})
    t = knot_times(plan)
    assert t[0] == 0.0 and t[-1] == 3.0
    assert np.diff(np.rint(t * 1e9)).min() >= 1  # (as the message carries them: whole nanoseconds)
    assert np.isclose(t, breakpoint_, atol=1e-9).sum() == 1
