"""crane_msgs_py.crane.braking: the closed-form jerk-limited stop against ruckig, closed forms of its own, and its
properties (it ends at rest, within its limits, and without a velocity reversal from a0 = 0)."""
import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from crane_msgs_py.crane.braking import Braking, stopping_distance
from crane_msgs_py.crane.params import ParameterError


def ruckig_stop(v0: float, a0: float, D: float, J: float):
    """ruckig's time-optimal trajectory to v = 0, a = 0 (its velocity interface) within |a| <= D, |jerk| <= J:
    the independent reference."""
    from ruckig import ControlInterface, InputParameter, Result, Ruckig, Trajectory
    inp = InputParameter(1)
    inp.control_interface = ControlInterface.Velocity
    inp.current_position, inp.current_velocity, inp.current_acceleration = [0.0], [v0], [a0]
    inp.target_velocity, inp.target_acceleration = [0.0], [0.0]
    inp.max_velocity, inp.max_acceleration, inp.max_jerk = [1e9], [D], [J]
    trajectory = Trajectory(1)
    assert Ruckig(1).calculate(inp, trajectory) in (Result.Working, Result.Finished)
    return trajectory


def assert_matches_ruckig(v0, a0, D, J, tol=1e-6):
    braking, reference = Braking(v0, a0, D, J), ruckig_stop(v0, a0, D, J)
    assert braking.duration == pytest.approx(reference.duration, abs=tol)
    assert braking.distance == pytest.approx(reference.at_time(reference.duration)[0][0], abs=tol)
    assert stopping_distance(v0, a0, D, J) == braking.distance
    for fraction in (0.0, 0.13, 0.5, 0.77, 0.999):  # the whole profile, not only its end
        t = fraction * braking.duration
        p, v, a = (x[0] for x in reference.at_time(t))
        assert braking.state(t) == pytest.approx((p, v, a), abs=tol), (fraction, braking.phases)


#: (v0 m/s, a0 m/s^2, D m/s^2, J m/s^3) covering every phase structure
CASES = {
    'D reached, a0 = 0': (0.33, 0.0, 0.5, 5.0),
    'short stop: triangular jerk': (0.02, 0.0, 0.5, 5.0),
    'moving backwards': (-0.3, 0.0, 0.5, 5.0),
    'a0 along the motion': (0.3, 0.2, 0.5, 5.0),
    'a0 already braking': (0.3, -0.3, 0.5, 5.0),
    'a0 braking, overshoots unless released': (0.01, -0.4, 0.5, 5.0),
    'a0 beyond D along the motion': (0.3, 0.9, 0.5, 5.0),
    'a0 beyond D against the motion': (0.6, -1.2, 0.5, 5.0),
    'a0 beyond D, overshoots': (0.05, -1.2, 0.5, 5.0),
    'v0 = 0, a0 > 0': (0.0, 0.3, 0.5, 5.0),
    'v0 = 0, a0 < 0 beyond D': (0.0, -0.8, 0.5, 5.0),
    'a0 ramps exactly to rest': (-0.3 ** 2 / 10.0, 0.3, 0.5, 5.0),
    'at rest': (0.0, 0.0, 0.5, 5.0),
    'a hoist': (-0.2, 0.05, 0.3, 2.0),
}


@pytest.mark.parametrize('v0, a0, D, J', CASES.values(), ids=CASES.keys())
def test_the_stop_is_ruckigs(v0, a0, D, J):
    assert_matches_ruckig(v0, a0, D, J)


@settings(max_examples=300, deadline=None)
@given(st.floats(-3.0, 3.0), st.floats(-4.0, 4.0), st.floats(0.05, 3.0), st.floats(0.2, 50.0))
def test_the_stop_is_ruckigs_from_any_state(v0, a0, D, J):
    assert_matches_ruckig(v0, a0, D, J)


def test_closed_forms_from_a0_0():
    """From (v0, 0): D reached after v0 > D^2 / J, the stop lasting v0 / D + D / J with the mean velocity
    v0 / 2 (its profile is point-symmetric); a shorter one lasts 2 sqrt(v0 / J) and travels v0 sqrt(v0 / J)."""
    v0, D, J = 0.33, 0.5, 5.0
    braking = Braking(v0, 0.0, D, J)
    assert braking.duration == pytest.approx(v0 / D + D / J, rel=1e-12)
    assert braking.distance == pytest.approx(v0 * (v0 / D + D / J) / 2.0, rel=1e-12)
    assert [p.jerk for p in braking.phases] == [-J, 0.0, J]
    v0 = 0.02  # < D^2 / J = 0.05: D never reached
    braking = Braking(v0, 0.0, D, J)
    assert braking.duration == pytest.approx(2.0 * math.sqrt(v0 / J), rel=1e-12)
    assert braking.distance == pytest.approx(v0 * math.sqrt(v0 / J), rel=1e-12)
    assert [p.jerk for p in braking.phases] == [-J, J]
    assert max(abs(braking.acceleration(t)) for t in (0.5 * braking.duration, braking.duration)) < D


def test_a0_beyond_D_is_first_brought_to_D_at_the_jerk_limit():
    braking = Braking(0.6, -1.2, 0.5, 5.0)  # braking harder than D: eased off to D first
    first = braking.phases[0]
    assert first.jerk == 5.0 and first.duration == pytest.approx(0.7 / 5.0, rel=1e-12)
    assert braking.acceleration(first.duration) == pytest.approx(-0.5, abs=1e-12)
    braking = Braking(0.3, 0.9, 0.5, 5.0)  # accelerating harder than D: the jerk limit takes it down through D
    assert braking.phases[0].jerk == -5.0
    assert braking.acceleration(0.4 / 5.0) == pytest.approx(0.5, abs=1e-12)


def test_mirrored_states_brake_mirrored():
    for v0, a0, D, J in CASES.values():
        forward, backward = Braking(v0, a0, D, J), Braking(-v0, -a0, D, J)
        assert backward.duration == pytest.approx(forward.duration, abs=1e-15)
        assert backward.distance == pytest.approx(-forward.distance, abs=1e-15)


def test_at_rest_nothing_happens_and_after_the_end_it_rests():
    braking = Braking(0.0, 0.0, 0.5, 5.0)
    assert braking.duration == 0.0 and braking.phases == () and braking.state(1.0) == (0.0, 0.0, 0.0)
    braking = Braking(0.3, 0.1, 0.5, 5.0)
    assert braking.state(braking.duration + 10.0) == (braking.distance, 0.0, 0.0)


@pytest.mark.parametrize('args, name', [((math.nan, 0.0, 0.5, 5.0), 'v0'), ((0.1, math.inf, 0.5, 5.0), 'a0'),
                                        ((0.1, 0.0, 0.0, 5.0), 'D'), ((0.1, 0.0, 0.5, -1.0), 'J'),
                                        ((0.1, 0.0, 0.5, math.inf), 'J')])
def test_bad_arguments_are_named(args, name):
    with pytest.raises(ParameterError, match=name):
        Braking(*args)
    with pytest.raises(ParameterError):
        Braking(0.1, 0.0, 0.5, 5.0).state(-1e-3)


states = dict(v0=st.floats(-3.0, 3.0), a0=st.floats(-4.0, 4.0), D=st.floats(0.05, 3.0), J=st.floats(0.2, 50.0))


@settings(max_examples=300, deadline=None)
@given(**states)
def test_it_ends_at_rest_continuously(v0, a0, D, J):
    """The phases chain continuously and the last one ends at v = 0, a = 0 by itself (not only by the rest
    that ``state`` returns after the end)."""
    braking = Braking(v0, a0, D, J)
    scale = abs(v0) + a0 * a0 / J + D * D / J  # of the velocities involved
    state = (0.0, v0, a0)
    for phase in braking.phases:
        assert (phase.position, phase.velocity, phase.acceleration) == pytest.approx(state, abs=1e-12 * (1 + scale))
        state = phase.at(phase.duration)
    _, v_end, a_end = state
    assert abs(v_end) <= 1e-9 * (1 + scale) and abs(a_end) <= 1e-9 * (1 + abs(a0) + D)


@settings(max_examples=300, deadline=None)
@given(**states)
def test_limits_are_never_exceeded(v0, a0, D, J):
    """|jerk| <= J in every phase; |a| <= D from the end of the first phase on, and never above max(D, |a0|)
    (beyond D at the start, |a| only comes down)."""
    braking = Braking(v0, a0, D, J)
    assert all(abs(p.jerk) <= J for p in braking.phases)
    bound = max(D, abs(a0)) * (1 + 1e-12)
    for phase in braking.phases:
        for f in (0.0, 0.25, 0.5, 0.75, 1.0):
            a = abs(phase.at(f * phase.duration)[2])
            assert a <= bound
            if phase is not braking.phases[0]:
                assert a <= D * (1 + 1e-12)
    if abs(a0) > D:  # the first phase's jerk opposes a0: |a| falls at the jerk limit from the start
        assert braking.phases[0].jerk == -math.copysign(J, a0)


@settings(max_examples=300, deadline=None)
@given(st.floats(-3.0, 3.0), st.floats(0.05, 3.0), st.floats(0.2, 50.0))
def test_from_a0_0_the_velocity_goes_monotonically_to_0(v0, D, J):
    braking = Braking(v0, 0.0, D, J)
    times = [braking.duration * k / 200 for k in range(201)]
    speeds = [braking.velocity(t) * math.copysign(1.0, v0) for t in times]
    assert all(s >= -1e-12 for s in speeds)  # never reverses
    assert all(b <= a + 1e-12 for a, b in zip(speeds, speeds[1:]))  # and only slows down
    assert braking.distance * v0 >= 0.0
