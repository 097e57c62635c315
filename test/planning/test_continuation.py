"""Motion from any state (planning.continuation): every plan is checked on crane_sim's independent numpy
crane (Eqs. 18-19 + servo), run through the old plan up to the handover and the new one after it."""
import math

import numpy as np
import pytest

from crane_msgs_py.crane.params import CraneParams
from crane_msgs_py.messages.names import CART_JOINT, HOIST_JOINT
from crane_planner.planning.continuation import (
    AxisState,
    Continuation,
    MotionState,
    braking_time,
    first_period,
    predict,
    problem_start,
    shaped_change,
    shaped_stop,
)
from crane_planner.planning.dispatch import PlanOptions, SolverCache, VariationalRequest, hoisting_options, plan
from crane_planner.planning.plan import PlanError
from crane_planner.planning.signals import Swing
from crane_sim.simulator import simulate

PARAMS = CraneParams()  # the paper's crane, tau = 10 ms
DT = 1e-3
HANDOVER = 1.2  # s: 40 % of a 3 s move


@pytest.fixture(scope='module')
def solvers():
    return SolverCache()


@pytest.fixture(scope='module')
def running(solvers):
    return plan('nvf', 0.3, 3.0, PARAMS, variational=solvers)


def measured_at(old, t_h, params=PARAMS, hoist=None):
    """The simulated crane at ``t_h`` under ``old`` (a MotionState, from the independent simulator)."""
    t = np.arange(0.0, t_h + 1e-9, DT)
    if hoist is None:
        s = old.evaluate(t)
        r = simulate(t, s.acceleration, params)
        cart = AxisState(s.position[-1], s.velocity[-1], s.acceleration[-1], r.y[0, -1] - s.position[-1])
        return MotionState({CART_JOINT: cart},
                           Swing(r.theta1[0, -1], r.theta2[0, -1], r.dtheta1[0, -1], r.dtheta2[0, -1]))
    c, h = old.axes['cart'].evaluate(t), old.axes['hoist'].evaluate(t)
    r = simulate(t, {'cart': c.acceleration, 'hoist': h.acceleration}, params)
    L = hoist + h.position[-1]
    return MotionState({CART_JOINT: AxisState(c.position[-1], c.velocity[-1], c.acceleration[-1],
                                              r.y[0, -1] - c.position[-1]),
                        HOIST_JOINT: AxisState(L, h.velocity[-1], h.acceleration[-1], r.L1[0, -1] - L)},
                       Swing(r.theta1[0, -1], r.theta2[0, -1], r.dtheta1[0, -1], r.dtheta2[0, -1]))


def handed_over(old, new, t_h, params=PARAMS, settle=4.0):
    """(residual m, simulation) of ``old`` until ``t_h`` then ``new``: peak load excursion after new's end."""
    t1 = np.arange(0.0, t_h + 1e-9, DT)
    t2 = np.arange(0.0, new.duration + settle, DT)
    a = np.concatenate([old.evaluate(t1).acceleration, new.evaluate(t2).acceleration[1:]])
    t = np.concatenate([t1, t_h + t2[1:]])
    r = simulate(t, a, params)
    return float(np.abs(r.load_excursion[0, t > t_h + new.duration]).max()), r


def assert_continuous(old, new, t_h):
    """The new plan starts exactly on the old reference: position (relative 0), velocity, acceleration."""
    o, n = old.evaluate(t_h), new.evaluate(0.0)
    assert n.position[0] == pytest.approx(0.0, abs=1e-12)
    assert n.velocity[0] == pytest.approx(o.velocity[0], abs=1e-9)
    assert n.acceleration[0] == pytest.approx(o.acceleration[0], abs=1e-8)


def test_unshaped_hard_stop_leaves_a_swing_the_comparisons_are_against(running):
    """The reference the stops below are measured against: holding the position at 40 % leaves ~cm."""
    t = np.arange(0.0, HANDOVER + 5.0, DT)
    p = np.where(t <= HANDOVER, running.evaluate(np.minimum(t, HANDOVER)).position, running.evaluate(HANDOVER).position)
    r = simulate(t, p, PARAMS, source='position')
    assert np.abs(r.load_excursion[0, t > HANDOVER + 1.0]).max() > 0.02


@pytest.mark.parametrize('method', ['nvf', 'rvf'])
def test_retarget_from_the_measured_state_ends_at_the_new_goal_without_swing(solvers, running, method):
    state = measured_at(running, HANDOVER)
    start, model = problem_start(state, PARAMS)
    cart = state.axis(CART_JOINT)
    new = solvers(VariationalRequest('plan', method, 0.5 - cart.position, 3.0, model, PlanOptions(), start))
    assert_continuous(running, new, HANDOVER)
    assert cart.position + new.displacement == pytest.approx(0.5, abs=1e-9)
    end = new.evaluate(new.duration)
    assert abs(end.velocity[0]) < 1e-9 and abs(end.acceleration[0]) < 1e-8
    residual, r = handed_over(running, new, HANDOVER)
    assert residual < 0.5e-4  # 0.05 mm: ten times inside the must-hold
    assert r.y[0, -1] == pytest.approx(0.5, abs=1e-5)


def test_stop_rests_anywhere_without_swing_and_plans_from_a_swinging_state(solvers, running):
    state = measured_at(running, 1.5)
    assert max(abs(x) for x in state.swing.values()) > 0.01  # mid-move the load swings
    start, model = problem_start(state, PARAMS)
    T = first_period(PARAMS)
    cart = state.axis(CART_JOINT)
    stop = solvers(VariationalRequest('plan', 'nvf', cart.velocity * T / 2, T, model, PlanOptions(), start,
                                      free_end=True))
    assert_continuous(running, stop, 1.5)
    end = stop.evaluate(T)
    assert abs(end.velocity[0]) < 1e-9 and abs(end.acceleration[0]) < 1e-8
    assert 0.0 < stop.displacement < cart.velocity * T  # it brakes: less than the speed would carry it
    residual, r = handed_over(running, stop, 1.5)
    assert residual < 0.5e-4
    assert r.y[0, -1] == pytest.approx(cart.position + stop.displacement, abs=1e-5)


def test_settle_damps_a_swing_and_ends_where_it_started(solvers):
    """A load swinging 30 mm at rest: the NVF plan from that state to the same place damps it below 1 mm."""
    # the swing of a free first-mode oscillation with 30 mm at the load
    theta = 0.03 / (PARAMS.L1 + PARAMS.L2)
    state = MotionState({CART_JOINT: AxisState()}, Swing(theta1=theta))
    start, model = problem_start(state, PARAMS)
    T = first_period(PARAMS)
    settle = solvers(VariationalRequest('plan', 'nvf', 0.0, T, model, PlanOptions(), start))
    assert settle.displacement == 0.0 and settle.evaluate(T).position[0] == pytest.approx(0.0, abs=1e-9)
    t = np.arange(0.0, T + 4.0, DT)
    x0 = np.array([0.0, 0.0, 0.0, theta, 0.0, 0.0, 0.0])
    r = simulate(t, settle.evaluate(t).acceleration, PARAMS, initial_state=x0)
    free = simulate(t, np.zeros_like(t), PARAMS, initial_state=x0)
    assert np.abs(free.load_excursion[0, t > T]).max() > 0.025  # left alone it keeps swinging
    assert np.abs(r.load_excursion[0, t > T]).max() < 1e-3 * 0.05


def test_hoisting_from_a_state_both_axes_continuous_and_at_rest(solvers):
    hoisting = plan('nvf', 0.3, 3.0, PARAMS, variational=solvers, hoist=(0.47, 0.3))
    state = measured_at(hoisting, HANDOVER, hoist=0.47)
    start, model = problem_start(state, PARAMS)
    rope = state.axis(HOIST_JOINT)
    assert model.L1 == pytest.approx(rope.position + rope.lag)
    new = solvers(VariationalRequest('plan', 'nvf', (0.5 - state.axis(CART_JOINT).position, 0.25 - model.L1), 3.0,
                                     model, hoisting_options(PlanOptions()), start))
    h0 = new.evaluate_axis('hoist', 0.0)
    assert h0.position[0] == pytest.approx(rope.position, abs=1e-12)
    assert h0.velocity[0] == pytest.approx(rope.velocity, abs=1e-9)
    assert new.evaluate_axis('hoist', new.duration).position[0] == pytest.approx(0.25, abs=1e-9)
    t1 = np.arange(0.0, HANDOVER + 1e-9, DT)
    t2 = np.arange(0.0, new.duration + 4.0, DT)
    c = np.concatenate([hoisting.axes['cart'].evaluate(t1).acceleration,
                        new.axes['cart'].evaluate(t2).acceleration[1:]])
    h = np.concatenate([hoisting.axes['hoist'].evaluate(t1).acceleration,
                        new.axes['hoist'].evaluate(t2).acceleration[1:]])
    t = np.concatenate([t1, HANDOVER + t2[1:]])
    r = simulate(t, {'cart': c, 'hoist': h}, PARAMS)
    assert r.L1[0, -1] == pytest.approx(0.25, abs=1e-5)
    assert np.abs(r.load_excursion[0, t > HANDOVER + new.duration]).max() < 0.5e-4


def test_predict_carries_a_measurement_to_the_handover_like_the_independent_simulator(running):
    t_m = HANDOVER - 0.06
    measured = measured_at(running, t_m)
    truth = measured_at(running, HANDOVER)

    def reference(t):
        s = running.evaluate(t)
        return [(s.position, s.velocity, s.acceleration, s.jerk)]

    predicted = predict(measured, reference, t_m, HANDOVER, PARAMS)
    p, q = predicted.axis(CART_JOINT), truth.axis(CART_JOINT)
    assert (p.position, p.velocity, p.acceleration) == pytest.approx((q.position, q.velocity, q.acceleration),
                                                                     abs=1e-12)
    # the simulator takes the reference sampled every ms (linear between): agreement to its error
    assert predicted.swing.values() == pytest.approx(truth.swing.values(), abs=5e-5)
    assert p.lag == pytest.approx(q.lag, abs=1e-6)
    # without prediction the swing 60 ms earlier is far off: the prediction is doing the work
    assert max(abs(a - b) for a, b in zip(measured.swing.values(), truth.swing.values())) > 1e-3


def test_servo_start_is_steady_tracking_by_default():
    state = MotionState({CART_JOINT: AxisState(0.1, 0.2, 0.3)})
    start, _ = problem_start(state, PARAMS)
    tau = PARAMS.tau
    # the model's reference y + tau v, v + tau a, a_ref is the state's reference
    assert start['y'] + tau * start['v'] == pytest.approx(0.0, abs=1e-15)
    assert start['v'] + tau * start['a'] == pytest.approx(0.2)
    assert start['a_ref'] == 0.3 and start['a'] == pytest.approx(0.3)
    start, _ = problem_start(state, PARAMS.replace(tau=0.0))
    assert (start['y'], start['v'], start['a']) == (0.0, 0.2, 0.3)


def test_bad_states_are_refused():
    with pytest.raises(PlanError, match='finite'):
        MotionState({CART_JOINT: AxisState(0.0, math.nan, 0.0)})
    with pytest.raises(PlanError, match='finite'):
        AxisState(0.0, 0.0, 0.0, math.inf)
    with pytest.raises(PlanError, match='swing'):
        MotionState({CART_JOINT: AxisState()}, (0.0, 0.0))
    with pytest.raises(PlanError, match=f'needs the {CART_JOINT}'):
        MotionState({HOIST_JOINT: AxisState(0.5)})
    with pytest.raises(PlanError, match=f'no {HOIST_JOINT} axis'):
        MotionState().axis(HOIST_JOINT)
    with pytest.raises(PlanError, match='rope length'):
        problem_start(MotionState({CART_JOINT: AxisState(), HOIST_JOINT: AxisState(-0.1)}), PARAMS)
    assert MotionState().at_rest and not MotionState({CART_JOINT: AxisState(0.0, 1e-3, 0.0)}).at_rest
    assert not MotionState({CART_JOINT: AxisState(), HOIST_JOINT: AxisState(0.5, 0.0, 1e-3)}).at_rest
    # the axes kept in the registry's order, whatever order they were given in
    state = MotionState({HOIST_JOINT: AxisState(0.5), CART_JOINT: AxisState()})
    assert tuple(state.axes) == (CART_JOINT, HOIST_JOINT) and state.has(HOIST_JOINT)


def test_the_indirect_route_refuses_a_moving_start():
    start, model = problem_start(MotionState({CART_JOINT: AxisState(0.0, 0.1)}), PARAMS)
    with pytest.raises(PlanError, match='direct solver'):
        SolverCache()(VariationalRequest('plan', 'nvf', 0.2, 3.0, model, PlanOptions(solver='indirect'), start))


# -- shapers: shaping the change -------------------------------------------------------------------


@pytest.fixture(scope='module')
def zv_running():
    return plan('zv', 0.3, 3.0, PARAMS)


def test_shaped_change_retargets_without_a_step_or_swing(zv_running):
    new = shaped_change(lambda d, T: plan('zv', d, T, PARAMS), zv_running, HANDOVER, 0.2, 3.0)
    assert isinstance(new, Continuation) and new.duration == pytest.approx(3.0)
    assert_continuous(zv_running, new, HANDOVER)
    assert zv_running.evaluate(HANDOVER).position[0] + new.displacement == pytest.approx(0.5, abs=1e-12)
    residual, r = handed_over(zv_running, new, HANDOVER)
    assert residual < 0.5e-4
    assert r.y[0, -1] == pytest.approx(0.5, abs=1e-5)


def test_a_shaped_change_also_continues_a_variational_plan(running):
    """Linear superposition: the NVF reference continued plus a ZV-shaped change leaves no swing either."""
    new = shaped_change(lambda d, T: plan('zv', d, T, PARAMS), running, HANDOVER, 0.2, 3.0)
    assert_continuous(running, new, HANDOVER)
    residual, _ = handed_over(running, new, HANDOVER)
    assert residual < 0.5e-4


def test_shaped_stop_brakes_the_base_within_the_limits_and_leaves_no_swing(zv_running):
    stopped = shaped_stop(zv_running, HANDOVER, 0.5, 5.0)
    new = Continuation.of('zv', stopped, HANDOVER, None)
    assert_continuous(zv_running, new, HANDOVER)
    _, a, j = new.peaks()
    assert a <= 0.5 + 1e-9 and j <= 5.0 + 1e-9  # the shaper's amplitudes sum to 1: never beyond the base's
    assert zv_running.evaluate(HANDOVER).position[0] + new.displacement < 0.3  # stops short of the goal
    residual, _ = handed_over(zv_running, new, HANDOVER)
    assert residual < 0.5e-4


def test_braking_time_matches_the_closed_form():
    """From v with a = 0 and no jerk limit: v / a_max; with a jerk limit: v / a_max + a_max / j_max."""
    assert braking_time(0.2, 0.0, 0.5, None) == pytest.approx(0.4, rel=1e-9)
    assert braking_time(0.2, 0.0, 0.5, 5.0) == pytest.approx(0.4 + 0.1, rel=1e-6)


def test_only_plans_from_a_state_say_so_and_a_refusal_still_probes_the_limits(solvers, running):
    """The start state is not confused with the solver's start points: a rest-to-rest plan carries no
    from_state, and an infeasible pair of limits is probed (one solve per limit) and named."""
    assert 'from_state' not in running.info
    start, model = problem_start(MotionState({CART_JOINT: AxisState(0.0, 0.1)}), PARAMS)
    assert solvers(VariationalRequest('plan', 'nvf', 0.2, 3.0, model, PlanOptions(), start)).info['from_state']
    with pytest.raises(PlanError, match='within max_acceleration 0.14 and max_jerk 0.5 .*infeasible'):
        plan('nvf', 0.3, 3.0, PARAMS, PlanOptions(max_acceleration=0.14, max_jerk=0.5), variational=SolverCache())
