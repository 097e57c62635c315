"""Motion from any state on the spatial crane (planning.continuation over cart and bridge): every plan is replayed
in crane_sim's ``CraneSimulator`` (its own spatial model, dt 1 ms, the reference linear between samples), the
first plan's reference up to the handover and the new plan's from there, so the new plan starts from the
simulator's true state: the references on every axis, each axis's actual lag behind it and the swing in both
directions as the simulator has it."""
import dataclasses

import numpy as np
import pytest
from references import peak_swing_at_rest

from crane_msgs_py.crane.params import CraneParams
from crane_msgs_py.messages.names import BRIDGE_JOINT, CART_JOINT
from crane_planner.planning.continuation import AxisState, MotionState, first_period, predict, problem_start
from crane_planner.planning.dispatch import PlanOptions, SolverCache, VariationalRequest, plan
from crane_planner.planning.plan import AxesPlan, PlanError
from crane_planner.planning.problem import Form
from crane_planner.planning.signals import Swing
from crane_sim.simulator import CraneSimulator, SpatialSwing

#: The paper's rig (servo tau = 10 ms) and the same with ideal servos.
NOMINAL = CraneParams()
IDEAL = NOMINAL.replace(tau=0.0)
AXES = (CART_JOINT, BRIDGE_JOINT)
DT = 1e-3
T = 3.0
HANDOVER = 1.2  # s: 40 % of the 3 s motion


@pytest.fixture(scope='module')
def solvers():
    return SolverCache()


class Replay:
    """One simulated crane driven by a sequence of plans' reference accelerations (each from its handover on)."""

    def __init__(self, params, swing: SpatialSwing | None = None):
        self.sim = CraneSimulator(params, DT, axes=AXES)
        self.sim.reset(swing=swing)
        self.starts = {name: 0.0 for name in AXES}  # each plan's positions are relative to its start

    def play(self, p: AxesPlan, until: float) -> None:
        """``p``'s references from its t = 0 for ``until`` s (whole steps)."""
        n = int(round(until / DT))
        refs = np.array([p.axes[a].evaluate(np.arange(n + 1) * DT).acceleration for a in AXES]).T
        for k in range(n):
            self.sim.step(refs[k], refs[k + 1])

    def state(self, p: AxesPlan, t: float) -> MotionState:
        """The true state now, ``t`` s into the plan ``p``: each axis's reference, its actual lag, the swing."""
        axes = {}
        for name in AXES:
            ref = p.axes[name].evaluate(t)
            position = self.starts[name] + ref.position[0]
            axes[name] = AxisState(position, ref.velocity[0], ref.acceleration[0],
                                   self.sim.axis_state(name)[0] - position)
        return MotionState(axes, Swing(**dataclasses.asdict(self.sim.swing)))

    def settle(self, seconds: float = 4.0) -> float:
        """The largest load excursion (m, the norm) over ``seconds`` with every reference at rest."""
        return peak_swing_at_rest(self.sim, seconds)


def handover(solvers, params, running: AxesPlan, t_h: float, request):
    """(new plan, handover state, replay after the new plan): ``running`` played until ``t_h``, then the plan
    ``request(state, start, model)`` makes from the true state there."""
    replay = Replay(params)
    replay.play(running, t_h)
    state = replay.state(running, t_h)
    start, model = problem_start(state, params)
    new = solvers(request(state, start, model))
    for name in AXES:
        replay.starts[name] = state.axis(name).position
    replay.play(new, new.duration)
    return new, state, replay


def assert_continuous(old: AxesPlan, new: AxesPlan, t_h: float) -> None:
    """The new reference starts exactly on the old one on every axis: position, velocity, acceleration."""
    for name in AXES:
        o, n = old.axes[name].evaluate(t_h), new.axes[name].evaluate(0.0)
        assert n.position[0] == pytest.approx(0.0, abs=1e-12), name
        assert n.velocity[0] == pytest.approx(o.velocity[0], abs=1e-9), name
        assert n.acceleration[0] == pytest.approx(o.acceleration[0], abs=1e-9), name


def assert_at_rest(p: AxesPlan) -> None:
    for name in AXES:
        end = p.axes[name].evaluate(p.duration)
        assert abs(end.velocity[0]) < 1e-9 and abs(end.acceleration[0]) < 1e-8, name


@pytest.mark.parametrize('params, bound_mm', [(IDEAL, 0.1), (NOMINAL, 0.5)], ids=['tau0', 'tau10ms'])
def test_a_new_goal_that_turns_the_direction_ends_there_without_swing(solvers, params, bound_mm):
    """Going to (0.6, 0) m and at 40 % sent to (0.3, 0.4) m instead: the cart brakes and turns back while the
    bridge sets off, planned together from the measured spatial swing; rest at the goal in 3 s more."""
    running = plan('nvf', 0.6, T, params, variational=solvers, bridge=0.0)
    goal = {CART_JOINT: 0.3, BRIDGE_JOINT: 0.4}

    def request(state, start, model):
        moves = {name: goal[name] - state.axis(name).position for name in AXES}
        return VariationalRequest('plan', 'nvf', moves, T, model, PlanOptions(), start)

    new, state, replay = handover(solvers, params, running, HANDOVER, request)
    assert new.info['from_state'] and isinstance(new, AxesPlan)
    assert abs(state.swing.theta1) > 0.01  # the load lags the cart's acceleration: the swing the plan starts from
    assert_continuous(running, new, HANDOVER)
    assert_at_rest(new)
    for name in AXES:
        assert state.axis(name).position + new.axes[name].displacement == pytest.approx(goal[name], abs=1e-9)
        assert replay.sim.axis_state(name)[0] == pytest.approx(goal[name], abs=1e-5)
    residual = replay.settle()
    print(f'retarget residual {1e3 * residual:.2e} mm (tau {params.tau:g} s)')
    assert 1e3 * residual <= bound_mm


def test_a_stop_mid_diagonal_rests_without_swing(solvers):
    """A 0.6 x 0.4 m diagonal stopped at 40 %, near full speed: NVF to rest anywhere (free end) over a first
    period, both axes at rest short of the goal with <= 0.5 mm of swing left."""
    running = plan('nvf', 0.6, T, NOMINAL, variational=solvers, bridge=0.4)
    period = first_period(NOMINAL)

    def request(state, start, model):
        scale = {name: state.axis(name).velocity * period / 2 for name in AXES}
        return VariationalRequest('plan', 'nvf', scale, period, model, PlanOptions(), start, free_end=True)

    new, state, replay = handover(solvers, NOMINAL, running, HANDOVER, request)
    assert_continuous(running, new, HANDOVER)
    assert_at_rest(new)
    for name, goal in ((CART_JOINT, 0.6), (BRIDGE_JOINT, 0.4)):
        speed = state.axis(name).velocity
        assert 0.0 < new.axes[name].displacement < speed * period, name  # it brakes: short of coasting
        assert state.axis(name).position + new.axes[name].displacement < goal, name
    residual = replay.settle()
    print(f'stop residual {1e3 * residual:.2e} mm')
    assert 1e3 * residual <= 0.5
    assert max(abs(replay.sim.axis_state(name)[1]) for name in AXES) < 1e-6  # at rest


def test_a_load_pushed_in_both_directions_is_settled_where_it_started(solvers):
    """A load at rest swinging 20 mm along x and 15 mm along y (theta1, phi1 set, released): NVF from that state
    back to the same place over a first period leaves <= 5 % of the free swing (measured: far less)."""
    length = NOMINAL.L1 + NOMINAL.L2
    pushed = SpatialSwing(theta1=0.02 / length, phi1=0.015 / length)
    state = MotionState({name: AxisState() for name in AXES}, Swing(**dataclasses.asdict(pushed)))
    start, model = problem_start(state, NOMINAL)
    period = first_period(NOMINAL)
    settle = solvers(VariationalRequest('plan', 'nvf', {CART_JOINT: 0.0, BRIDGE_JOINT: 0.0}, period, model,
                                        PlanOptions(), start))
    assert_at_rest(settle)
    for name in AXES:
        assert settle.axes[name].displacement == 0.0
        assert settle.axes[name].evaluate(period).position[0] == pytest.approx(0.0, abs=1e-9)
        assert settle.axes[name].peaks()[0] > 1e-3, name  # both axes move to damp it
    free = Replay(NOMINAL, pushed)
    free.play(settle, 0.0)
    free_swing = free.settle(period + 4.0)
    replay = Replay(NOMINAL, pushed)
    replay.play(settle, period)
    residual = replay.settle()
    print(f'settle: free swing {1e3 * free_swing:.2f} mm, after the settle {1e3 * residual:.2e} mm')
    assert free_swing > 0.02
    assert residual <= 0.05 * free_swing
    assert max(abs(replay.sim.axis_state(name)[0]) for name in AXES) < 1e-5  # back where it started


def test_predict_carries_a_spatial_measurement_to_the_handover_like_the_simulator(solvers):
    """The swing in both directions measured 60 ms before the handover, carried there along both references by
    the planning model, agrees with the simulator's."""
    running = plan('nvf', 0.6, T, NOMINAL, variational=solvers, bridge=0.4)
    t_m = HANDOVER - 0.06
    replay = Replay(NOMINAL)
    replay.play(running, t_m)
    measured = replay.state(running, t_m)
    n = int(round(t_m / DT))
    refs = np.array([running.axes[a].evaluate(np.arange(n, n + 61) * DT).acceleration for a in AXES]).T
    for k in range(60):
        replay.sim.step(refs[k], refs[k + 1])
    truth = replay.state(running, HANDOVER)

    def reference(t):
        return [tuple(getattr(running.axes[a].evaluate(t), k) for k in ('position', 'velocity', 'acceleration',
                                                                          'jerk')) for a in AXES]

    predicted = predict(measured, reference, t_m, HANDOVER, NOMINAL)
    assert predicted.swing.spatial
    assert predicted.swing.values() == pytest.approx(truth.swing.values(), abs=5e-5)
    for name in AXES:
        assert predicted.axis(name).lag == pytest.approx(truth.axis(name).lag, abs=1e-6)
    assert max(abs(a - b) for a, b in zip(measured.swing.values(), truth.swing.values())) > 1e-3


def test_the_swing_has_the_length_of_the_axes_present():
    """The planar swing without a bridge, the spatial one (phi too) with one (``dynamics.crane_ode``'s order);
    none given: at rest."""
    assert MotionState({CART_JOINT: AxisState(), BRIDGE_JOINT: AxisState()}).swing.values() == (0.0,) * 8
    with pytest.raises(PlanError, match='phi1'):
        MotionState({CART_JOINT: AxisState(), BRIDGE_JOINT: AxisState()}, Swing.rest(spatial=False))
    with pytest.raises(PlanError, match='swing'):
        MotionState({CART_JOINT: AxisState()}, Swing.rest(spatial=True))
    swing = (0.01, 0.002, -0.02, 0.003, 0.1, 0.2, -0.3, 0.4)
    start, _ = problem_start(MotionState({CART_JOINT: AxisState(), BRIDGE_JOINT: AxisState(0.0, 0.1)},
                                         Swing.of(swing, spatial=True)), NOMINAL)
    assert [start[k] for k in ('theta1', 'theta2', 'phi1', 'phi2', 'dtheta1', 'dtheta2', 'dphi1',
                               'dphi2')] == list(swing)
    assert start['vb'] + NOMINAL.tau * start['ab'] == pytest.approx(0.1)  # the bridge's servo tracks steadily


def test_a_request_mirrored_in_one_travel_axis_starts_from_the_mirrored_solution():
    """The crane is symmetric in each travel axis (``Transcription.mirror``): after 0.3 x 0.2 m, the request
    -0.3 x 0.2 m starts at its optimum (no IPOPT iteration) and is the first plan with the cart mirrored; a hoist's
    change of sign (no mirror) starts cold."""
    cache = SolverCache()
    first = plan('nvf', 0.3, T, IDEAL, variational=cache, bridge=0.2)
    mirrored = plan('nvf', -0.3, T, IDEAL, variational=cache, bridge=0.2)
    assert mirrored.info['iterations'] == 0
    t = np.linspace(0.0, T, 7)
    assert mirrored.axes[CART_JOINT].evaluate(t).acceleration == pytest.approx(
        -first.axes[CART_JOINT].evaluate(t).acceleration, abs=1e-9)
    assert mirrored.axes[BRIDGE_JOINT].evaluate(t).acceleration == pytest.approx(
        first.axes[BRIDGE_JOINT].evaluate(t).acceleration, abs=1e-9)
    solver = next(iter(cache._solvers.values()))
    hoisting = solver.transcription(Form(servo=False, hoist=True))
    start = {'x0': np.ones(hoisting.nw), 'lam_x0': np.ones(hoisting.nw), 'lam_g0': np.ones(hoisting.ng)}
    assert solver.warm_start(hoisting, ((1.0, 1.0), start), (-0.3, 0.1))['x0'][0] == -1.0  # the cart's y mirrored
    assert solver.warm_start(hoisting, ((1.0, 1.0), start), (0.3, -0.1)) is None
