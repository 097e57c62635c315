"""The stop planner (crane_planner.serving.stops, transitions) on the spatial crane, and the other handovers of
``transitions`` beside it (a new goal, a settle): a motion of cart and bridge streamed as its knots is stopped or
retargeted from the swing measured in both directions, and the stream (the motion's knots up to the handover, then
the new plan's) is replayed in crane_sim's ``CraneSimulator`` (its own spatial model)."""
import dataclasses

import numpy as np
import pytest
from references import peak_swing_at_rest

from crane_msgs_py.crane.params import CraneParams
from crane_msgs_py.messages.names import BRIDGE_JOINT, CART_JOINT
from crane_planner.planning.dispatch import PlanOptions, SolverCache, plan
from crane_planner.planning.plan import PlanError
from crane_planner.planning.signals import Swing
from crane_planner.serving import transitions
from crane_planner.serving.stops import StopRequest, StopWarmup, plan_stop, warmups
from crane_planner.serving.transitions import JointReading, Measurement, Running
from crane_planner.streaming.hermite import QuinticHermite
from crane_planner.streaming.knots import knot_columns, knot_times
from crane_sim.simulator import CraneSimulator, SpatialSwing

PARAMS = CraneParams()  # tau = 10 ms
JOINTS = ('cart', 'bridge')
ORIGIN = 5_000_000_000  # ns: the running motion's first knot
STARTS = (0.2, -0.1)  # m
GOALS = (0.2 + 0.6, -0.1 + 0.4)
HANDOVER = ORIGIN + 1_500_000_000  # half way through the 3 s motion: full speed
MEASURED = HANDOVER - 60_000_000  # the newest joint_states, 60 ms before the handover
DT = 1e-3
MS = 1_000_000


@pytest.fixture(scope='module')
def solvers():
    return SolverCache()


@pytest.fixture(scope='module')
def running(solvers):
    """An NVF diagonal of 0.6 x 0.4 m in 3 s, as its knots stream (absolute positions)."""
    p = plan('nvf', 0.6, 3.0, PARAMS, variational=solvers, bridge=0.4)
    t = knot_times(p)
    return Running(JOINTS, t, *knot_columns(p, t, STARTS), ORIGIN, p)


class Stream:
    """crane_sim's spatial crane driven by the streamed references' accelerations, one 1 ms tick at a time."""

    def __init__(self, swing: SpatialSwing | None = None):
        self.sim = CraneSimulator(PARAMS, DT, axes=JOINTS)
        self.sim.reset(swing=swing)
        self.starts = dict(zip(JOINTS, STARTS))  # the simulator's axes start at 0: positions relative to these

    def play(self, accelerations: np.ndarray) -> None:
        """(ticks + 1, joints) reference accelerations, linear between ticks."""
        for k in range(len(accelerations) - 1):
            self.sim.step(accelerations[k], accelerations[k + 1])

    def measurement(self, stamp_ns: int) -> Measurement:
        """joint_states now: each axis's position and velocity, the spatial swing."""
        joints = {name: JointReading(self.starts[name] + self.sim.axis_state(name)[0], self.sim.axis_state(name)[1])
                  for name in JOINTS}
        return Measurement(stamp_ns, joints, Swing(**dataclasses.asdict(self.sim.swing)))

    def settle(self, seconds: float = 4.0) -> float:
        """The largest load excursion (m, the norm) over ``seconds`` with every reference at rest."""
        return peak_swing_at_rest(self.sim, seconds)


def motion_accelerations(running: Running, from_ns: int, to_ns: int) -> np.ndarray:
    stamps = np.arange(from_ns, to_ns + 1, MS)
    return np.column_stack([ref[2] for ref in running.at(stamps)])


def plan_accelerations(p, duration: float) -> np.ndarray:
    """(ticks + 1, joints) reference accelerations of the plan ``p`` (an ``AxesPlan`` of ``JOINTS``) from its start."""
    t = np.arange(0.0, duration + 1e-9, DT)
    return np.column_stack([p.axes[name].evaluate(t).acceleration for name in JOINTS])


def test_a_diagonal_stopped_from_the_measured_spatial_swing_rests_without_swing(solvers, running):
    stream = Stream()
    stream.play(motion_accelerations(running, ORIGIN, MEASURED))
    measured = stream.measurement(MEASURED)
    assert abs(measured.swing.phi1) > 0.005  # the load swings out of the x-z plane too
    stream.play(motion_accelerations(running, MEASURED, HANDOVER))
    stop = plan_stop(solvers, running, HANDOVER, PARAMS, measured=measured)
    # the prediction (the servos taken as tracking steadily, a = a_ref, which misses tau j_ref: ~1e-4 rad/s)
    assert stop.state.swing.values() == pytest.approx(dataclasses.astuple(stream.sim.swing), abs=3e-4)
    trajectory = stop.trajectory()
    assert trajectory.method == 'nvf' and trajectory.position.shape[1] == 2
    refs = running.at(HANDOVER)
    for j, name in enumerate(JOINTS):  # it continues the motion where it takes over (what the streamer checks)
        assert trajectory.position[0, j] == pytest.approx(refs[j][0][0], abs=1e-9), name
        assert trajectory.velocity[0, j] == pytest.approx(refs[j][1][0], abs=1e-7), name
        assert trajectory.acceleration[0, j] == pytest.approx(refs[j][2][0], abs=1e-6), name
        assert abs(trajectory.velocity[-1, j]) < 1e-9 and abs(trajectory.acceleration[-1, j]) < 1e-8, name
        assert refs[j][0][0] < trajectory.position[-1, j] < GOALS[j], name  # brakes short of the goal
    # each axis brakes no harder than twice the motion's hardest (no acceleration limit given)
    hardest = max(np.abs(running.interps[j](np.linspace(0.0, 3.0, 400))[2]).max() for j in range(2))
    assert max(np.abs(trajectory.acceleration).max(axis=0)) <= 2.0 * hardest * (1 + 1e-3)
    t = np.arange(0.0, trajectory.duration + 1e-9, DT)
    stream.play(np.column_stack([QuinticHermite(trajectory.t, trajectory.position[:, j], trajectory.velocity[:, j],
                                                trajectory.acceleration[:, j])(t)[2] for j in range(2)]))
    residual = stream.settle()
    print(f'stop: {trajectory.duration:.3f} s, residual {1e3 * residual:.2e} mm')
    assert residual <= 0.5e-3
    for j, name in enumerate(JOINTS):  # (the simulator integrates accelerations linear between 1 ms ticks)
        assert STARTS[j] + stream.sim.axis_state(name)[0] == pytest.approx(trajectory.position[-1, j], abs=1e-4)
        assert abs(stream.sim.axis_state(name)[1]) < 1e-4  # at rest (to the ticks' integration, as test_stops)


def test_a_stop_within_the_bridges_acceleration_limit(solvers, running):
    """With max_bridge_acceleration at half the unlimited stop's peak the stop holds it, and lasts longer."""
    free = plan_stop(solvers, running, HANDOVER, PARAMS)
    limit = 0.5 * free.plan.axes[BRIDGE_JOINT].peaks()[1]
    limited = plan_stop(solvers, running, HANDOVER, PARAMS, PlanOptions(max_bridge_acceleration=limit))
    assert limited.plan.axes[BRIDGE_JOINT].peaks()[1] <= limit * (1 + 1e-6)
    assert limited.plan.duration > free.plan.duration
    print(f'stop: {free.plan.duration:.3f} s, within max_bridge_acceleration {limit:.3g}: '
          f'{limited.plan.duration:.3f} s')


def test_the_stops_warm_up_with_a_bridge_builds_every_solver_a_stop_uses(running):
    cache = SolverCache()
    for request in warmups(PARAMS, bridge=True):
        cache(request)
    built = dict(cache._solvers)
    forms = {key: set(solver._instances) for key, solver in built.items()}  # (each solver's NLPs, by model form)
    stop = plan_stop(cache, running, HANDOVER, PARAMS)
    assert stop.plan.info['solved_in_plane']  # (the diagonal's state lies in its vertical plane: the planar NLP)
    assert cache._solvers == built and {key: set(s._instances) for key, s in built.items()} == forms
    lighter = SolverCache()
    assert StopWarmup(JOINTS, PARAMS)(lighter) is None and lighter._solvers.keys() == built.keys()
    rehearsed = StopRequest.rehearsal(JOINTS, PARAMS)(cache)
    assert rehearsed.position.shape[1] == 2 and np.abs(rehearsed.velocity[-1]).max() < 1e-9


def test_a_measurement_carries_the_swing_of_its_joints():
    """The planar swing without a bridge, the spatial one (phi too) with one (``signals.swing_names``)."""
    Measurement(0, {CART_JOINT: JointReading(0.0)}, Swing.rest(spatial=False))
    Measurement(0, {CART_JOINT: JointReading(0.0), BRIDGE_JOINT: JointReading(0.0)}, Swing.rest(spatial=True))
    with pytest.raises(PlanError, match='phi1'):
        Measurement(0, {CART_JOINT: JointReading(0.0), BRIDGE_JOINT: JointReading(0.0)}, Swing.rest(spatial=False))
    with pytest.raises(PlanError, match='swing'):
        Measurement(0, {CART_JOINT: JointReading(0.0)}, Swing.rest(spatial=True))
    assert Measurement.at_rest(7, {CART_JOINT: 0.1, BRIDGE_JOINT: 0.2}).swing.values() == (0.0,) * 8


def test_a_settle_of_a_load_pushed_in_both_directions_moves_both_axes_back_to_where_they_were(solvers):
    """``transitions.settle`` from the swing measured at rest: both travel axes move, end where they started, and
    leave <= 5 % of the free swing (about 25 mm here)."""
    length = PARAMS.L1 + PARAMS.L2
    pushed = SpatialSwing(theta1=-0.02 / length, phi1=0.015 / length, dphi1=0.02)
    state = transitions.MotionState({name: transitions.AxisState(s) for name, s in zip(JOINTS, STARTS)},
                                    Swing(**dataclasses.asdict(pushed)))
    assert transitions.swing_of(state, PARAMS) > 0.02
    settle = transitions.settle(solvers, state, PARAMS, PlanOptions())
    free, damped = Stream(pushed), Stream(pushed)
    damped.play(plan_accelerations(settle, settle.duration))
    free_swing, residual = free.settle(settle.duration + 4.0), damped.settle()
    print(f'settle: {settle.duration:.3f} s, free swing {1e3 * free_swing:.2f} mm, after {1e3 * residual:.2e} mm')
    assert residual <= 0.05 * free_swing
    for name in JOINTS:
        assert settle.axes[name].displacement == 0.0 and abs(damped.sim.axis_state(name)[0]) < 1e-5


@pytest.mark.parametrize('method', ['nvf', 'zv'])
def test_a_new_goal_that_turns_the_motion_is_planned_from_the_measured_swing_and_ends_there_without_swing(solvers,
                                                                                                          method):
    """Streaming to (0.6, 0) m from ``STARTS``, at 40 % sent to (0.3, 0.4) m from there: ``handover_state`` from
    the joint_states 60 ms before, ``retarget`` by NVF over cart and bridge (or ZV: each axis's reference
    continued plus its shaped change); continuous where the streamer takes it over, at rest at the goal with
    <= 0.5 mm left."""
    p = plan(method, 0.6, 3.0, PARAMS, variational=solvers, bridge=0.0)
    t = knot_times(p)
    running = Running(JOINTS, t, *knot_columns(p, t, STARTS), ORIGIN, p)
    handover = ORIGIN + 1_200_000_000
    goal = {CART_JOINT: STARTS[0] + 0.3, BRIDGE_JOINT: STARTS[1] + 0.4}
    stream = Stream()
    stream.play(motion_accelerations(running, ORIGIN, handover - 60 * MS))
    state = transitions.handover_state(running, handover, stream.measurement(handover - 60 * MS), PARAMS)
    stream.play(motion_accelerations(running, handover - 60 * MS, handover))
    new = transitions.retarget(solvers, running, handover, state, method, goal, 3.0, PARAMS, PlanOptions())
    starts = transitions.joint_starts(new, state)
    refs = running.at(handover)
    for j, name in enumerate(JOINTS):
        s = new.axes[name].evaluate([0.0, new.duration])
        assert starts[j] + s.position[0] == pytest.approx(refs[j][0][0], abs=1e-9), name
        assert s.velocity[0] == pytest.approx(refs[j][1][0], abs=1e-9), name
        assert s.acceleration[0] == pytest.approx(refs[j][2][0], abs=1e-9), name
        assert starts[j] + s.position[1] == pytest.approx(goal[name], abs=1e-9), name
    stream.play(plan_accelerations(new, new.duration))
    residual = stream.settle()
    print(f'retarget ({method}): residual {1e3 * residual:.2e} mm')
    assert residual <= 0.5e-3
    for j, name in enumerate(JOINTS):
        assert STARTS[j] + stream.sim.axis_state(name)[0] == pytest.approx(goal[name], abs=1e-4), name


def test_a_shaped_diagonal_stops_by_braking_each_axis_within_its_limits(solvers):
    """A ZV diagonal of 0.6 x 0.4 m (within cart 0.8, bridge 0.6 m/s^2) stopped at half way: each axis's base
    braked by ruckig within its own acceleration limit and reshaped; no swing left (<= 0.5 mm) on the spatial
    simulator."""
    limits = {CART_JOINT: 0.8, BRIDGE_JOINT: 0.6}
    options = PlanOptions(max_acceleration=limits[CART_JOINT], max_bridge_acceleration=limits[BRIDGE_JOINT])
    p = plan('zv', 0.6, 3.0, PARAMS, options, bridge=0.4)
    t = knot_times(p)
    running = Running(JOINTS, t, *knot_columns(p, t, STARTS), ORIGIN, p)
    stop = plan_stop(solvers, running, HANDOVER, PARAMS, options)
    assert stop.plan.info['stop'] == 'shaped'
    for name, limit in limits.items():
        assert stop.plan.axes[name].peaks()[1] <= limit * (1 + 1e-9), name
    trajectory = stop.trajectory()
    refs = running.at(HANDOVER)
    for j, name in enumerate(JOINTS):
        assert trajectory.position[0, j] == pytest.approx(refs[j][0][0], abs=1e-9), name
        assert trajectory.velocity[0, j] == pytest.approx(refs[j][1][0], abs=1e-9), name
        assert refs[j][0][0] < trajectory.position[-1, j] < GOALS[j], name
    stream = Stream()
    stream.play(motion_accelerations(running, ORIGIN, HANDOVER))
    stream.play(plan_accelerations(stop.plan, stop.plan.duration))
    residual = stream.settle()
    print(f'shaped stop: {stop.plan.duration:.3f} s, residual {1e3 * residual:.2e} mm')
    assert residual <= 0.5e-3
