"""The sim's axis controller (crane_sim.axis_controller): the fault reaction to a lost reference stream.

Driven as the sim node's loop drives it: samples stamped on a 1 ms grid go
through ``offer`` into real ``ReferencePlayout``s, whose timeout declares the
stream lost; the controller's reference accelerations drive a real
``CraneSimulator`` (Eqs. 18-19 with the servo of Eq. 6). The plant's
stopping distance is checked against ``braking.stopping_distance`` (itself
checked against ruckig) plus the servo's lag.
"""
import itertools
import math

import pytest

from crane_msgs_py.crane.braking import Braking, stopping_distance
from crane_msgs_py.crane.params import CraneParams, ParameterError
from crane_sim.axis_controller import (
    FAULT_STATES,
    TRANSITIONS,
    AxisController,
    AxisState,
    FaultConfig,
    IllegalTransition,
    Offer,
    check_transition,
)
from crane_sim.playout import DRY, ReferencePlayout
from crane_sim.reference_intake import ReferenceIntake
from crane_sim.simulator import CraneSimulator

DT = 1e-3
DELAY, TIMEOUT = 0.2, 0.5
D, J = 0.5, 5.0
S = AxisState
PLANT = CraneParams()


class Rig:
    """Playouts -> controller -> plant, step by step as the sim node's loop does it; samples arrive on time
    (stamped at the step they arrive in) and are played ``DELAY`` later."""

    def __init__(self, axes=('cart',), source='acceleration', config=None, delay=DELAY, timeout=TIMEOUT):
        self.sim = CraneSimulator(PLANT, dt=DT, axes=axes)
        self.playouts = [ReferencePlayout(delay, timeout, 'zoh', source) for _ in axes]
        self.controller = AxisController(axes, self.positions(), config or FaultConfig(D, J, 1e-3, TIMEOUT))
        self.k, self.seen, self.changes, self.offers = 0, 0, [], []
        self.rows = []  # (t1, each axis's (position, velocity, acceleration) of the plant) after each step

    def positions(self):
        return [self.sim.axis_state(a)[0] for a in self.sim.axes]

    @property
    def t(self) -> float:
        return self.k * DT

    def run(self, until: float, sample=None):
        """Step up to plant time ``until`` (s); ``sample(t)``: the sample stamped t, [(position, acceleration)]
        per axis, or None (none sent)."""
        controller = self.controller
        while self.t < until - 1e-9:
            t0, t1 = self.t, self.t + DT
            pairs = sample(t0) if sample else None
            if pairs is not None:
                offer = controller.offer([p for p, _ in pairs], t0)
                self.offers.append(offer)
                if offer is Offer.START:
                    for one in self.playouts:
                        one.reset()
                if offer is not Offer.REFUSE:
                    for one, (p, a) in zip(self.playouts, pairs):
                        one.push(t0, p, a)
            if controller.state is S.TRACKING:
                tracked = [one.step(t0, t1) for one in self.playouts]
                lost, self.seen = self.playouts[0].timeouts > self.seen, self.playouts[0].timeouts
                ramps = controller.step(t0, t1, tracked, lost)
            else:
                ramps = controller.step(t0, t1)
            self.sim.step(*zip(*ramps))
            self.changes += controller.take_changes()
            self.rows.append((t1, [self.sim.axis_state(a) for a in self.sim.axes]))
            self.k += 1
        return self

    def at(self, t: float, axis: int = 0):
        """The plant's (position, velocity, acceleration) of an axis at the end of the step ending at ``t``."""
        return next(state[axis] for t1, state in self.rows if abs(t1 - t) < DT / 2)


def accelerating(t: float):
    """The cart's reference: 0.3 m/s^2 for a second, then 0.1 m/s^2 (still accelerating when the stream dies)."""
    if t < 1.0:
        return [(0.15 * t * t, 0.3)]
    return [(0.15 + 0.3 * (t - 1.0) + 0.05 * (t - 1.0) ** 2, 0.1)]


def until(t_end, reference):
    """``reference`` for stamps before ``t_end``, then nothing: the streamer killed at ``t_end``."""
    return lambda t: reference(t) if t < t_end - 1e-9 else None


def lost_stream(kill: float = 1.5, axes=('cart',), reference=accelerating, **kwargs) -> Rig:
    rig = Rig(axes, **kwargs).run(kill + DELAY + TIMEOUT + 3.0, until(kill, reference))
    assert [c.new for c in rig.changes] == [S.TRACKING, S.FAULT_STOPPING, S.FAULT_HOLD]
    return rig


# --------------------------------------------------------------------------- the state machine


def test_only_the_listed_transitions_are_legal():
    for old, new in itertools.product(S, S):
        if new in TRANSITIONS[old]:
            check_transition(old, new)
        else:
            with pytest.raises(IllegalTransition, match=f'from {old.value} to {new.value}'):
                check_transition(old, new)
    # a fault is always reported stopping first, and left only by a resume or a reset
    assert S.FAULT_HOLD not in TRANSITIONS[S.TRACKING] and S.TRACKING not in TRANSITIONS[S.FAULT_STOPPING]
    assert all(S.IDLE in TRANSITIONS[s] for s in S)


def test_an_illegal_change_raises_and_leaves_the_state():
    controller = AxisController(['cart'], [0.0])
    with pytest.raises(IllegalTransition):
        controller._change(S.FAULT_HOLD, 0.0)
    assert controller.state is S.IDLE and not controller.changes


def test_before_a_first_reference_it_rests_and_takes_the_first_wherever_it_starts():
    rig = Rig().run(1.0)
    assert rig.controller.state is S.IDLE and rig.at(1.0) == (0.0, 0.0, 0.0)
    assert rig.controller.offer([0.25], 1.0) is Offer.START  # no fault: no position check
    assert rig.controller.state is S.TRACKING and rig.controller.offer([7.0], 1.0) is Offer.ACCEPT


# --------------------------------------------------------------------------- the fault reaction


def test_a_lost_stream_brakes_the_reference_and_the_cart_stops_within_the_stopping_distance():
    rig = lost_stream()
    fault, (_, stopping, holding) = rig.controller.fault, rig.changes
    # declared lost when the newest sample (stamped 1.499 s) is older than the timeout at the playout time
    assert stopping.time == pytest.approx(1.499 + DELAY + TIMEOUT, abs=1.01 * DT)
    # from the reference's velocity and acceleration then: the newest sample's 0.1 m/s^2 played only while it was
    # within DRY sample spacings of the playout time (two steps), then the buffer was dry and the velocity held
    braking = fault.brakings[0]
    assert braking.a0 == 0.0
    assert braking.v0 == pytest.approx(0.3 + 0.1 * (1.499 + (math.floor(DRY) + 1) * DT - 1.0), abs=1e-9)
    assert holding.time - stopping.time == pytest.approx(braking.duration, abs=DT)
    # the plant travels the reference's stopping distance plus the servo's lag (Eq. 6: the reference leads
    # the cart by tau * v), which comes to rest exactly where the reference holds
    y_f, v_f, _ = rig.at(stopping.time)
    y_end, v_end, a_end = rig.at(rig.t)
    travelled, expected = y_end - y_f, stopping_distance(braking.v0, braking.a0, D, J)
    assert abs(travelled - expected) <= PLANT.tau * abs(v_f) + 1e-9
    assert travelled == pytest.approx(expected + PLANT.tau * v_f, abs=1e-9)
    assert y_end == pytest.approx(fault.stops[0], abs=1e-9) and abs(v_end) < 1e-9 and abs(a_end) < 1e-9
    # the servo never demands more than the ramp: |a| within D once the first phase has eased a0 off
    braking_rows = [s[0] for t, s in rig.rows if stopping.time < t <= holding.time]
    assert max(abs(a) for _, _, a in braking_rows) <= max(D, abs(braking.a0)) + 1e-9


@pytest.mark.parametrize('kill', [0.3, 1.5, 2.7])
def test_a_lost_stream_stops_the_axis_within_the_watchdogs_distance_of_its_last_reference(kill):
    """docs/faults.md: from the reference of the last sample received (stamped t_last, velocity v there), the axis
    goes on at v until the watchdog (``reference_timeout`` T) and then brakes: it comes to rest no further than
    |v| T + stopping_distance(|v|, 0, D, J), plus the servo's lag tau |v| (Eq. 6) and the acceleration of the
    DRY steps played past t_last. It never extrapolates the last acceleration over the watchdog."""
    rig = lost_stream(kill)
    t_last = kill - DT
    x_last, a = accelerating(t_last)[0]
    v = 0.3 * min(t_last, 1.0) + 0.1 * max(t_last - 1.0, 0.0)
    y_end = rig.at(rig.t)[0]
    dry = (math.floor(DRY) + 1) * DT
    bound = abs(v) * TIMEOUT + stopping_distance(abs(v) + a * dry, 0.0, D, J) + PLANT.tau * abs(v) + a * dry * TIMEOUT
    assert 0.0 < y_end - x_last <= bound + 1e-9
    # extrapolating the acceleration over the watchdog, as the drive never does, goes measurably further
    v_x = v + a * TIMEOUT
    extrapolated = v * TIMEOUT + a * TIMEOUT ** 2 / 2 + stopping_distance(v_x, a, D, J)
    assert y_end - x_last < extrapolated - 1e-3


@pytest.fixture(scope='module')
def moves():
    """NVF, RVF and ZV plans of 0.6 m in 4 s (the planning core's; CasADi for the first two)."""
    from crane_planner.planning.dispatch import plan
    return {method: plan(method, 0.6, 4.0, PLANT) for method in ('nvf', 'rvf', 'zv')}


@pytest.mark.parametrize('at', [0.1, 0.4, 0.9])
@pytest.mark.parametrize('method', ['nvf', 'rvf', 'zv'])
def test_a_stream_lost_during_a_planned_move_stops_within_the_formula_short_of_the_goal(moves, method, at):
    """docs/faults.md's worst stopping distance for the methods' own moves (0.6 m in 4 s) killed at 10, 40 and
    90 %, with the sim's defaults (playout_delay, reference_timeout, fault_deceleration, fault_jerk): past the
    last sample's position at most |v| T + |a| h_d T + S(|v| + |a| h_d) + tau |v|; up to 40 % never beyond the
    goal (at 90 % the plan was decelerating, which the held velocity does not: past it by under a millimetre); at
    40 % of NVF (the requirement) at most 0.15 m past where the cart was at the kill (the plant playout_delay
    behind)."""
    from crane_sim.nodes.sim_node import PARAMETERS
    delay, timeout, D_, J_ = (PARAMETERS[name][0] for name in ('playout_delay', 'reference_timeout',
                                                               'fault_deceleration', 'fault_jerk'))
    p = moves[method]

    def reference(t):
        s = p.evaluate([min(t, p.duration)])
        return [(float(s.position[0]), float(s.acceleration[0]))]

    kill = at * p.duration
    rig = Rig(config=FaultConfig(D_, J_, 1e-3, timeout), delay=delay, timeout=timeout)
    rig.run(kill + delay + timeout + 3.0, until(kill, reference))
    assert [c.new for c in rig.changes] == [S.TRACKING, S.FAULT_STOPPING, S.FAULT_HOLD]
    last = p.evaluate([kill - DT])
    x_last, v, a = (abs(float(x[0])) for x in (last.position, last.velocity, last.acceleration))
    dry = (math.floor(DRY) + 1) * DT
    bound = v * timeout + a * dry * timeout + stopping_distance(v + a * dry, 0.0, D_, J_) + PLANT.tau * v
    y_end = rig.at(rig.t)[0]
    assert 0.0 < y_end - x_last <= bound + 1e-9, (y_end - x_last, bound)
    furthest = max(state[0][0] for _, state in rig.rows)
    if at <= 0.4:  # far from the goal: never beyond it, nor on the way
        assert furthest <= 0.6 + 1e-9
    else:  # braking already, the plan's deceleration is not extrapolated either: past it by what the formula allows
        assert furthest <= x_last + bound + 1e-9 and furthest - 0.6 < 1e-3
    if (method, at) == ('nvf', 0.4):
        assert y_end - rig.at(round(kill - delay, 3))[0] <= 0.15


def test_the_braking_follows_the_closed_form_step_by_step():
    """The reference at every step's end is the closed form's (the ramps match its integrals exactly)."""
    rig = Rig().run(1.5, accelerating)
    controller = rig.controller
    ramps = controller.step(rig.t, rig.t + DT, [(0.0, 0.0)], lost=True)  # lost now, from the reference's state
    braking = controller.fault.brakings[0]
    origin, v = controller.fault.origins[0], braking.v0
    for n in range(1, 900):
        r0, r1 = ramps[0]
        v += DT * (r0 + r1) / 2  # what the plant's servo got
        ramps = controller.step(rig.t + n * DT, rig.t + (n + 1) * DT)
        ref = controller.references[0]
        p1, v1, _ = braking.state((n + 1) * DT)
        assert (ref.position, ref.velocity) == pytest.approx((origin + p1, v1), abs=1e-12)
        assert v == pytest.approx(braking.velocity(n * DT), abs=1e-12)
    assert controller.state is S.FAULT_HOLD


def test_it_holds_without_a_reference():
    rig = lost_stream()
    held = rig.controller.fault.stops[0]
    rig.run(rig.t + 5.0)  # nothing arrives
    assert rig.controller.state is S.FAULT_HOLD
    y, v, a = rig.at(rig.t)
    assert y == pytest.approx(held, abs=1e-9) and abs(v) < 1e-9


def test_a_sample_far_from_where_the_axes_stand_is_refused_and_counted():
    rig = lost_stream()
    controller = rig.controller
    held = controller.fault.stops[0]
    before = rig.at(rig.t)
    rig.run(rig.t + 0.5, lambda t: [(held + 2e-3, 0.2)])  # a stream that does not start where the cart stands
    assert controller.state is S.FAULT_HOLD and controller.refused == 500
    assert set(rig.offers[-500:]) == {Offer.REFUSE}
    assert controller.last_refusal.state is S.FAULT_HOLD
    assert controller.last_refusal.offsets == pytest.approx((2e-3,), abs=1e-12)
    assert rig.at(rig.t)[0] == pytest.approx(before[0], abs=1e-12)  # it did not move the cart


def test_samples_while_stopping_are_refused_even_where_it_will_stop():
    rig = Rig().run(1.5, accelerating)
    rig.run(1.5 + DELAY + TIMEOUT + 0.1)  # lost, braking
    controller = rig.controller
    assert controller.state is S.FAULT_STOPPING
    stop = controller.fault.stops[0]
    assert controller.offer([stop], rig.t) is Offer.REFUSE
    assert controller.last_refusal.state is S.FAULT_STOPPING and controller.last_refusal.offsets == (0.0,)


def test_a_stream_starting_where_the_axes_stand_resumes_from_rest():
    rig = lost_stream()
    controller = rig.controller
    held = controller.fault.stops[0]
    start = rig.t

    def move(t):  # a new stream 0.5 mm off where the cart holds: held 0.1 s, then 0.2 m/s^2 for 0.5 s
        k = round((t - start) / DT) - 100  # the motion's step (1 ms each), negative while held
        s = max(k, 0) * DT
        return [(held + 5e-4 + 0.1 * s * s, 0.2 if k >= 0 else 0.0)] if k < 500 else \
            [(held + 5e-4 + 0.025 + 0.1 * (s - 0.5), 0.0)]

    offered = len(rig.offers)
    rig.run(start + 1.0, move)
    assert [c.new for c in rig.changes[-1:]] == [S.TRACKING] and controller.fault is None
    # its first sample: whether the stream rests there, the second tells (and the first is not counted)
    assert rig.offers[offered:offered + 2] == [Offer.REFUSE, Offer.START] and rig.offers[-1] is Offer.ACCEPT
    assert controller.refused == 0
    # from rest where it held: the new stream's accelerations, played DELAY later
    ref = controller.references[0]
    assert ref.velocity == pytest.approx(0.1, abs=1e-9)
    assert ref.position == pytest.approx(held + 0.025 + 0.1 * (1.0 - DELAY - 0.1 - 0.5), abs=1e-9)


def test_a_stream_in_motion_passing_where_the_axes_hold_is_refused():
    """Taken where it passes the held position, a moving stream would step the reference's velocity from 0 to
    its own: it is refused, and said to be moving, all the way through the tolerance."""
    rig = lost_stream()
    controller = rig.controller
    held = controller.fault.stops[0]
    start, before = rig.t, rig.at(rig.t)
    rig.run(start + 0.2, lambda t: [(held - 0.01 + 0.1 * (t - start), 0.0)])  # 0.1 m/s, at held after 0.1 s
    assert controller.state is S.FAULT_HOLD and set(rig.offers[-200:]) == {Offer.REFUSE}
    assert controller.refused == 200 and not controller.last_refusal.moving  # (10 mm past it now)
    assert rig.at(rig.t)[0] == pytest.approx(before[0], abs=1e-12)  # it did not move the cart
    controller.offer([held + 2e-4], rig.t)
    assert controller.offer([held + 3e-4], rig.t) is Offer.REFUSE and controller.last_refusal.moving
    assert controller.offer([held + 3e-4], rig.t) is Offer.START  # at rest there: a stream from rest


def test_reset_clears_a_fault_and_waits_for_a_first_reference():
    rig = lost_stream()
    controller = rig.controller
    rig.sim.reset(rig.sim.state)
    controller.reset(rig.positions(), rig.t)
    assert controller.state is S.IDLE and controller.fault is None
    assert controller.offer([3.0], rig.t) is Offer.START  # anywhere: a first reference again


def test_both_axes_brake_and_hold_once_both_are_at_rest():
    L1 = PLANT.L1

    def reference(t):  # the cart as above; the hoist shortening the rope at 0.05 m/s^2 for 0.4 s, then coasting
        hoist = (L1 - 0.025 * t * t, -0.05) if t < 0.4 else (L1 - 0.004 - 0.02 * (t - 0.4), 0.0)
        return [*accelerating(t), hoist]

    rig = lost_stream(axes=('cart', 'hoist'), reference=reference)
    fault = rig.controller.fault
    cart, hoist = fault.brakings
    assert hoist.v0 == pytest.approx(-0.02, abs=0.05 * DT + 1e-12) and hoist.a0 == 0.0
    assert fault.stopped_at - fault.lost_at == pytest.approx(max(cart.duration, hoist.duration), abs=DT)
    for axis, braking, tau in ((0, cart, PLANT.tau), (1, hoist, PLANT.tau_hoist)):
        y_f, v_f, _ = rig.at(fault.lost_at, axis)
        y_end, v_end, _ = rig.at(rig.t, axis)
        assert y_end - y_f == pytest.approx(stopping_distance(braking.v0, braking.a0, D, J) + tau * v_f, abs=1e-9)
        assert y_end == pytest.approx(fault.stops[axis], abs=1e-9) and abs(v_end) < 1e-9
    # a stream resumes only if it starts where every axis stands
    held = fault.stops
    assert rig.controller.offer([held[0], held[1] + 2e-3], rig.t) is Offer.REFUSE
    assert rig.controller.last_refusal.offsets == pytest.approx((0.0, 2e-3), abs=1e-12)
    assert rig.controller.offer([held[0] - 1e-4, held[1] + 1e-4], rig.t) is Offer.REFUSE  # (moved: 2 mm)
    assert rig.controller.offer([held[0] - 1e-4, held[1] + 1e-4], rig.t) is Offer.START  # at rest there


def test_with_positions_only_the_playout_has_held_the_last_one_so_it_holds_there_at_once():
    """A controller that only gets positions holds the last setpoint when they stop coming (the playout): by
    the time the stream is declared lost the reference rests, so the braking has no length (but rounding's,
    within the step); the fault is still reported (stopping, then holding) and the stream resumes from the
    last position."""
    def positions(t):
        p, _ = accelerating(t)[0]
        return [(p, 0.0)]

    rig = lost_stream(source='position', reference=positions)
    _, stopping, holding = rig.changes
    assert stopping.time == rig.controller.fault.lost_at and holding.time - stopping.time <= DT + 1e-12
    assert abs(rig.controller.fault.brakings[0].distance) < 1e-12
    last = positions(1.499)[0][0]
    assert rig.controller.fault.stops[0] == pytest.approx(last, abs=1e-9)
    assert rig.at(rig.t)[0] == pytest.approx(last, abs=1e-9)
    assert rig.controller.offer([last], rig.t) is Offer.REFUSE  # the first: is it at rest there?
    assert rig.controller.offer([last], rig.t) is Offer.START


def test_the_status_says_when_the_stream_was_lost_and_where_each_axis_stops():
    rig = Rig().run(1.5, accelerating).run(1.5 + DELAY + TIMEOUT + 0.1)
    controller = rig.controller
    fault = controller.fault
    status = controller.status(clock=lambda t: 1000.0 + t)
    assert status.state is S.FAULT_STOPPING and status.positions == fault.origins
    assert f'reference stream lost at {1000.0 + fault.lost_at:.3f} s' in status.message
    assert 'no fresh sample for 0.5 s' in status.message and 'braking at 0.5 m/s^2, jerk 5 m/s^3' in status.message
    assert f'to stop at {fault.stops[0]:.6g} m' in status.message
    rig.run(rig.t + 2.0)
    status = controller.status()
    assert status.state is S.FAULT_HOLD and status.positions == fault.stops
    assert f'holding cart at {fault.stops[0]:.6g} m' in status.message and 'within 0.001 m' in status.message
    # a change's status is that of its new state, whatever the state now
    assert controller.status(S.FAULT_STOPPING).state is S.FAULT_STOPPING
    assert controller.status(S.TRACKING).state is S.TRACKING and S.TRACKING not in FAULT_STATES


def test_samples_missing_mid_motion_lose_the_stream_saying_so_while_braking_and_holding():
    rig = Rig().run(1.0, accelerating)
    controller = rig.controller
    controller.played((rig.t, 0.0, 0.0))
    controller.played((rig.t + 0.5, 0.0, 0.0))  # a gap while the reference holds: nothing was missed
    controller.step(rig.t, rig.t + DT, [(0.0, 0.0)])
    assert controller.state is S.TRACKING
    controller.played((rig.t + 1.0, 0.1, 0.2))  # a gap across which it moved
    controller.step(rig.t, rig.t + DT, [(0.0, 0.0)])
    status = controller.status()
    assert status.state is S.FAULT_STOPPING
    assert '(samples missing for 500 ms mid-motion)' in status.message
    assert 'no fresh sample' not in status.message
    rig.run(rig.t + 2.0)
    status = controller.status()
    assert status.state is S.FAULT_HOLD and '(samples missing for 500 ms mid-motion)' in status.message


def test_unstamped_samples_timed_by_their_arrival_never_lose_the_stream_across_a_gap():
    """A Float64MultiArray's samples are placed on a grid from their arrival (``reference_intake``): after a
    delay of the sender or of delivery the grid starts again at the arrival, a jump in the timing that shows a
    delay, not samples lost. Neither is a stamped sample's gap judged against an unstamped one before it."""
    rig = Rig().run(1.0, accelerating)
    controller = rig.controller
    controller.played((rig.t, 0.0, 0.2), stamped=False)
    controller.played((rig.t + 0.3, 0.01, 0.2), stamped=False)  # re-anchored 0.3 s on, mid-motion
    controller.played((rig.t + 0.6, 0.02, 0.2))  # a stamped one after an unstamped one: no pair to judge
    controller.step(rig.t, rig.t + DT, [(0.2, 0.2)])
    assert controller.state is S.TRACKING
    controller.played((rig.t + 0.9, 0.03, 0.2))  # two stamped ones 0.3 s apart (over MAX_GAP): judged
    controller.step(rig.t, rig.t + DT, [(0.2, 0.2)])
    assert controller.state is S.FAULT_STOPPING


def test_the_next_fault_uses_a_changed_configuration():
    rig = Rig().run(1.5, accelerating)
    rig.controller.config = FaultConfig(deceleration=2.0, jerk=50.0, resume_tolerance=1e-3, timeout=TIMEOUT)
    rig.run(1.5 + DELAY + TIMEOUT + 2.0)
    braking = rig.controller.fault.brakings[0]
    assert (braking.D, braking.J) == (2.0, 50.0)
    assert braking == Braking(braking.v0, braking.a0, 2.0, 50.0)


@pytest.mark.parametrize('name', ['deceleration', 'jerk', 'resume_tolerance', 'timeout'])
def test_the_configuration_needs_positive_values(name):
    with pytest.raises(ParameterError, match=name):
        FaultConfig(**{name: 0.0})


def spike(t: float):
    """The cart's reference: a quintic rest-to-rest of 75 mm in 76 ms from t = 1 s, the steep base motion of a
    ZVD shaper at its lower time bound (peak 75 m/s^2, jerk up to 1e4 m/s^3)."""
    T, D = 0.076, 0.075
    s = min(max((t - 1.0) / T, 0.0), 1.0)
    return [(D * s**3 * (10 - 15 * s + 6 * s * s), D / T**2 * (60 * s - 180 * s * s + 120 * s**3))]


def through_intake(lost: set[int]) -> tuple[AxisController, float]:
    """``spike`` stamped every 1 ms up to 1.5 s, the samples with an index in ``lost`` never sent, through the
    sim node's path (``ReferenceIntake`` -> ``played`` -> a playout -> ``step``); the controller and the
    reference's velocity at the end (m/s, exactly 0 had every sample come)."""
    intake = ReferenceIntake(TIMEOUT, DELAY, DT)
    playout = ReferencePlayout(DELAY, TIMEOUT)
    controller = AxisController(('cart',), [0.0], FaultConfig(D, J, 1e-3, TIMEOUT))
    for k in range(1500 + round((DELAY + 0.1) / DT)):
        t0 = k * DT
        if k < 1500 and k not in lost:
            (p, a), = spike(t0)
            for sample in intake.receive(k * MS, k * MS, p, a):
                stamp, p, a = sample
                if controller.offer([p], t0) is Offer.START:
                    playout.reset()
                playout.push(stamp * 1e-9, p, a)
                controller.played((stamp * 1e-9, p, a))
        if controller.state is S.TRACKING:
            controller.step(t0, t0 + DT, [playout.step(t0, t0 + DT)])
        else:
            controller.step(t0, t0 + DT)
    return controller, controller.references[0].velocity


MS = 1_000_000


def test_a_sample_lost_on_a_steep_ramp_is_bridged_and_the_motion_goes_on():
    """One sample lost anywhere in the spike (an Ethernet-like link's 1 % loss): the intake bridges it, the
    stream is never judged lost, and the reference ends at rest, within 0.4 mm/s where the jerk is smooth
    (held across the gap, the acceleration before it leaves up to 10 mm/s) and within |jump of the jerk| h^2 / 2
    = 5.1 mm/s at the spike's corners, where the jerk jumps between 0 and 1.03e4 m/s^3 (the bound of
    ``MAX_BRIDGED``). Two
    lost in a row on the ramp are not bridged: held, they lose the stream, and the fault reaction brakes."""
    controller, velocity = through_intake(set())
    assert controller.state is S.TRACKING and velocity == pytest.approx(0.0, abs=1e-6)
    jerk_jump = 60 * 0.075 / 0.076**3
    for k in range(1000, 1078):
        controller, velocity = through_intake({k})
        assert [c.new for c in controller.take_changes()] == [S.TRACKING], k
        assert abs(velocity) <= (jerk_jump * DT**2 / 2 if k in (1000, 1076) else 4e-4), (k, velocity)
    for lost in ({1001, 1002}, {1020, 1021}, {1075, 1076}):
        controller, _ = through_intake(lost)
        assert [c.new for c in controller.take_changes()][:2] == [S.TRACKING, S.FAULT_STOPPING], lost
