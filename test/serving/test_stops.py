"""A running motion's stop (crane_planner.serving.stops): planned here and in a worker process alike, and
checked on crane_sim's crane (numpy, independent of the planner's CasADi model) as the streamer streams it:
the motion's knots up to the handover, then the stop's knots."""
import time

import numpy as np
import pytest

from crane_msgs_py.crane.params import CraneParams
from crane_planner.planning.dispatch import SolverCache, plan
from crane_planner.planning.plan import PlanError
from crane_planner.serving.stops import STOP_LEAD, StopRequest, StopWarmup, StopWorker, plan_stop, warmups
from crane_planner.serving.transitions import Running
from crane_planner.serving.workers import SolverProcess
from crane_planner.streaming.hermite import QuinticHermite
from crane_planner.streaming.knots import knot_columns, knot_times
from crane_planner.streaming.reference_stream import ReferenceStream
from crane_sim.simulator import simulate

PARAMS = CraneParams()
ORIGIN = 5_000_000_000  # ns: the running motion's first knot
START = 0.2  # m
HANDOVER = ORIGIN + 1_500_000_000  # half way through a 3 s motion
DT = 1e-3
MS = 1_000_000  # ns: the streamer's tick at 1 kHz


@pytest.fixture(scope='module')
def solvers():
    return SolverCache()


@pytest.fixture(scope='module')
def running(solvers):
    """An RVF move of 0.3 m in 3 s, as its knots stream (absolute positions)."""
    p = plan('rvf', 0.3, 3.0, PARAMS, variational=solvers)
    t = knot_times(p)
    return Running(('cart',), t, *knot_columns(p, t, [START]), ORIGIN, p)


def streamed(running, trajectory):
    """What the streamer publishes: the motion's knots until the handover, then the stop's: (t, acceleration)."""
    t_h = (trajectory.handover_ns - ORIGIN) * 1e-9
    t1 = np.arange(0.0, t_h, DT)
    a1 = running.at(ORIGIN + np.round(t1 * 1e9).astype(np.int64))[0][2]
    t2 = np.arange(0.0, trajectory.duration + 4.0, DT)
    a2 = QuinticHermite(*trajectory.arrays())(t2)[2]
    return np.concatenate([t1, t_h + t2]), np.concatenate([a1, a2])


def test_a_stop_from_a_moving_state_leaves_no_swing_on_the_simulator(solvers, running):
    stop = plan_stop(solvers, running, HANDOVER, PARAMS)
    trajectory = stop.trajectory()
    assert trajectory.method == 'nvf' and trajectory.handover_ns == HANDOVER
    # it continues the motion where it takes over (what the streamer checks)
    ref = running.at(HANDOVER)[0]
    assert trajectory.position[0, 0] == pytest.approx(ref[0][0], abs=1e-9)
    assert trajectory.velocity[0, 0] == pytest.approx(ref[1][0], abs=1e-7)
    assert trajectory.acceleration[0, 0] == pytest.approx(ref[2][0], abs=1e-6)
    assert trajectory.end == pytest.approx(trajectory.position[-1, 0]) and trajectory.end < START + 0.3
    t, a = streamed(running, trajectory)
    r = simulate(t, a, PARAMS)
    after = t > 1.5 + trajectory.duration
    assert np.abs(r.v[0, after]).max() < 1e-4  # at rest
    residual = np.abs(r.load_excursion[0, after]).max()
    assert residual < 0.5e-3
    # the motion held where it is at the handover (what the streamer does without a stop) swings far more
    held = running.at(ORIGIN + np.round(np.minimum(t, 1.5) * 1e9).astype(np.int64))[0][0]
    assert np.abs(simulate(t, held, PARAMS, source='position').load_excursion[0, after]).max() > 10 * residual


def test_the_stops_warm_up_builds_every_solver_a_stop_uses(running):
    cache = SolverCache()
    for request in warmups(PARAMS):
        cache(request)
    built = dict(cache._solvers)
    plan_stop(cache, running, HANDOVER, PARAMS)
    assert cache._solvers == built


@pytest.mark.parametrize('joints', [('cart',), ('cart', 'hoist')])
def test_a_rehearsal_builds_the_solvers_the_warm_up_lists(joints):
    cache = SolverCache()
    trajectory = StopRequest.rehearsal(joints, PARAMS)(cache)
    assert trajectory.method == 'nvf' and trajectory.position.shape[1] == len(joints)
    built = dict(cache._solvers)
    for request in warmups(PARAMS, hoist=len(joints) > 1):
        cache(request)
    assert cache._solvers == built
    lighter = SolverCache()  # the stop worker's warm-up: the same solvers
    assert StopWarmup(joints, PARAMS)(lighter) is None and lighter._solvers.keys() == built.keys()


def test_a_stop_request_runs_in_a_worker_as_here(solvers, running):
    request = StopRequest(('cart',), tuple(running.interps), ORIGIN, HANDOVER, PARAMS)
    here = request(solvers)
    worker = SolverProcess()
    try:
        there = worker.solve(request, 60.0)
    finally:
        worker.close()
    assert there.duration == pytest.approx(here.duration)
    np.testing.assert_allclose(there.position, here.position, atol=1e-7)
    assert there.arrays()[1].ndim == 1  # one joint: the columns as ReferenceStream.accept takes them


@pytest.fixture(scope='module')
def stop_worker():
    # the splice's physics is checked here, not how fast this host answers: the clock of these stops is the
    # test's own, and the answer may take as long as a busy host needs
    worker = StopWorker(('cart',), PARAMS, answer_timeout=60.0)
    with pytest.raises(PlanError, match='the stop planner process is not ready: starting'):
        worker.stop((), ORIGIN, lambda: HANDOVER, PARAMS)
    deadline = time.monotonic() + 120.0
    while not worker.ready and time.monotonic() < deadline:
        assert not worker.status.startswith('failed'), worker.status
        time.sleep(0.05)
    assert worker.ready, worker.status
    yield worker
    worker.close()


def test_the_streamers_stop_is_planned_in_its_worker_and_spliced_in_without_swing(stop_worker, running):
    """The streamer's path: its ReferenceStream streams the motion, ~/stop takes it over from the worker's
    answer; what the stream then publishes, tick by tick, leaves no swing on crane_sim."""
    stream = ReferenceStream(MS, hold=START, start_tolerance=1e-6)
    tick = [0]
    assert stream.start(ORIGIN, lambda: tick[0])
    t, p, v, a = (running.interps[0].t, running.interps[0].position, running.interps[0].velocity,
                  running.interps[0].acceleration)
    stream.accept(t, p, v, a, ORIGIN, ORIGIN)
    samples = []
    for _ in range(1500):
        samples.append(stream.sample(tick[0]))
        tick[0] += 1
    trajectory = stop_worker.take_over(stream, lambda: ORIGIN + tick[0] * MS, PARAMS)
    assert trajectory.handover_ns >= ORIGIN + 1500 * MS + STOP_LEAD * 1e9 - 1
    while stream.streaming or stream.queued:
        samples.append(stream.sample(tick[0]))
        tick[0] += 1
    samples += [stream.sample(tick[0] + k) for k in range(4000)]
    acceleration = np.array(samples)[:, 2]
    r = simulate(np.arange(acceleration.size) * DT, acceleration, PARAMS)
    assert np.abs(r.load_excursion[0, -2000:]).max() < 0.5e-3
    assert np.abs(r.v[0, -2000:]).max() < 1e-4


def test_the_streamers_stop_worker_says_why_it_cannot_and_starts_again(stop_worker, running):
    assert stop_worker.stop(running.interps, ORIGIN, lambda: running.end_ns - 1, PARAMS) is None  # it ends first
    with pytest.raises(PlanError, match='no motion is streaming'):
        stop_worker.take_over(ReferenceStream(MS, hold=START, start_tolerance=1e-6), lambda: ORIGIN, PARAMS)
    stop_worker._worker._process.kill()
    stop_worker._worker._process.join()
    assert stop_worker.status == 'its process ended' and not stop_worker.ready
    with pytest.raises(PlanError, match='not ready: its process ended'):
        stop_worker.stop(running.interps, ORIGIN, lambda: HANDOVER - round(STOP_LEAD * 1e9), PARAMS)
    assert stop_worker.status == 'starting'  # started again


def test_a_stop_with_a_hoist_continues_both_joints(solvers):
    p = plan('nvf', 0.3, 3.0, PARAMS, variational=solvers, hoist=(PARAMS.L1, PARAMS.L1 - 0.1))
    t = knot_times(p)
    running = Running(('cart', 'hoist'), t, *knot_columns(p, t, [START, PARAMS.L1]), ORIGIN, p)
    trajectory = plan_stop(solvers, running, HANDOVER, PARAMS).trajectory()
    refs = running.at(HANDOVER)
    assert trajectory.position.shape[1] == 2
    for j in range(2):
        assert trajectory.position[0, j] == pytest.approx(refs[j][0][0], abs=1e-9)
        assert trajectory.velocity[0, j] == pytest.approx(refs[j][1][0], abs=1e-7)
    assert np.abs(trajectory.velocity[-1]).max() < 1e-9


@pytest.mark.parametrize('method', ['zv', 'zvd'])  # (EI leaves its residual by design: tested apart)
@pytest.mark.parametrize('at', [0.15, 0.3, 0.5, 0.7])
def test_a_shaped_motions_stop_ends_short_of_its_goal_sooner_than_it_and_without_swing(method, at):
    """A shaped 0.6 m move in 3 s (no axis limits) stopped at ``at`` of it: its base braked as hard as the base
    itself moves. It ends where the motion had not yet arrived (a base braked within the shaped reference's
    lower peaks instead ran on from its own harder acceleration: ZV stopped at 15 % ended 0.275 m past the goal),
    no later than the motion would have, and crane_sim's crane ends it at rest without swing."""
    p = plan(method, 0.6, 3.0, PARAMS)
    t = knot_times(p)
    running = Running(('cart',), t, *knot_columns(p, t, [START]), ORIGIN, p)
    handover = ORIGIN + round(at * 3.0 * 1e9)
    stop = plan_stop(None, running, handover, PARAMS)  # (a shaper's: no solver)
    trajectory = stop.trajectory()
    where = running.at(handover)[0][0][0]
    assert where < trajectory.end <= START + 0.6 + 1e-9  # (late in the base, the motion's own end)
    assert at * 3.0 + trajectory.duration <= 3.0 + 1e-9
    t, a = streamed(running, trajectory)
    r = simulate(t, a, PARAMS)
    after = t > at * 3.0 + trajectory.duration + 0.1  # (the servo, tau 10 ms, settles on the end)
    assert np.abs(r.v[0, after]).max() < 1e-4 and np.abs(r.load_excursion[0, after]).max() < 1e-3
