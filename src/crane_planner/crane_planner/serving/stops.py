"""A running motion's stop without swing: the one the planner node and the streamer node both plan.

A stop takes over a running motion ``STOP_LEAD`` ahead (the handover), from
the crane's state there (``transitions.handover_state``: the running
reference, the swing predicted along it), by ``transitions.stop`` (an NVF
stop to rest anywhere, or a shaped motion's base braked and reshaped); its
trajectory is the plan's knots from the handover (``knots.knot_times``,
``knots.knot_columns``).

API (kept stable: both nodes build on it):

- ``STOP_LEAD``: how far ahead (s) of its request a stop takes over.
- ``plan_stop(variational, running, handover_ns, params, options=None, measured=None, method=None,
  state=None) -> Stop``: the stop of ``running`` (a ``transitions.Running``) taking over at
  ``handover_ns``. ``variational`` runs its ``VariationalRequest``s (``Planner.variational``, a
  ``SolverCache``); ``measured``: the newest ``transitions.Measurement`` (None: the model's swing);
  ``method``: default the running motion's (a shaped motion brakes its base, anything else stops by NVF);
  ``state``: the handover state if already predicted. PlanError (a ValueError) says why there is none.
- ``Stop``: ``plan`` (relative), ``state`` (at the handover), ``handover_ns``; ``starts`` (per joint, where
  the trajectory's positions start), ``end`` (where the cart stops, m), ``trajectory(times=None)`` (default
  the plan's knot times) -> ``StopTrajectory``.
- ``StopTrajectory``: ``t`` (s from the handover), ``position``, ``velocity``, ``acceleration`` ((knots,
  joints), absolute), ``handover_ns``, ``duration``, ``method``, ``end``; ``arrays()``: (t, p, v, a) as
  ``ReferenceStream.accept`` takes them.
- ``warmups(params, hoist=False, options=None, bridge=False) -> list[VariationalRequest]``: what builds a
  stop's solvers (``Planner.warmups``, or run on a ``SolverCache``); ``moving_state(params, joints)``: the
  moving, swinging state they start from.
- ``StopRequest(joints, interps, origin_ns, handover_ns, params, options=None)``: a stop of the streamer's
  motion (its ``QuinticHermite`` per joint, first knot at ``origin_ns``) as a worker process runs it:
  picklable, ``request(solvers) -> StopTrajectory``. ``StopRequest.rehearsal(joints, params, options=None)``:
  one of a made-up motion, a warm-up: in a worker, or called with a ``variational`` (``Planner.variational``)
  it builds the caller's swing prediction (CasADi, in the calling process) and the stop's solvers.
  ``StopWarmup(joints, params)``: the stop worker's lighter warm-up (``warmups`` and the prediction, at
  ``workers.WARM_NICE``).
- ``StopWorker(joints, params)``: the streamer's stop planner, a ``workers.SolverProcess`` started in the
  background: ``status``, ``ready``, ``lead`` (s: how far ahead the next stop takes over at first),
  ``stop(interps, origin_ns, now, params) -> StopTrajectory | None``
  (None: the motion ends before a stop could take over; PlanError: why there is no stop, the worker's state
  included), ``take_over(stream, now, params) -> StopTrajectory | None`` (the stop of what a
  ``ReferenceStream`` streams, accepted by it), ``close()``.

What loads CasADi (``transitions``: the swing prediction; ``dispatch``: the solvers) is imported inside
the functions that plan, never at the top: the streamer imports this module for ``StopWorker`` and
``StopRequest`` and must not load CasADi, its stops are planned in the worker. Pure Python, no ROS import.
"""
from __future__ import annotations

import os
import threading
from dataclasses import dataclass

import numpy as np

from crane_msgs_py.crane.params import CraneParams
from crane_msgs_py.messages.names import BRIDGE_JOINT, CART_JOINT, HOIST_JOINT
from crane_msgs_py.runtime.realtime import set_fifo

from ..planning.plan import PlanError
from ..streaming.hermite import QuinticHermite
from ..streaming.knots import knot_columns, knot_times
from ..streaming.stop_trajectory import StopTrajectory
from .workers import WARM_NICE, SolverProcess, start_fork_server

#: How far ahead (s) of its request a stop takes over (its NVF stop is planned in tens of milliseconds).
STOP_LEAD = 0.1
#: A stop's answer must be in this long (s) before its handover for the streamer to take it in time.
ANSWER_MARGIN = 0.005
#: How many times a stop whose answer came too late is planned again further ahead.
ATTEMPTS = 3
#: Longest wait (s) for a worker's answer: past it the stop is refused (the worker finishes it unheard).
ANSWER_TIMEOUT = 1.0


@dataclass(frozen=True)
class Stop:
    """A planned stop: the plan (relative), the state it starts from and its handover (ns of ROS time)."""

    plan: object
    state: object
    handover_ns: int

    @property
    def starts(self) -> list:
        from .transitions import joint_starts
        return joint_starts(self.plan, self.state)

    def trajectory(self, times=None) -> StopTrajectory:
        """The stop at ``times`` (s from the handover; default its knots)."""
        times = knot_times(self.plan) if times is None else np.asarray(times, dtype=float)
        columns = knot_columns(self.plan, times, self.starts)
        return StopTrajectory(times, *columns, self.handover_ns, float(self.plan.duration), self.plan.method)


def plan_stop(variational, running, handover_ns: int, params: CraneParams, options=None, measured=None,
              method: str | None = None, state=None) -> Stop:
    """The stop of ``running`` taking over at ``handover_ns``; see the module docstring."""
    from ..planning.dispatch import PlanOptions
    from . import transitions
    options = PlanOptions() if options is None else options
    if state is None:
        state = transitions.handover_state(running, handover_ns, measured, params)
    plan = transitions.stop(variational, running, handover_ns, state, running.method if method is None else method,
                            params, options)
    return Stop(plan, state, handover_ns)


def warmups(params: CraneParams, hoist: bool = False, options=None, bridge: bool = False) -> list:
    """``VariationalRequest``s that build the solvers a stop uses: NVF from a moving, swinging state to rest
    anywhere (``transitions.stop``'s request), with a hoist the hoisting crane's, with a ``bridge`` the spatial
    crane's (every axis of the crane planned together) and the planar crane's besides (a stop from a state in
    one vertical plane, of one axis's travel say, is solved on that plane: ``planning.straight``)."""
    from ..planning.continuation import first_period, problem_start
    from ..planning.dispatch import PlanOptions, VariationalRequest, hoisting_options
    from .transitions import stop_options
    options = stop_options(PlanOptions() if options is None else options)
    if hoist:
        options = hoisting_options(options)
    requests = []
    for spatial in (True, False) if bridge else (False,):
        state = moving_state(params, (CART_JOINT, *((BRIDGE_JOINT,) if spatial else ()),
                                      *((HOIST_JOINT,) if hoist else ())))
        start, model = problem_start(state, params)
        duration = first_period(model)
        # (as transitions' free end: the problem's scale)
        ends = {name: s.velocity * duration / 2 for name, s in state.axes.items()}
        displacement = ends[CART_JOINT] if len(ends) == 1 else ends
        requests.append(VariationalRequest('plan', 'nvf', displacement, duration, model, options, start, True))
    return requests


def moving_state(params: CraneParams, joints):
    """A made-up ``continuation.MotionState`` of the crane with ``joints`` (the cart's first) for warm-ups: the
    travel axes moving (0.1 m/s, 0.05 m/s^2), the hoist still at the model's L1, the load swinging in the
    direction of travel (theta, and with a bridge phi)."""
    from ..planning.continuation import AxisState, MotionState
    from ..planning.signals import Swing
    axes = {name: AxisState(params.L1) if name == HOIST_JOINT else AxisState(0.0, 0.1, 0.05) for name in joints}
    # the load lags the acceleration: theta > 0, phi < 0 (``Problem.initial_guess``); with a bridge out of the
    # vertical plane of the travel (phi not theta's), so that the coupled NLP is built, not the planar one
    out_of_plane = dict(phi1=-0.01, phi2=0.0, dphi1=0.05, dphi2=0.0) if BRIDGE_JOINT in axes else {}
    return MotionState(axes, Swing(theta1=0.02, dtheta1=-0.05, **out_of_plane))


@dataclass(frozen=True)
class StopRequest:
    """A stop of the streamer's motion as a worker process runs it (``workers.SolverProcess.solve``).

    Attributes:
        joints: the streamed joints, the cart's first.
        interps: the motion's ``QuinticHermite`` per joint (``reference_stream.Motion.interps``).
        origin_ns: ROS time of the motion's first knot.
        handover_ns: when the stop takes over.
        params: the crane model.
        options: ``dispatch.PlanOptions`` (None: the defaults).
    """

    joints: tuple
    interps: tuple
    origin_ns: int
    handover_ns: int
    params: CraneParams
    options: object = None

    def __call__(self, solvers) -> StopTrajectory:
        """The stop, planned on ``solvers`` (the worker's ``SolverCache``)."""
        from .transitions import Running
        running = Running.of_interps(self.joints, self.interps, self.origin_ns)
        return plan_stop(solvers, running, self.handover_ns, self.params, self.options).trajectory()

    @classmethod
    def rehearsal(cls, joints, params: CraneParams, options=None) -> 'StopRequest':
        """A stop 0.6 s into a made-up move (a quintic of 0.2 m in 2 s of every travel axis, the hoist held at the
        model's L1): a warm-up, so that the first real stop finds the stop's solvers (``warmups``) and the swing
        prediction built."""
        t = [0.0, 1.0, 2.0]  # (the quintic's knots: exact, its acceleration 0 at the middle)
        moving = QuinticHermite(t, [0.0, 0.1, 0.2], [0.0, 0.1875, 0.0], [0.0] * 3)
        held = QuinticHermite(t, [params.L1] * 3, [0.0] * 3, [0.0] * 3)
        interps = tuple(held if name == HOIST_JOINT else moving for name in joints)
        return cls(tuple(joints), interps, 0, 600_000_000, params, options)


@dataclass(frozen=True)
class StopWarmup:
    """A stop worker's warm-up, run by it as a request: the stop's solvers (``warmups``) and the swing
    prediction's integrator, built on a thread at ``workers.WARM_NICE`` so that the build yields the cores to
    everything else starting up (the planner's warm-up, the streamer's loop)."""

    joints: tuple
    params: CraneParams

    def __call__(self, solvers) -> None:
        thread = threading.Thread(target=self._build, args=(solvers,), name='stop-warmup')
        thread.start()
        thread.join()

    def _build(self, solvers) -> None:
        from .transitions import Running, handover_state
        try:
            os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), WARM_NICE)  # this thread only (Linux)
        except (AttributeError, OSError):
            pass
        for request in warmups(self.params, HOIST_JOINT in self.joints, bridge=BRIDGE_JOINT in self.joints):
            try:
                solvers(request)
            except Exception:  # (built on first use then)
                pass
        rehearsal = StopRequest.rehearsal(self.joints, self.params)
        handover_state(Running.of_interps(self.joints, rehearsal.interps, 0), rehearsal.handover_ns, None,
                       self.params)


class StopWorker:
    """The streamer's stops, planned in a worker process of their own (the streamer never loads CasADi).

    The worker starts in the background (a fork server that imports CasADi,
    then ``StopWarmup``: seconds), at normal
    scheduling whatever the starting thread's; one that died or failed to
    start is started again by the next ``stop``. One stop at a time.

    Args:
        joints: the streamed joints, the cart's first.
        params: the crane model of the rehearsal.
        start_timeout: longest wait (s) for the worker to be ready.
        answer_timeout: longest wait (s) for a stop's answer (``ANSWER_TIMEOUT``); past it the stop is refused
            and the streamer brakes instead.
    """

    def __init__(self, joints, params: CraneParams, start_timeout: float = 60.0,
                 answer_timeout: float = ANSWER_TIMEOUT):
        self.joints = tuple(joints)
        self.start_timeout, self.answer_timeout = start_timeout, answer_timeout
        self._worker: SolverProcess | None = None
        self._status = 'starting'
        self._closed = False
        self._busy = threading.Lock()
        self._took = 0.0  # how long (s) the last stop took to plan: the next one's lead is at least 1.5 times that
        start_fork_server()
        self._start(params)

    @property
    def status(self) -> str:
        """'ready', or what else the worker is (starting, failed, ended, busy)."""
        worker = self._worker
        if worker is not None and not worker.alive:
            return 'its process ended'
        return self._status

    @property
    def ready(self) -> bool:
        return self.status == 'ready'

    @property
    def lead(self) -> float:
        """How far ahead (s) of its request the next stop takes over at first (``stop``'s default lead, or 1.5
        times as long as the last stop took to plan): what the runway guard counts on."""
        return max(STOP_LEAD, 1.5 * self._took + ANSWER_MARGIN)

    def stop(self, interps, origin_ns: int, now, params: CraneParams,
             lead: float = STOP_LEAD) -> StopTrajectory | None:
        """The stop of the motion of ``interps`` (first knot at ``origin_ns``) taking over ``lead`` s after
        ``now()`` (ROS time, ns), or 1.5 times as long as the last stop took to plan if that is longer, planned in
        the worker, and again further ahead should its answer come too late for its handover. None if the
        motion ends first (it ends at rest by itself); PlanError says why there is no stop."""
        if not self._busy.acquire(blocking=False):
            raise PlanError('another stop is being planned')
        try:
            worker, status = self._worker, self.status
            if status != 'ready':
                if status == 'its process ended' or status.startswith('failed'):
                    self._restart(worker, params)
                raise PlanError(f'the stop planner process is not ready: {status}')
            end_ns = origin_ns + round((interps[0].t[-1] - interps[0].t[0]) * 1e9)
            lead = max(lead, 1.5 * self._took + ANSWER_MARGIN)
            for _ in range(ATTEMPTS):
                asked = now()
                handover = asked + round(lead * 1e9)
                if handover >= end_ns:
                    return None
                answer = self._solve(worker, StopRequest(self.joints, tuple(interps), origin_ns, handover, params),
                                     params)
                answered = now()
                self._took = (answered - asked) * 1e-9
                if answered < handover - ANSWER_MARGIN * 1e9:
                    return answer
                lead = max(2.0 * lead, 1.5 * self._took + ANSWER_MARGIN)
            raise PlanError(f'the stop planner answered too late for the handover {ATTEMPTS} times (last lead '
                            f'{lead / 2:.3f} s)')
        finally:
            self._busy.release()

    def take_over(self, stream, now, params: CraneParams) -> StopTrajectory | None:
        """Stop the motion ``stream`` (a ``reference_stream.ReferenceStream``) streams: its ``stop``, accepted
        by the stream as its handover (None: the motion ends first). PlanError or the stream's ValueError says
        why not."""
        motion = stream.last_motion
        if motion is None or not stream.streaming:
            raise PlanError('no motion is streaming')
        trajectory = self.stop(motion.interps, motion.origin_ns, now, params)
        if trajectory is not None:
            stream.accept(*trajectory.arrays(), trajectory.handover_ns, now())
        return trajectory

    def close(self) -> None:
        """Stop the worker (idempotent); a start under way ends it once it is up."""
        self._closed = True
        if self._worker is not None:
            self._worker.close()

    def _solve(self, worker: SolverProcess, request: StopRequest, params: CraneParams) -> StopTrajectory:
        try:
            return worker.solve(request, self.answer_timeout)
        except PlanError:
            if worker.closed:  # it died
                self._restart(worker, params)
            elif worker.late:  # its answer is dropped once in; no stop is asked of it meanwhile
                self._status = 'busy with a stop that took too long'
                threading.Thread(target=self._finish_late, args=(worker, params), daemon=True).start()
            raise
        except RuntimeError as exc:  # a bug in the worker's planning: it lives on
            raise PlanError(f'the stop planner failed: {exc}') from None

    def _finish_late(self, worker: SolverProcess, params: CraneParams) -> None:
        worker.finish_late()
        if worker.closed:
            self._restart(worker, params)
        else:
            self._status = 'ready'

    def _restart(self, worker: SolverProcess | None, params: CraneParams) -> None:
        if worker is not None:
            worker.close(kill=True)
        self._worker = None
        self._start(params)

    def _start(self, params: CraneParams) -> None:
        self._status = 'starting'
        threading.Thread(target=self._started, args=(params,), name='stop-worker', daemon=True).start()

    def _started(self, params: CraneParams) -> None:
        # the fork server and its workers inherit this thread's scheduling: never the caller's SCHED_FIFO
        set_fifo(0)
        try:
            worker = SolverProcess((), self.start_timeout)
        except Exception as exc:  # (PlanError: not ready in time; OSError: no process)
            self._status = f'failed to start: {exc}'
            return
        try:  # the warm-up as a request (SolverProcess's own warm-ups are VariationalRequests, read here)
            worker.solve(StopWarmup(self.joints, params), self.start_timeout)
        except (PlanError, RuntimeError):  # a failed warm-up only means building on first use
            if worker.late:
                worker.finish_late()  # (a dead worker shows in ``status``)
        if self._closed:
            worker.close()
            return
        self._worker, self._status = worker, 'ready'
