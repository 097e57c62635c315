"""A goal and a swinging load (serving.swinging, serving.following): success means quiet (a residual over
residual_tolerance aborts the goal, naming it), and a goal sent while the load swings is planned from the swing
(NVF, RVF) or after a settle damped it (a shaper), never as if the load hung still. On the fake crane
(``fake_crane``) with a real NVF planner; the physics judged on crane_sim's crane, not the planner's model."""
import math

import numpy as np
import pytest

from crane_msgs_py.crane.params import CraneParams
from crane_planner.planning.signals import Swing
from crane_planner.serving.goals import GoalState
from crane_planner.serving.moves import Move
from crane_planner.serving.swinging import SWINGING
from crane_planner.serving.transitions import JointReading, Measurement
from crane_sim.simulator import simulate
from serving.fake_crane import MS, T0, Crane, move

S = GoalState
PARAMS = CraneParams()
#: the load 8.6 mm aside, the cables in line, at rest
SWUNG = Swing(theta1=0.01)


@pytest.fixture(scope='module')
def planner():
    from crane_planner.serving import Planner
    return Planner()


def measuring(crane, swing: Swing, every_ms: int = 20):
    """joint_states of the cart where the fake streamer holds it and the load at ``swing`` (held), every
    ``every_ms`` from now on, until the function returned is called."""
    due = [crane.clock()]

    def measure(now):
        if now >= due[0]:
            due[0] = now + every_ms * MS
            crane.service.on_joint_state(Measurement(now, {'cart': JointReading(crane.hold)}, swing))
    crane.clock.hooks.append(measure)
    measure(crane.clock())
    return lambda: crane.clock.hooks.remove(measure)


def test_a_goal_leaving_the_load_swinging_over_residual_tolerance_aborts_naming_the_residual():
    crane = Crane()
    goal = crane.goal('a', move(0.3, 2.0))
    crane.at(T0 + 2_100 * MS, lambda: measuring(crane, SWUNG))  # swinging after the motion, in its window
    outcome, feedback = crane.execute(goal, move(0.3, 2.0), settle=0.5)
    excursion = math.sin(0.01) * (PARAMS.L1 + PARAMS.L2)  # theta2 = 0: the load in line with the upper cable
    assert outcome.how == 'abort' and outcome.residual_swing == pytest.approx(excursion, rel=1e-6)
    assert f'residual swing {1e3 * excursion:.3f} mm, over residual_tolerance 2 mm: the load still swings' in \
        outcome.message
    assert goal.state is S.ENDED and crane.hold == pytest.approx(0.3)  # it moved: only the swing failed it

    tolerant = Crane(residual_tolerance=0.02)
    goal = tolerant.goal('a', move(0.3, 2.0))
    tolerant.at(T0 + 2_100 * MS, lambda: measuring(tolerant, SWUNG))
    outcome, _ = tolerant.execute(goal, move(0.3, 2.0), settle=0.5)
    assert outcome.success and f'residual swing {1e3 * excursion:.3f} mm' in outcome.message


def test_a_goal_with_no_joint_states_succeeds_saying_the_residual_was_not_measured():
    crane = Crane()
    goal = crane.goal('a', move(0.3, 2.0))
    outcome, _ = crane.execute(goal, move(0.3, 2.0), settle=0.5)
    assert outcome.success and math.isnan(outcome.residual_swing)
    assert 'no joint_states: residual not measured' in outcome.message


def test_a_swing_under_half_the_tolerance_is_planned_from_rest():
    crane = Crane()
    small = Swing(theta1=0.4 * SWINGING * 0.002 / (PARAMS.L1 + PARAMS.L2))
    measuring(crane, small)
    crane.clock.sleep(0.05)
    goal = crane.goal('a', move(0.3, 2.0))
    outcome, _ = crane.execute(goal, move(0.3, 2.0), settle=0.2)
    assert len(crane.published) == 1 and crane.published[0][1].samples[0].t[-1] == pytest.approx(2.0)
    assert outcome.plan.plan.method == 'zv'


def test_an_nvf_goal_while_the_load_swings_is_planned_from_the_swing_and_leaves_none(planner):
    """The swing measured now, predicted to the goal's start (handover_lead ahead): the plan from it, played
    on crane_sim from the swing as it is then, leaves under 0.1 mm; from rest it would leave the swing."""
    crane = Crane(planner=planner, method='nvf')
    crane.at(T0 + 300 * MS, measuring(crane, SWUNG))  # (this fake's swing is fixed: none measured once it moves)
    crane.clock.sleep(0.05)
    measured_ns = crane.service.view.measured.stamp_ns
    goal = crane.goal('a', move(0.3, 2.5, method='nvf'))
    outcome, feedback = crane.execute(goal, move(0.3, 2.5, method='nvf'), settle=0.2)
    assert outcome.success and 'from a swing of 8.6 mm' in outcome.message
    assert feedback[0]['swing'] == pytest.approx(0.0086, abs=1e-4)
    (sent_ns, trajectory), = crane.published
    handover = trajectory.stamp_ns
    assert handover >= sent_ns and handover - sent_ns <= 0.2e9  # a lead ahead, not at once
    plan = outcome.plan.plan
    assert plan.duration == pytest.approx(2.5) and trajectory.starts[0] == pytest.approx(0.0)
    # crane_sim: the load swinging freely from the measurement to the start, then the plan's reference
    t_free = np.arange(0.0, (handover - measured_ns) * 1e-9 + 1e-9, 1e-3)
    t = np.arange(0.0, plan.duration + 3.0, 1e-3)
    a = np.concatenate([np.zeros(len(t_free)), plan.evaluate(t).acceleration[1:]])
    r = simulate(np.concatenate([t_free, t_free[-1] + t[1:]]), a, PARAMS,
                 initial_state=[0.0, 0.0, 0.0, *SWUNG.values()])
    after = r.t > t_free[-1] + plan.duration
    assert np.abs(r.load_excursion[0, after]).max() < 1e-4
    assert r.y[0, -1] == pytest.approx(0.3, abs=1e-5)  # (the 1 ms steps of its acceleration)


def test_an_nvf_goal_while_the_load_swings_refuses_via_points_and_the_fastest_plan_naming_the_swing(planner):
    crane = Crane(planner=planner, method='nvf')
    measuring(crane, SWUNG)
    crane.clock.sleep(0.05)
    via = Move('nvf', goal=(0.3,), duration=2.5, via=((0.1,),))
    outcome, _ = crane.execute(crane.goal('a', via), via)
    assert outcome.how == 'abort' and outcome.message.startswith('move.via: the load swings 8.6 mm')
    assert 'over 0.5 of residual_tolerance 2 mm' in outcome.message and '~/settle' in outcome.message
    fastest = Move('nvf', goal=(0.3,), duration=0.0)  # 0: the fastest within the limits
    outcome, _ = crane.execute(crane.goal('b', fastest), fastest)
    assert outcome.how == 'abort' and 'the fastest plan is planned from a load at rest' in outcome.message
    assert crane.published == []


def test_a_shapers_goal_while_the_load_swings_has_it_damped_first_then_runs_from_rest(planner):
    crane = Crane(planner=planner)
    crane.at(T0 + 300 * MS, measuring(crane, SWUNG))  # (fixed: none measured once the settle moves)
    crane.clock.sleep(0.05)
    goal = crane.goal('a', move(0.3, 2.0))
    outcome, feedback = crane.execute(goal, move(0.3, 2.0), settle=0.2)
    assert len(crane.published) == 2, crane.log.lines
    (_, settle), (sent_ns, shaped) = crane.published
    # the settle: NVF from the swing, ending where the cart is held
    assert settle.starts[0] == 0.0 and settle.samples[0].position[-1] == pytest.approx(0.0, abs=1e-9)
    settle_end = settle.stamp_ns + round(float(settle.samples[0].t[-1]) * 1e9)
    # then the goal from rest, once the streamer held after the settle
    assert sent_ns >= settle_end and outcome.plan.plan.method == 'zv'
    assert shaped.starts[0] == pytest.approx(0.0) and crane.hold == pytest.approx(0.3)
    assert any('which zv cannot damp: settling a swing of about 8.6 mm' in line for _, line in crane.log.lines)
    assert feedback[0]['swing'] == pytest.approx(0.0086, abs=1e-4)
    assert outcome.success


def test_a_newer_goal_during_the_settle_before_a_shapers_goal_takes_its_place(planner):
    crane = Crane(planner=planner)
    measuring(crane, SWUNG)
    crane.clock.sleep(0.05)
    goal = crane.goal('a', move(0.3, 2.0))
    crane.at(T0 + 500 * MS, lambda: crane.goal('b', move(0.1, 2.0)))
    outcome, _ = crane.execute(goal, move(0.3, 2.0))
    assert outcome.how == 'abort' and 'preempted by a newer goal before its motion started' in outcome.message
    # the settle, then the newer goal's handover of it (a shaper's, sent on its arrival): the settle's damping
    # goes on under its shaped change
    (_, settle), (_, handover) = crane.published
    assert settle.stamp_ns < handover.stamp_ns < settle.stamp_ns + round(float(settle.samples[0].t[-1]) * 1e9)


def test_an_nvf_goal_while_the_load_swings_starts_at_its_start_time_sent_publish_lead_before_it(planner):
    """A start_time ahead: planned from the swing predicted to it, stamped with it exactly (what the caller
    waits for), held until publish_lead before it as a goal from rest is."""
    crane = Crane(planner=planner, method='nvf')
    crane.at(T0 + 300 * MS, measuring(crane, SWUNG))
    crane.clock.sleep(0.05)
    start_ns = T0 + 1_500 * MS
    later = move(0.3, 2.5, start_ns=start_ns, method='nvf')
    outcome, _ = crane.execute(crane.goal('a', later), later, settle=0.2)
    (sent_ns, trajectory), = crane.published
    assert outcome.success and 'from a swing of 8.6 mm' in outcome.message
    assert trajectory.stamp_ns == start_ns
    assert start_ns - round(crane.config.publish_lead * 1e9) <= sent_ns < start_ns


def test_an_nvf_goal_whose_plan_from_the_swing_fails_has_the_swing_damped_first_then_runs_from_rest(planner):
    """The solver makes no plan from the swing (here: a planner whose retarget fails): the goal is not lost,
    a settle damps the swing, then it is planned from rest."""
    from crane_planner.planning.plan import PlanError
    from crane_planner.serving import transitions
    crane = Crane(planner=planner, method='nvf')
    crane.at(T0 + 300 * MS, measuring(crane, SWUNG))
    crane.clock.sleep(0.05)
    original = transitions.retarget

    def failing(*args, **kwargs):
        raise PlanError('nvf: no plan within max_solve_time 1 s (IPOPT stopped after 49 iterations)')
    transitions.retarget = failing
    try:
        goal = crane.goal('a', move(0.3, 2.5, method='nvf'))
        outcome, _ = crane.execute(goal, move(0.3, 2.5, method='nvf'), settle=0.2)
    finally:
        transitions.retarget = original
    assert outcome.success and len(crane.published) == 2, (outcome.message, crane.log.lines)
    (_, settle), (_, goal_trajectory) = crane.published
    assert settle.samples[0].position[-1] == pytest.approx(0.0, abs=1e-9)  # the settle ends where it started
    assert outcome.plan.plan.method == 'nvf' and crane.hold == pytest.approx(0.3)
    assert any('no plan from the swing was made' in line for _, line in crane.log.lines)


def test_on_a_runway_a_goal_from_the_swing_is_published_with_its_masses_from_the_swing(planner):
    """A shared runway: the goal planned from the swing is published when sent (not placed: it starts at its
    handover), its masses from the swing there, and a hold where it ends."""
    from crane_planner.runway.occupancy import Occupancy
    from crane_planner.serving.runway_step import RunwayStep
    crane = Crane(planner=planner, method='nvf', runway=True, crane_name='crane_a')
    published: list[Occupancy] = []
    step = RunwayStep(lambda: crane.config, crane.clock, published.append)
    crane.service.serving.runway = crane.service.runway = step
    crane.at(T0 + 300 * MS, measuring(crane, SWUNG))
    crane.clock.sleep(0.05)
    goal = crane.goal('a', move(0.3, 2.5, method='nvf'))
    outcome, _ = crane.execute(goal, move(0.3, 2.5, method='nvf'), settle=0.2)
    assert outcome.success and 'from a swing of 8.6 mm' in outcome.message
    crane.clock.sleep(0.05)
    assert ['hold' if len(o.t) == 1 else 'motion' for o in published] == ['hold', 'motion', 'hold']
    motion = published[1]
    (sent_ns, trajectory), = crane.published
    assert motion.published_ns == sent_ns
    handover = trajectory.stamp_ns
    # at the handover the load hangs aside by the swing (8.6 mm, as it swings freely), the hook by less
    at = motion.at([handover])
    load_aside = abs(float(at.masses[0, 1, 0]))
    assert 0.005 < load_aside < 0.009 and abs(float(at.masses[0, 0, 0])) < load_aside
    assert motion.at([motion.end_ns]).masses[0, :, 0] == pytest.approx([0.3, 0.3], abs=1e-4)
    assert published[2].footprint.masses[0, 1, 0] == pytest.approx(0.3)
