"""The operator mode's core (streaming.operator): a stick shaped online, checked on crane_sim's crane."""
import math

import numpy as np
import pytest

from crane_msgs_py.crane.axes import AxisLimits
from crane_msgs_py.crane.params import CraneParams
from crane_planner.planning.plan import PlanError
from crane_planner.streaming.operator import OperatorStream
from crane_sim.simulator import simulate

PARAMS = CraneParams()
DT = 1e-3
CART = AxisLimits(0.3, 0.5, 5.0)
HOIST = AxisLimits(0.2, 0.5, 5.0)


def drive(shaper, stick, total=9.0, hoist=None, timeout=0.5, every=0.05):
    """Run an OperatorStream tick by tick with the stick ``stick(t)`` -> (cart, load up) or None (no
    message), messages every ``every`` s; (t, positions, velocities, accelerations, stream)."""
    clock = [0.0]
    start = (0.0,) if hoist is None else (0.0, hoist)
    limits = (CART,) if hoist is None else (CART, HOIST)
    op = OperatorStream(DT, start, limits, shaper, PARAMS, timeout, clock=lambda: clock[0])
    n = round(total / DT)
    out = np.zeros((3, n, len(start)))
    for k in range(n):
        t = clock[0] = k * DT
        command = stick(t)
        if command is not None and k % round(every / DT) == 0:
            op.command(command[0], -command[1])
        sample = op.sample()
        for i in range(3):
            out[i, k] = sample[i] if hoist is not None else (sample[i],)
    return np.arange(n) * DT, out[0], out[1], out[2], op


def residual_mm(t, acc, after, hoist=False):
    r = simulate(t, {'cart': acc[:, 0], 'hoist': acc[:, 1]} if hoist else acc[:, 0], PARAMS)
    return 1e3 * float(np.abs(r.load_excursion[0, t > after]).max()), r


def held(speed, seconds, load=0.0):
    return lambda t: (speed, load) if t < seconds else (0.0, 0.0)


@pytest.mark.parametrize('shaper', ['zv', 'zvd', 'ei'])
def test_a_stick_held_3_s_then_released_leaves_under_5_percent_of_the_rate_limited_swing(shaper):
    t, p, v, a, _ = drive('none', held(0.2, 3.0))
    unshaped, _ = residual_mm(t, a, 7.0)
    t, p, v, a, op = drive(shaper, held(0.2, 3.0))
    shaped, r = residual_mm(t, a, 7.0)
    assert unshaped > 10.0  # the rate limits alone leave a swing of centimetres
    assert shaped <= 0.05 * unshaped, (shaped, unshaped)
    assert p[-1, 0] == pytest.approx(0.6, abs=1e-9)  # 0.2 m/s for 3 s, wherever it is shaped
    assert np.abs(v).max() <= CART.max_velocity + 1e-9 and np.abs(a).max() <= CART.max_acceleration + 1e-9
    assert op.at_rest


def test_a_lost_stick_counts_as_zero_after_the_timeout_and_stops_without_swing():
    def lost(t):
        return (0.2, 0.0) if t < 1.5 else None  # the messages stop mid-travel

    t, p, v, a, op = drive('zv', lost, total=7.0)
    cut_t, cut_p, cut_v, cut_a, _ = drive('none', lost, total=7.0)
    shaped, _ = residual_mm(t, a, 5.0)
    unshaped, _ = residual_mm(cut_t, cut_a, 5.0)
    assert shaped <= 0.05 * unshaped
    # braking starts once the last command is cmd_timeout old, and ends within ruckig's braking plus the shaper
    last_message = 1.45
    moving = np.nonzero(np.abs(v[:, 0]) > 1e-9)[0]
    stopped_at = t[moving[-1]] + DT
    braking = 0.2 / CART.max_acceleration + CART.max_acceleration / CART.max_jerk
    assert stopped_at <= last_message + 0.5 + braking + op.delay() + 2 * DT
    assert stopped_at > last_message + 0.5  # not before the timeout


def test_the_reference_changes_on_the_tick_after_the_command():
    clock = [0.0]
    op = OperatorStream(DT, (0.0,), (CART,), 'zv', PARAMS, clock=lambda: clock[0])
    for _ in range(10):
        assert op.sample() == (0.0, 0.0, 0.0)
    op.command(0.2)
    p, v, a = op.sample()
    assert a > 0.0 and v > 0.0  # the first impulse of ZV is at 0: no delay beyond the tick


def test_hoisting_while_travelling_the_shaper_follows_the_rope():
    stick = held(0.2, 3.0, load=0.1)  # forward, lifting 0.1 m/s
    t, p, v, a, _ = drive('none', stick, hoist=0.47)
    unshaped, _ = residual_mm(t, a, 7.0, hoist=True)
    t, p, v, a, op = drive('zv', stick, hoist=0.47)
    adaptive, r = residual_mm(t, a, 7.0, hoist=True)
    assert p[-1, 1] == pytest.approx(0.17, abs=1e-6)  # the rope 0.3 m shorter (lifted)
    assert r.L1[0, -1] == pytest.approx(0.17, abs=1e-3)  # the sim's rope, through its servo
    assert adaptive <= 0.15 * unshaped, (adaptive, unshaped)
    # designed at the start length alone (a fixed shaper) it is worse than following the rope
    fixed = OperatorStream(DT, (0.0, 0.47), (CART, HOIST), 'zv', PARAMS)
    fixed._redesign = lambda length: None  # never redesigned
    clock = [0.0]
    fixed.clock = lambda: clock[0]
    acc = np.zeros((t.size, 2))
    for k in range(t.size):
        clock[0] = t[k]
        if k % 50 == 0:
            c = stick(t[k])
            fixed.command(c[0], -c[1])
        acc[k] = fixed.sample()[2]
    fixed_residual, _ = residual_mm(t, acc, 7.0, hoist=True)
    assert adaptive < 0.5 * fixed_residual, (adaptive, fixed_residual)


def test_the_hoist_stops_short_of_its_range():
    t, p, v, a, _ = drive('zv', held(0.0, 5.0, load=0.2), hoist=0.47)
    assert p[:, 1].min() >= 0.05 - 1e-9 and p[-1, 1] < 0.1  # lifted to the shortest rope, not past it


def test_operator_limits_must_be_finite_and_positive():
    with pytest.raises(PlanError, match='operator mode needs a finite max_velocity'):
        OperatorStream(DT, (0.0,), (AxisLimits(math.inf, 1.0),), 'zv', PARAMS)
    with pytest.raises(PlanError, match='operator mode needs a finite max_hoist_acceleration'):
        OperatorStream(DT, (0.0, 0.47), (CART, AxisLimits(1.0, 0.0)), 'zv', PARAMS)
    with pytest.raises(ValueError, match='max_jerk must be > 0'):
        AxisLimits(1.0, 1.0, -1.0)
    with pytest.raises(PlanError, match='operator_shaper'):
        OperatorStream(DT, (0.0,), (CART,), 'fast', PARAMS)


def test_a_diagonal_stick_with_a_bridge_is_shaped_on_both_travel_axes_and_leaves_no_swing():
    """cmd_vel linear.x and linear.y to the cart and the bridge, both shaped: released after 2 s, the load (on
    crane_sim's spatial crane) swings less than 2 mm, where the rate limits alone leave centimetres."""
    from types import SimpleNamespace

    from crane_planner.streaming.operator import twist_velocities
    from crane_sim.simulator import CraneSimulator
    twist = SimpleNamespace(linear=SimpleNamespace(x=0.2, y=-0.15, z=0.1))
    assert twist_velocities(twist, ('cart', 'bridge', 'hoist')) == (0.2, -0.15, -0.1)

    def run(shaper):
        clock = [0.0]
        op = OperatorStream(DT, (0.1, -0.2), (CART, CART), shaper, PARAMS, clock=lambda: clock[0],
                            joints=('cart', 'bridge'))
        sim = CraneSimulator(PARAMS, dt=DT, axes=('cart', 'bridge'))
        sim.reset()
        swing, previous = [], None
        for k in range(round(8.0 / DT)):
            clock[0] = k * DT
            if k % 50 == 0 and k * DT < 2.0:
                op.command(*twist_velocities(twist, op.joints))
            p, v, a = op.sample()
            if previous is not None:
                sim.step(previous, a)
            previous = a
            swing.append(sim.load_excursion)
        return 1e3 * max(swing[round(6.0 / DT):]), p, op

    unshaped, _, _ = run('none')
    shaped, p, op = run('zv')
    assert unshaped > 10.0 and shaped < 2.0, (shaped, unshaped)
    # each axis at its commanded speed from the first command to the last one's timeout (1.95 + 0.5 s)
    assert p == pytest.approx((0.1 + 0.2 * 2.45, -0.2 - 0.15 * 2.45), abs=1e-6) and op.at_rest
