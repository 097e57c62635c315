"""``crane-demo``: the paper's experiment end to end over ROS 2.

Starts the planner, streamer and sim nodes in one namespace of a private ROS
graph, then for every case (nominal plant, L1 = 0.42 m as in paper §5.2, each
with and without Ethernet-like impairment; and ``commission``: a plant the
planner does not know, measured with noise, identified from one excitation
move, then planned for) and every method requests a move over the planner
service, lets the streamer stream it at 1 kHz, and measures the residual load
swing from the sim's 50 Hz joint_states. The ``spatial`` case (the cart and
the bridge together, the load swinging in x and y) is computed offline once
the nodes have stopped, planned by ``dispatch.plan`` and replayed in
crane_sim's batch spatial model (``spatial_demo``: the nodes' bridge path is
the ROS tests'): 0.3 m x 0.2 m in 3 s by every method on the model's plant
and on one with L1 -10 %, and a fast 1.0 m x 0.8 m diagonal in 2.2 s by NVF
on the coupled model, ZV, and two planar NVF plans (one per axis) played
together, its residual the norm of the load's horizontal offset over 4 s
(figure demo_spatial.png: the diagonal from above and its swing). Prints one
table, writes figures, stops every node it started. Exit status 0, 1 when a
node fails to come up or dies (the reason on stderr), 2 on bad options.
"""
from __future__ import annotations

import argparse
import json
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from crane_msgs_py.crane.params import PARAMETER_NAMES, CraneParams
from crane_msgs_py.messages.names import CART_JOINT, HOIST_JOINT
from crane_msgs_py.runtime.realtime import DIE_WITH_PARENT

from .harness import CraneHarness, HarnessError, start_crane_nodes, state_columns
from .processes import NodeDied, NodeGroup, find_executable, isolated_graph

PROG = 'crane-demo'
DEMO_METHODS = ('nvf', 'rvf', 'zv', 'nzv', 'zvd')
#: Paper §5.2: the upper cable shortened to 0.42 m.
PERTURBED_L1 = 0.42
#: An Ethernet link to a closed controller: a few ms of delay with jitter, rare losses.
NETWORK = {'network.delay': 0.002, 'network.jitter': 0.0005, 'network.distribution': 'normal',
           'network.loss': 0.01}
NETWORK_OFF = {'network.delay': 0.0, 'network.jitter': 0.0, 'network.loss': 0.0}


#: The operator case's stick (crane-teleop --script): forward 0.2 m/s, then lifting 0.05 m/s while
#: travelling, released; run with the streamer's operator_shaper zv, and none (rate limits only).
OPERATOR_SCRIPT, OPERATOR_SHAPERS = '0.2:1 0.2,0.05:2', ('zv', 'none')
#: The retarget case's new goal: this much beyond the move's, at this fraction of its duration.
RETARGET_EXTRA, RETARGET_AT, STOP_AT = 0.2, 0.4, 0.5
#: The settle case: how long the pushed load swings before ~/settle, and when after it the residual counts.
SETTLE_AFTER_PUSH, SETTLE_WITHIN = 1.0, 3.0

#: The hoisting cases: the upper cable from 0.47 to 0.27 m (m) while the cart travels, in this long (s),
#: and the move back: long enough for the hoisting NLP to converge readily (a shorter one does not: see the README).
HOIST, HOIST_DURATION, HOIST_RETURN = (0.47, 0.27), 3.0, 1.5

#: The commissioning case's crane: unknown to the planner (L1 +12 %, L2 -10 %, m2 +15 %: the mass
#: ratio 0.511 -> 0.546), with a little joint damping and a slower servo than the model's.
UNKNOWN_PLANT = CraneParams(L1=0.47 * 1.12, L2=0.391 * 0.90, m2=0.201 * 1.15, c1=0.002, c2=0.0005, tau=0.015)
#: Standard deviation (rad) of the sim's angle noise while the commissioning move is recorded.
COMMISSION_NOISE = 1e-3
#: The commissioning excitation: a quintic of the run's displacement in this long (s), and the
#: free swing recorded after it (s): fast enough to swing both modes, long enough for 4 slow periods.
EXCITATION_DURATION, EXCITATION_RECORD = 1.0, 8.0


@dataclass(frozen=True)
class Case:
    name: str
    plant: CraneParams  # the sim's, the true crane
    network: bool
    commission: bool = False  # first plan with the planner's model, identify, then plan again
    hoist: tuple | None = None  # (L1 start, L1 goal) m: the rope moves during the motion (nodes with a hoist)
    #: what is measured: 'move' (a planned move from rest), or motion from any state: 'retarget', 'stop',
    #: 'settle', 'operator'; 'spatial': the cart and the bridge, offline (``spatial_demo``, no nodes); 'route':
    #: moves past protected areas and through a via point, offline (``route_demo``, no nodes); 'feedback': the
    #: streamer's sway feedback off and on, each on nodes of its own (``feedback_demo``); 'runway': two cranes on
    #: one runway, on nodes of their own (``runway_demo``)
    kind: str = 'move'
    #: the methods this case runs by default (of --methods; every one of them with --cases all), None = all;
    #: the operator case's are operator_shaper values
    methods: tuple | None = None
    hoisting_nodes: bool = False  # runs on the nodes with a hoist (the operator case's stick lifts the load)

    @property
    def L1(self) -> float:
        return self.plant.L1

    @property
    def on_nodes(self) -> bool:
        """Whether the case runs on the demo's nodes (all but the offline spatial and route cases, and the feedback
        and runway cases on nodes of their own)."""
        return self.kind not in ('spatial', 'route', 'feedback', 'runway')


CASES = {
    'nominal': Case('nominal', CraneParams(), False),
    'perturbed': Case('perturbed', CraneParams(L1=PERTURBED_L1), False),
    'nominal+net': Case('nominal+net', CraneParams(), True, methods=('rvf', 'zv', 'zvd')),
    'perturbed+net': Case('perturbed+net', CraneParams(L1=PERTURBED_L1), True),
    'commission': Case('commission', UNKNOWN_PLANT, False, commission=True),
    # hoisting: 0.3 m of travel while lifting the load by 0.2 m, on the model's plant and on one whose
    # payload hangs 20 % lower than the model says
    'hoist': Case('hoist', CraneParams(), False, hoist=HOIST, methods=('rvf', 'zv', 'zvd')),
    'hoist+L2': Case('hoist+L2', CraneParams(L2=0.391 * 1.2), False, hoist=HOIST, methods=('rvf', 'zv')),
    # motion from any state: a new goal (0.2 m further) at 40 % of the move, a cancel at 50 % (the stop is
    # NVF's), a 30 mm push damped by ~/settle, and a scripted stick (forward, lifting while travelling, release)
    'retarget': Case('retarget', CraneParams(), False, kind='retarget', methods=('rvf', 'zv')),
    'stop': Case('stop', CraneParams(), False, kind='stop', methods=('rvf', 'zv')),
    'settle': Case('settle', CraneParams(), False, kind='settle', methods=('nvf',)),
    'operator': Case('operator', CraneParams(), False, kind='operator', methods=OPERATOR_SHAPERS,
                     hoisting_nodes=True),
    # the spatial crane, offline: every method on 0.3 x 0.2 m (nominal, L1 -10 %), and a fast diagonal by
    # coupled NVF, ZV and NVF per plane (the plants and moves are spatial_demo's)
    'spatial': Case('spatial', CraneParams(), False, kind='spatial'),
    # protected areas, offline: a wall the load is lifted over, a column it goes around, a via point
    # (``route_demo``); the shapers go straight, so the planner refuses them here (NVF and RVF route)
    'route': Case('route', CraneParams(), False, kind='route', methods=('nvf', 'rvf', 'zv')),
    # closed-loop sway control: the perturbed crane (NVF, ZV), a push during an NVF move, wind and gusts at rest,
    # each with the streamer's feedback off and on (``feedback_demo``: the situations, the table, the figure)
    'feedback': Case('feedback', CraneParams(), False, kind='feedback', methods=('nvf', 'zv')),
    # cranes sharing a runway: two cranes' goals sent together (ZV, then NVF back), one waits for the other, then
    # an operator drives one into the other's way and its guard stops it (``runway_demo``)
    'runway': Case('runway', CraneParams(), False, kind='runway', methods=('zv', 'nvf')),
}
#: What runs without --cases: every case but perturbed+net (nothing perturbed and nominal+net do not show
#: between them), so that make demo, hoisting, motion from any state and the spatial case included, stays
#: short (docs/benchmarks.md has its time);
#: --cases all runs every one, with every method.
DEFAULT_CASES = tuple(name for name in CASES if name != 'perturbed+net')
#: Table columns of the commission case: before and after identification.
BEFORE, AFTER = 'commission:model', 'commission:identified'


@dataclass
class Run:
    """One measured motion."""

    case: str
    method: str
    plan_time_s: float
    peak_acceleration: float
    residual_mm: float
    action_residual_mm: float                     # the ExecuteMove result's residual_swing (planner's model)
    t: np.ndarray = field(repr=False)             # joint_states times (s) from the motion start
    load_mm: np.ndarray = field(repr=False)       # load excursion (mm) at those times
    plan_t: np.ndarray = field(repr=False)        # served plan: knot times (s)
    plan_v: np.ndarray = field(repr=False)
    plan_a: np.ndarray = field(repr=False)
    rope: np.ndarray | None = field(default=None, repr=False)  # the upper cable's length (m) at ``t`` (hoisting)

    def row(self) -> dict:
        return {'case': self.case, 'method': self.method, 'plan_time_s': self.plan_time_s,
                'peak_acceleration': self.peak_acceleration, 'residual_mm': self.residual_mm,
                'action_residual_mm': self.action_residual_mm}


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog=PROG, description=__doc__.splitlines()[0].split(': ', 1)[1])
    p.add_argument('--methods', metavar='M,M,...',
                   help=f'methods every case runs (default {",".join(DEMO_METHODS)}, some cases a few of them)')
    p.add_argument('--cases', default=','.join(DEFAULT_CASES), metavar='C,C,...',
                   help=f'cases to run, from {",".join(CASES)}, or all (default {",".join(DEFAULT_CASES)})')
    p.add_argument('--displacement', type=float, default=0.3, metavar='D', help='cart move (m), default 0.3')
    p.add_argument('--duration', type=float, default=2.5, metavar='T', help='motion time (s), default 2.5 (paper §5)')
    p.add_argument('--settle', type=float, default=2.0, metavar='S',
                   help='seconds of swing observed after each motion (default 2.0, more than the slow '
                        "mode's 1.73 s period)")
    # not 1.0: from the warm start of a 3 s move, NVF's 0.3 m in 1 s takes an order of magnitude more IPOPT
    # iterations than in 1.5 s, enough to run past the planner's max_solve_time on a loaded machine and fail
    # the demo
    p.add_argument('--return-duration', type=float, default=1.5, metavar='T',
                   help='time (s) of the unmeasured move back between runs, starting as the observation '
                        'ends (default 1.5)')
    p.add_argument('--out', default='out', help='folder for figures and results (default out)')
    p.add_argument('--namespace', default='/crane_demo', help='namespace of the three nodes')
    p.add_argument('--domain-id', type=int, help='ROS_DOMAIN_ID (default: random, with localhost discovery)')
    p.add_argument('--sweep-points', type=int, default=25, metavar='N',
                   help='points of the L1 +-30 %% sweep figure (crane-plan sweep), 0 = skip (default 25)')
    p.add_argument('--no-figures', action='store_true', help='write results.json only')
    record = p.add_mutually_exclusive_group()
    record.add_argument('--record', metavar='DIR',
                        help='rosbag2 (MCAP) recording of reference, joint_states, trajectory, /diagnostics and '
                             'crane_markers (default OUT/recording, replaced if there)')
    record.add_argument('--no-record', action='store_true', help='record nothing')
    p.add_argument('--startup-timeout', type=float, default=90.0, metavar='S',
                   help='seconds for the nodes to come up and the planner to build its solvers (default 90)')
    return p


def _parse(argv) -> argparse.Namespace:
    parser = build_parser()
    args = parser.parse_args(argv)
    from crane_planner.planning import METHODS
    given = args.methods is not None
    methods = [m.strip() for m in (args.methods if given else ','.join(DEMO_METHODS)).split(',') if m.strip()]
    cases = [c.strip() for c in args.cases.split(',') if c.strip()]
    every_case = cases == ['all']
    args.every = every_case or given  # every method in every case (settle: nvf/rvf only)
    cases = list(CASES) if every_case else cases
    bad = [m for m in methods if m not in METHODS] + [c for c in cases if c not in CASES]
    if bad or not methods or not cases:
        parser.exit(2, f'{PROG}: error: unknown method or case {", ".join(bad) or "(none given)"}\n')
    for name in ('displacement', 'duration', 'settle', 'return_duration'):
        value = getattr(args, name)
        if not np.isfinite(value) or (value <= 0 and name != 'displacement') or value == 0:
            parser.exit(2, f'{PROG}: error: argument --{name.replace("_", "-")}: bad value {value}\n')
    args.methods, args.cases = methods, [CASES[c] for c in cases]
    return args


def progress(text: str):
    print(f'[{PROG}] {text}', file=sys.stderr, flush=True)


def run_case_method(driver: CraneHarness, case: Case, method: str, args, name: str | None = None) -> Run:
    D, T = args.displacement, (HOIST_DURATION if case.hoist else args.duration)
    back_hoist = None if case.hoist is None else case.hoist[::-1]
    start_ns, plan_time, _ = driver.move(method, 0.0, D, T, settle=args.settle, hoist=case.hoist)
    end_ns = start_ns + round((T + args.settle) * 1e9)
    t, load, rope, residual = _window_residual(driver, case, start_ns, start_ns, start_ns + round(T * 1e9), end_ns)
    action_residual = driver.move_result(start_ns).residual_swing  # what the caller of the action is told
    plan_t, plan_v, plan_a, peak = _served(driver, start_ns)
    # The swing zeroed before the move back (the simulated crane has no damping to wait for), so that it starts
    # from rest: sent while the load swings, it would be planned from the swing, a harder problem than this
    # housekeeping needs.
    driver.reset_sim()
    back_duration = args.return_duration if case.hoist is None else max(args.return_duration, HOIST_RETURN)
    # (its result after a brief watch: nothing is measured of it, and none is left pending at the end)
    back_ns, _, _ = driver.move('nvf', D, 0.0, back_duration, hoist=back_hoist, settle=0.05)
    back_end_ns = back_ns + round((back_duration + 0.05) * 1e9)
    driver.sleep((back_end_ns - driver.now_ns()) * 1e-9)
    driver.move_result(back_ns)
    driver.wait_for_state_after(back_end_ns)
    driver.reset_sim()
    return Run(name or case.name, method, plan_time, peak, residual, 1e3 * action_residual, t, load, plan_t, plan_v,
               plan_a, rope=rope)


def case_methods(case: Case, methods, every: bool = False) -> list[str]:
    """The methods ``case`` runs: its own of ``methods``, or (``every``: --cases all) all of them; the
    operator case's operator_shaper values always."""
    if case.kind == 'operator':
        return list(case.methods)
    if case.kind == 'settle':  # a shaper cannot settle
        return [m for m in methods if m in (('nvf', 'rvf') if every else case.methods)]
    return [m for m in methods if every or case.methods is None or m in case.methods]


def _window_residual(driver: CraneHarness, case: Case, begin_ns: int, origin_ns: int, after_ns: int, end_ns: int):
    """(t from ``origin_ns`` s, load mm, rope or None, residual mm over [after, end]) of joint_states in
    [begin, end], the load's excursion with the rope length they carry (a hoist), else the plant's L1."""
    from crane_msgs_py.crane.geometry import load_excursion
    from crane_sim.metrics import residual_load_mm
    # a 50 Hz sample past the window; the timeout only guards against a hang: on a busy host the sim's plant
    # time (joint_states' stamps) may run seconds behind the clock, and catches up
    rec = driver.states_between(begin_ns, end_ns + 50_000_000, timeout=30.0)
    if len(rec) < 10:
        raise HarnessError(f'only {len(rec)} joint_states in the {case.name} case: is the sim publishing?')
    c = state_columns(rec)
    t = (c['stamp'] - origin_ns) * 1e-9
    rope = c[HOIST_JOINT] if np.isfinite(c[HOIST_JOINT]).all() else None  # the hoist's position is L1
    L1 = case.plant.L1 if rope is None else rope
    residual = float(residual_load_mm(t, c['theta1'], c['theta2'], L1, case.plant.L2,
                                      after=(after_ns - origin_ns) * 1e-9, until=(end_ns - origin_ns) * 1e-9))
    return t, 1e3 * load_excursion(c['theta1'], c['theta2'], L1, case.plant.L2), rope, residual


def _served(driver: CraneHarness, stamp_ns: int):
    """(t, v, a) of the trajectory stamped ``stamp_ns`` as the streamer plays it, and its peak |a|: the peaks
    lie between knots (a ZVD base motion of 76 ms starts and ends at rest: its knots carry no acceleration)."""
    from crane_msgs_py.messages.conversions import joint_trajectory_to_arrays
    t, p, v, a = _dense(*joint_trajectory_to_arrays(driver.trajectory(stamp_ns)))
    return t, v, a, float(np.max(np.abs(a)))


def _end_of(driver: CraneHarness, stamp_ns: int) -> int:
    end = driver.trajectory(stamp_ns).points[-1].time_from_start
    return stamp_ns + end.sec * 1_000_000_000 + end.nanosec


def _home(driver: CraneHarness, args, hoist: float | None = None, duration: float | None = None):
    """Back to the cart at 0 (and the rope at ``hoist``) from wherever the streamer holds them, then the
    sim reset (no damping to wait for)."""
    duration = duration or (max(args.return_duration, HOIST_RETURN) if hoist is not None else args.return_duration)
    back, _, _ = driver.move('nvf', None, 0.0, duration, settle=0.05, hoist=None if hoist is None else (None, hoist))
    driver.move_result(back)  # (its result after a brief watch, not the default settle: nothing is measured)
    driver.reset_sim()


def run_any_state(driver: CraneHarness, case: Case, method: str, args) -> Run:
    """One run of a motion-from-any-state case: the residual after the new goal's motion, the
    stop, the settle, or the released stick."""
    D, T, settle = args.displacement, args.duration, args.settle
    if case.kind in ('retarget', 'stop'):
        start, _, _ = driver.move(method, 0.0, D, T, settle=settle)
        at = RETARGET_AT if case.kind == 'retarget' else STOP_AT
        driver.sleep(max(0.0, (start + round(at * T * 1e9) - driver.now_ns()) * 1e-9))
        asked = driver.now_ns()
        if case.kind == 'retarget':
            event = driver.retarget(method, D + RETARGET_EXTRA, T, settle=settle)
            driver.outcome(start)  # preempted
            action = driver.move_result(event).residual_swing
        else:
            _, result = driver.cancel(start)  # after the stop and its settle window
            event = [s for s in driver.sent_trajectories() if s > start][-1]
            action = result.residual_swing
        plan_time = (event - asked) * 1e-9  # from the request to the handover
        end = _end_of(driver, event)
        t, load, rope, residual = _window_residual(driver, case, start, start, end, end + round(settle * 1e9))
        plan_t, plan_v, plan_a, peak = _served(driver, event)
        plan_t = plan_t + (event - start) * 1e-9
        _home(driver, args)
    elif case.kind == 'settle':
        driver.set_parameters('planner', {'settle_method': method})
        driver.push_sim()
        driver.sleep(SETTLE_AFTER_PUSH)
        called = driver.now_ns()
        event, _ = driver.settle()
        plan_time = (event - called) * 1e-9
        end = called + round((SETTLE_WITHIN + settle) * 1e9)
        driver.sleep(max(0.0, (end - driver.now_ns()) * 1e-9))
        t, load, rope, residual = _window_residual(driver, case, called - round(SETTLE_AFTER_PUSH * 1e9), called,
                                                   called + round(SETTLE_WITHIN * 1e9), end)
        plan_t, plan_v, plan_a, peak = _served(driver, event)
        plan_t = plan_t + (event - called) * 1e-9
        action = float('nan')
        driver.reset_sim()
    else:  # the operator's stick, shaped online by the streamer (method: its operator_shaper)
        driver.set_parameters('streamer', {'mode': 'operator', 'operator_shaper': method})
        driver.sleep(0.2)
        begin = driver.now_ns()
        tool = driver.run_tool('crane-teleop', '--namespace', args.namespace, f'--script={OPERATOR_SCRIPT}')
        if tool.wait(timeout=30.0) != 0:
            raise HarnessError(f'crane-teleop failed: {tool.stderr.read().strip()}')
        released = driver.now_ns()
        plan_time = 0.0
        after = released + round(2.5e9)  # the stick's braking and the shaper played out, with time to spare
        end = after + round(settle * 1e9)
        driver.sleep(max(0.0, (end - driver.now_ns()) * 1e-9 + 0.3))
        t, load, rope, residual = _window_residual(driver, case, begin, begin, after, end)
        plan_t = plan_v = plan_a = np.zeros(0)
        peak, action = float('nan'), float('nan')
        driver.set_parameters('streamer', {'mode': 'trajectory'})
        driver.sleep(0.2)
        _home(driver, args, hoist=HOIST[0], duration=3.0)  # 0.6 m back with the rope: the default return is too short
    return Run(case.name, method, plan_time, peak, residual, 1e3 * action, t, load, plan_t, plan_v, plan_a, rope=rope)


def _dense(t, p, v, a, step: float = 2e-4):
    """The served trajectory sampled every ``step`` s by the streamer's quintic Hermite interpolation."""
    from crane_planner.streaming.hermite import QuinticHermite
    grid = np.union1d(np.arange(t[0], t[-1], step), t)
    return (grid, *QuinticHermite(t, p, v, a)(grid))


def commission(driver: CraneHarness, args, model: CraneParams):
    """Stream one excitation move with the sim's noise on, record joint_states, identify: (Recording, Identification).

    The excitation is a quintic of ``args.displacement`` in EXCITATION_DURATION s
    sent by the driver itself (no method plans a move meant to swing); the
    reference beside the measured cart gives tau. Then the cart goes back.
    """
    from crane_planner.identification import Recording, identify
    from crane_planner.planning.plan import Samples
    from crane_planner.planning.profiles import quintic

    D, T = args.displacement, EXCITATION_DURATION
    t = np.linspace(0.0, T, 11)  # a quintic: Hermite between any knots is exact
    samples = Samples(t, *quintic(t, D, T))
    driver.set_parameters('sim', {'noise': COMMISSION_NOISE})
    start_ns = driver.send(samples, 0.0, 'the excitation')
    end_ns = start_ns + round((T + EXCITATION_RECORD) * 1e9)
    c = state_columns(driver.states_between(start_ns, end_ns, timeout=T + EXCITATION_RECORD + 10.0))
    driver.set_parameters('sim', {'noise': 0.0})
    driver.reset_sim()  # the swing the excitation left zeroed: the move back starts from rest
    back_ns, _, _ = driver.move('nvf', D, 0.0, args.return_duration, settle=0.05)
    t_rec = (c['stamp'] - start_ns) * 1e-9
    recording = Recording(t_rec, c[CART_JOINT], c['theta1'], c['theta2'], quintic(t_rec, D, T)[0])
    result = identify(recording, model)
    back_end_ns = back_ns + round((args.return_duration + 0.05) * 1e9)
    driver.sleep((back_end_ns - driver.now_ns()) * 1e-9)
    driver.move_result(back_ns)
    driver.wait_for_state_after(back_end_ns)
    driver.reset_sim()
    return recording, result


def columns(cases) -> list[str]:
    """Table columns: one per case, two for the commission case (before and after identification), three for
    the spatial case (``spatial_demo.COLUMNS``); none for the feedback case (a table of its own)."""
    from .route_demo import COLUMNS as ROUTE_COLUMNS
    from .spatial_demo import COLUMNS
    return [name for c in cases
            for name in ((BEFORE, AFTER) if c.commission else COLUMNS if c.kind == 'spatial'
                         else ROUTE_COLUMNS if c.kind == 'route' else () if c.kind in ('feedback', 'runway')
                         else (c.name,))]


def _describe(identified) -> str:
    v = identified.values
    return (f'L1 {v["L1"]:.4f} m, L2 {v["L2"]:.4f} m, mass ratio {v["mass_ratio"]:.3f}, zeta {v["zeta1"]:.4f}/'
            f'{v["zeta2"]:.4f}, tau {v["tau"]:.4f} s (truth L1 {UNKNOWN_PLANT.L1:.4f}, L2 {UNKNOWN_PLANT.L2:.4f}, '
            f'mass ratio {UNKNOWN_PLANT.m2 / (UNKNOWN_PLANT.m1 + UNKNOWN_PLANT.m2):.3f}, tau {UNKNOWN_PLANT.tau:g})')


def print_table(runs: list[Run], cases, methods):
    from .spatial_demo import SETTLE
    width = 32
    print('cells: peak reference acceleration (m/s^2) | residual load swing (mm) measured by the demo | '
          'as the ExecuteMove result reports it (mm) | plan round trip (ms); retarget/stop: after the new goal\'s or '
          "the stop's motion, the time from the request to the handover, settle: 3 s after ~/settle, operator: the "
          "streamer's operator_shaper, 2.5 s after the stick is released; spatial: offline (crane_sim's spatial "
          f"model), the norm of the load's horizontal offset over {SETTLE:g} s after the motion, the peak of the "
          "horizontal acceleration's norm, the planning time, no ExecuteMove result (nan)")
    by_key = {(r.case, r.method): r for r in runs}
    methods = list(methods) + [m for m in dict.fromkeys(r.method for r in runs) if m not in methods]
    first = max(8, *(len(m) + 1 for m in methods))  # the spatial case's nvf/plane is longer than a method
    print(f'{"method":<{first}}' + ''.join(f'{c:>{width}}' for c in columns(cases)))
    for m in methods:
        cells = []
        for c in columns(cases):
            r = by_key.get((c, m))
            cells.append(f'{r.peak_acceleration:6.3f} |{r.residual_mm:7.2f} |{r.action_residual_mm:7.2f} |'
                         f'{1e3 * r.plan_time_s:5.0f}'
                         if r else '-')
        print(f'{m:<{first}}' + ''.join(f'{cell:>{width}}' for cell in cells))


def write_figures(runs: list[Run], args, timing_log: Path | None, spatial: list | None = None) -> list[Path]:
    """Every figure of the cases run (``spatial``: the spatial case's ``SpatialRun`` records, if it ran)."""
    from .figures import plt, save_figure  # headless (Agg) matplotlib

    out = Path(args.out)
    written = []
    on_nodes = [c for c in args.cases if c.on_nodes]
    moves = [c for c in on_nodes if c.kind == 'move'] or on_nodes
    if moves:  # the plans the streamer served (the spatial case's have their own figure)
        first_case = columns(moves)[0]
        fig, axes = plt.subplots(2, 1, figsize=(9, 7), sharex=True)
        for r in runs:
            if r.case == first_case:
                axes[0].plot(r.plan_t, r.plan_v, label=r.method.upper())
                axes[1].plot(r.plan_t, r.plan_a, label=r.method.upper())
        axes[0].set_ylabel('reference velocity (m/s)')
        axes[1].set_ylabel('reference acceleration (m/s²)')
        axes[1].set_xlabel('time (s)')
        axes[0].set_title(f'served plans: {args.displacement:g} m in {args.duration:g} s (paper Figs. 2-3)')
        for ax in axes:
            ax.grid(True, alpha=0.3)
            ax.legend(ncol=5, fontsize=8)
        written.append(save_figure(fig, out / 'demo_plans.png'))

    panels = [(name, case) for case in args.cases if case.kind == 'move'
              for name in ((BEFORE, AFTER) if case.commission else (case.name,))]
    if panels:
        n = len(panels)
        fig, axes = plt.subplots(n, 1, figsize=(9, 2.6 * n + 0.6), sharex=True, squeeze=False)
        for ax, (name, case) in zip(axes[:, 0], panels):
            for r in runs:
                if r.case == name:
                    ax.plot(r.t, r.load_mm, label=f'{r.method.upper()} ({r.residual_mm:.2f} mm)')
            ax.axvline(HOIST_DURATION if case.hoist else args.duration, color='k', lw=0.6, ls=':')
            ax.set_ylabel('load (mm)')
            if case.commission:
                title = (f'{name}: unknown crane (L1 {case.plant.L1:.3f}, L2 {case.plant.L2:.3f} m), planned with '
                         + ('the Table 1 model' if name == BEFORE else 'the identified model'))
            elif case.hoist:
                title = (f'{name}: hoisting L1 {case.hoist[0]:g} -> {case.hoist[1]:g} m while travelling, L2 '
                         f'{case.plant.L2:.3f} m' + (' (the model: 0.391 m)' if case.plant.L2 != 0.391 else ''))
            else:
                title = f'{name}: L1 = {case.L1:g} m' + (', network impairment' if case.network else '')
            ax.set_title(title, fontsize=10)
            ax.set_ylim(-12, 12)
            ax.grid(True, alpha=0.3)
            ax.legend(ncol=3, fontsize=7)
        axes[-1, 0].set_xlabel('time from motion start (s); measured at 50 Hz (paper Figs. 6-15)')
        written.append(save_figure(fig, out / 'demo_swing.png'))

    any_state = [case for case in on_nodes if case.kind != 'move']
    if any_state:  # motion from any state: the swing around the event (the handover, the cancel, ~/settle, the stick)
        fig, axes = plt.subplots(len(any_state), 1, figsize=(9, 2.7 * len(any_state) + 0.6), squeeze=False)
        titles = {'retarget': f'retarget: {args.displacement:g} m, a goal {RETARGET_EXTRA:g} m further at '
                              f'{100 * RETARGET_AT:g} % (dotted: the handover)',
                  'stop': f'stop: the goal canceled at {100 * STOP_AT:g} % (dotted: the stop takes over)',
                  'settle': f'settle: a {1e3 * 0.03:g} mm push, ~/settle {SETTLE_AFTER_PUSH:g} s later (t = 0)',
                  'operator': f'operator: crane-teleop --script "{OPERATOR_SCRIPT}" (lifting while travelling), '
                              'shaped online vs rate limits only'}
        for ax, case in zip(axes[:, 0], any_state):
            for r in runs:
                if r.case == case.name:
                    ax.plot(r.t, r.load_mm, label=f'{r.method.upper()} ({r.residual_mm:.2f} mm)')
                    if r.plan_t.size:
                        ax.axvline(r.plan_t[0], color='k', lw=0.6, ls=':')
            ax.set_title(titles[case.kind], fontsize=10)
            ax.set_ylabel('load (mm)')
            ax.grid(True, alpha=0.3)
            ax.legend(ncol=3, fontsize=7)
        axes[-1, 0].set_xlabel('time (s), measured at 50 Hz')
        written.append(save_figure(fig, out / 'demo_any_state.png'))

    hoisting = [case for case in args.cases if case.hoist]
    if hoisting:  # swing and rope length over time, per hoisting case
        fig, axes = plt.subplots(2, len(hoisting), figsize=(6 * len(hoisting), 6.5), sharex=True, squeeze=False)
        for col, case in enumerate(hoisting):
            for r in runs:
                if r.case == case.name and r.rope is not None:
                    axes[0, col].plot(r.t, r.load_mm, label=f'{r.method.upper()} ({r.residual_mm:.2f} mm)')
                    axes[1, col].plot(r.t, r.rope, label=r.method.upper())
            axes[0, col].set_title(f'{case.name}: L2 {case.plant.L2:.3f} m', fontsize=10)
            axes[0, col].set_ylabel('load swing (mm)')
            axes[1, col].set_ylabel('rope length L1 (m), measured')
            axes[1, col].set_xlabel('time from motion start (s)')
            for ax in axes[:, col]:
                ax.axvline(HOIST_DURATION, color='k', lw=0.6, ls=':')
                ax.grid(True, alpha=0.3)
            axes[0, col].legend(ncol=2, fontsize=7)
        fig.suptitle(f'{args.displacement:g} m of travel while hoisting {HOIST[0]:g} -> {HOIST[1]:g} m in '
                     f'{HOIST_DURATION:g} s', fontsize=11)
        written.append(save_figure(fig, out / 'demo_hoist.png'))

    if timing_log and timing_log.exists():
        lateness = np.asarray(json.loads(timing_log.read_text()).get('lateness_us', []), dtype=float)
        if lateness.size:
            fig, ax = plt.subplots(figsize=(8, 4.5))
            ax.hist(lateness, bins=200, log=True)
            p50, p99 = np.percentile(lateness, [50, 99])
            ax.set_title(f'streamer tick lateness: {lateness.size} ticks, p50 {p50:.0f} µs, '
                         f'p99 {p99:.0f} µs, max {lateness.max():.0f} µs', fontsize=10)
            ax.set_xlabel('lateness of the tick (µs)')
            ax.set_ylabel('ticks')
            written.append(save_figure(fig, out / 'demo_tick_timing.png'))
    if spatial:
        from .spatial_demo import plot_spatial
        written.append(plot_spatial(spatial, out / 'demo_spatial.png'))
    return written


def run_spatial_case(args) -> tuple[list[Run], list]:
    """The spatial case, offline (``spatial_demo.run_spatial``, after the nodes have stopped so that the solvers
    do not share the cores with the stream): its table rows as Runs (no ExecuteMove result: nan) and its
    ``SpatialRun`` records for the figure."""
    from .spatial_demo import run_spatial
    progress('spatial case: planned and simulated offline (crane_sim\'s spatial model, no nodes)')
    records = run_spatial(args.methods, args.every, log=progress)
    empty = np.zeros(0)  # no served plan: the demo's plans figure is the nodes'
    return [Run(r.column, r.method, r.plan_time_s, r.peak_acceleration, r.residual_mm, float('nan'), r.t, r.load_mm,
                empty, empty, empty) for r in records], records


def run_route_case(args) -> tuple[list[Run], list]:
    """The route case, offline (``route_demo.run_routes``, after the nodes have stopped): its table rows as Runs
    (no ExecuteMove result: nan), its ``RouteRun`` records for the figure and the routes' table, and the
    refusals said."""
    from .route_demo import run_routes
    progress('route case: planned as the planner serves it and simulated offline (crane_sim, no nodes)')
    methods = case_methods(CASES['route'], args.methods, args.every)
    records, _ = run_routes(methods, log=progress)
    empty = np.zeros(0)
    return [Run(r.column, r.method, r.plan_time_s, r.peak_acceleration, r.residual_mm, float('nan'), r.t,
                r.load_mm, empty, empty, empty) for r in records], records


def run_feedback_case(args, env: dict, log_dir: Path) -> list:
    """The feedback case on nodes of its own (``feedback_demo.run_feedback``: open loop, then closed loop), after
    the demo's nodes have stopped: its ``FeedbackRun`` records."""
    from .feedback_demo import Settings, run_feedback
    progress('feedback case: the streamer\'s sway feedback off, then on, each on nodes of its own')
    methods = tuple(case_methods(CASES['feedback'], args.methods, args.every))
    return run_feedback(env, log_dir, Settings(args.namespace, methods, args.displacement, args.duration, args.settle,
                                               startup_timeout=args.startup_timeout), progress)


def run_runway_case(args, env: dict, log_dir: Path) -> list:
    """The runway case on two cranes' nodes of their own (``runway_demo.run_runway``), after the demo's nodes have
    stopped, recorded (both cranes' joint_states and trajectories, /runway/occupancy, /runway/state, /diagnostics)
    into OUT/runway_recording unless --no-record: its ``RunwayRun`` records."""
    from .runway_demo import CRANES, METHODS, Settings, run_runway
    progress('runway case: two cranes on one runway, each its own process group')
    asked = case_methods(CASES['runway'], args.methods, args.every)  # (ZV first: out, then NVF back)
    methods = tuple(sorted(asked, key=lambda m: (METHODS.index(m) if m in METHODS else len(METHODS), m)))
    topics = [f'/{name}/{topic}' for name in CRANES for topic in ('joint_states', 'trajectory')] + ['/diagnostics']
    started = []

    def record():
        started.append(start_recorder(args, env, log_dir, None, topics=topics, runway=True,
                                      bag=Path(args.out) / 'runway_recording'))
        return lambda: stop_recorder(started.pop())

    try:
        return run_runway(env, log_dir / 'runway', Settings(methods, startup_timeout=args.startup_timeout), progress,
                          recorder=None if args.no_record else record)
    finally:
        for proc in started:  # (an error ended the case before the recording was stopped)
            stop_recorder(proc)


def print_routes(records: list) -> None:
    """The route case's own figures: each method's route and the smallest distance of a mass to the box."""
    from .route_demo import COLUMNS, MARGIN
    print(f'routes (margin {MARGIN * 1e3:g} mm): route taken | smallest distance of a mass to the box in crane_sim '
          '(mm) | residual (mm); a method the planner refuses: -')
    methods = list(dict.fromkeys(r.method for r in records))
    by_key = {(r.column, r.method): r for r in records}
    print(f'{"method":<8}' + ''.join(f'{c:>30}' for c in COLUMNS))
    for m in methods:
        cells = [by_key.get((c, m)) for c in COLUMNS]
        print(f'{m:<8}' + ''.join(f'{"-":>30}' if r is None else
                                  f'{r.route or "direct":>8} |{r.clearance_mm:7.1f} |{r.residual_mm:9.5f}'
                                  .rjust(30) for r in cells))


def run_sweep(args) -> Path | None:
    """Paper Fig. 4 from ``crane-plan sweep`` (offline; run after the nodes stop, to keep the stream steady)."""
    if args.sweep_points < 2 or args.no_figures:
        return None
    path = Path(args.out) / 'demo_sweep_L1.png'
    cmd = [find_executable('crane_planner', 'crane-plan'), 'sweep', '--param', 'L1', '--span', '0.3',
           '--points', str(args.sweep_points), '--displacement', str(args.displacement),
           '--duration', str(args.duration), '--methods', ','.join(args.methods), '--settle', str(args.settle),
           '--plot', str(path), '--json']
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        raise HarnessError(f'crane-plan sweep failed: {r.stderr.strip()}')
    (Path(args.out) / 'sweep_L1.json').write_text(r.stdout)
    return path


def start_recorder(args, env: dict, log_dir: Path, nodes: NodeGroup | None, topics=None, runway: bool = False,
                   bag: Path | None = None):
    """``crane-record`` into ``bag`` (default ``--record``, else OUT/recording) as a process: the demo's topics, or
    ``topics``, and with ``runway`` the runway's."""
    import shutil
    given = bag is None and args.record is not None
    bag = Path(bag or args.record or Path(args.out) / 'recording')
    if bag.exists() and not given:
        shutil.rmtree(bag)  # the demo's own recording of an earlier run
    log_path = log_dir / f'crane-record-{bag.name}.log'
    log = open(log_path, 'w')
    options = (['--topics', ','.join(topics)] if topics else []) + (['--runway'] if runway else [])
    proc = subprocess.Popen([find_executable('crane_planner', 'crane-record'), '--namespace', args.namespace,
                             '--out', str(bag), *options], env={**env, DIE_WITH_PARENT: '1'}, stdout=log,
                            stderr=subprocess.STDOUT, start_new_session=True)
    proc.bag, proc.log_path = bag, log_path
    deadline = time.monotonic() + 30.0
    while 'recording' not in proc.log_path.read_text():
        if nodes is not None:
            nodes.check_alive()  # a node that dies meanwhile is the error to report, not the recorder
        if proc.poll() is not None or time.monotonic() > deadline:
            raise HarnessError(f'crane-record did not start: {proc.log_path.read_text().strip()[-300:]}')
        time.sleep(0.1)
    progress(f'recording into {bag}')
    return proc


def stop_recorder(proc) -> Path:
    """Stop ``crane-record`` (SIGINT: it closes the recording) and return the recording's folder."""
    import signal
    proc.send_signal(signal.SIGINT)
    try:
        proc.wait(timeout=30.0)
    except subprocess.TimeoutExpired:
        proc.kill()
        raise HarnessError('crane-record did not stop within 30 s') from None
    log = proc.log_path.read_text().strip()
    if proc.returncode != 0:
        raise HarnessError(f'crane-record failed: {log[-300:]}')
    progress(log.splitlines()[-1])  # what it recorded, and lost, per topic
    return proc.bag


def main(argv=None) -> int:
    args = _parse(argv)
    Path(args.out).mkdir(parents=True, exist_ok=True)
    t_start = time.monotonic()
    with isolated_graph(args.domain_id) as env:  # this process joins the same private graph as its nodes
        return _run(args, env, t_start)


def _run(args, env: dict, t_start: float) -> int:
    out = Path(args.out)
    runs: list[Run] = []
    identification = None
    log_dir = Path(tempfile.mkdtemp(prefix='crane-demo-'))
    timing_log = (out / 'streamer_timing.json').resolve()
    progress(f'ROS_DOMAIN_ID={env["ROS_DOMAIN_ID"]}, namespace {args.namespace}, node logs in {log_dir}')
    driver = recorder = None
    written_bag = None
    try:
        model = CraneParams()  # the planner's
        on_nodes = [c for c in args.cases if c.on_nodes]
        total = sum(len(case_methods(c, args.methods, args.every)) * (2 if c.commission else 1) for c in on_nodes)
        k = 0
        # the cart-only cases on nodes with the joint [cart], then the hoisting ones on nodes with
        # [cart, hoist] (the joints are fixed at a node's start-up); none for the spatial case alone
        setups = [(hoisting, [c for c in on_nodes if (c.hoist is not None or c.hoisting_nodes) == hoisting])
                  for hoisting in (False, True)]
        setups = [(hoisting, cases) for hoisting, cases in setups if cases]
        for i, (hoisting, cases) in enumerate(setups):
            with NodeGroup(env, log_dir / ('hoist' if hoisting else 'cart')) as nodes:
                streamer = {} if hoisting else {'timing_log': str(timing_log)}  # the paper's stream's timing
                start_crane_nodes(nodes, args.namespace, streamer_params=streamer, hoist=hoisting)
                driver = CraneHarness(args.namespace, nodes, log=progress, node_name='crane_demo')
                driver.wait_until_up(args.startup_timeout)
                if recorder is None and not args.no_record:  # one recording of every case
                    recorder = start_recorder(args, env, log_dir, nodes)
                progress(f'nodes up{" with a hoist" if hoisting else ""} in {time.monotonic() - t_start:.1f} s')
                for case in cases:
                    driver.set_parameters('sim', {name: getattr(case.plant, name) for name in PARAMETER_NAMES})
                    driver.set_parameters('streamer', NETWORK if case.network else NETWORK_OFF)
                    driver.reset_sim()
                    phases = [(BEFORE, model), (AFTER, None)] if case.commission else [(case.name, model)]
                    for name, planner_model in phases:
                        if planner_model is None:  # commissioning: identify the crane, give the planner its model
                            progress('commissioning: one excitation move, recorded with '
                                     f'{1e3 * COMMISSION_NOISE:g} mrad angle noise')
                            recording, identified = commission(driver, args, model)
                            planner_model = identified.params
                            identification = (recording, identified)
                            progress(f'identified {_describe(identified)} in {identified.fit_time_s:.2f} s')
                        driver.set_parameters('planner', {n: getattr(planner_model, n) for n in PARAMETER_NAMES})
                        for method in case_methods(case, args.methods, args.every):
                            k += 1
                            run = (run_case_method(driver, case, method, args, name) if case.kind == 'move'
                                   else run_any_state(driver, case, method, args))
                            runs.append(run)
                            progress(f'[{k:2d}/{total}] {name:<22} {method:<4} residual {run.residual_mm:6.2f} mm, '
                                     f'peak a_ref {run.peak_acceleration:.3f} m/s^2, '
                                     f'plan {1e3 * run.plan_time_s:.0f} ms')
                    driver.set_parameters('planner', {n: getattr(model, n) for n in PARAMETER_NAMES})
                if recorder is not None and i == len(setups) - 1:
                    written_bag, recorder = stop_recorder(recorder), None
                driver.close()
                driver = None
        feedback = run_feedback_case(args, env, log_dir) if any(c.kind == 'feedback' for c in args.cases) else []
        runway = run_runway_case(args, env, log_dir) if any(c.kind == 'runway' for c in args.cases) else []
        # The nodes are stopped here, so the streamer has written its timing log.
        spatial = None
        if any(c.kind == 'spatial' for c in args.cases):
            spatial_runs, spatial = run_spatial_case(args)
            runs += spatial_runs
        routes = None
        if any(c.kind == 'route' for c in args.cases):
            route_runs, routes = run_route_case(args)
            runs += route_runs
        if columns(args.cases):  # (not the feedback or runway case alone: tables of their own)
            print_table(runs, args.cases, args.methods)
        if routes:
            print_routes(routes)
        if feedback:
            from .feedback_demo import print_feedback
            print_feedback(feedback)
        if runway:
            from .runway_demo import print_runway
            print_runway(runway)
        (out / 'results.json').write_text(json.dumps([r.row() for r in runs + feedback + runway], indent=1) + '\n')
        written = [out / 'results.json'] + ([written_bag] if written_bag is not None else [])
        written += [out / 'runway_recording'] if runway and not args.no_record else []
        if identification is not None:
            recording, identified = identification
            (out / 'commission.json').write_text(json.dumps(
                {'truth': UNKNOWN_PLANT.as_dict(), 'identified': identified.as_json()}, indent=1) + '\n')
            (out / 'commissioned_planner.yaml').write_text(identified.params_yaml())
            recording.write_csv(out / 'commission_recording.csv')
            written += [out / 'commission.json', out / 'commissioned_planner.yaml', out / 'commission_recording.csv']
            if not args.no_figures:
                from .figures import plot_identification
                written.append(plot_identification(recording, identified, out / 'demo_commission_fit.png'))
        if not args.no_figures:
            written += write_figures(runs, args, timing_log, spatial)
            if routes:
                from .route_demo import plot_routes
                written.append(plot_routes(routes, out / 'demo_route.png'))
            if feedback:
                from .feedback_demo import plot_feedback
                written.append(plot_feedback(feedback, out / 'demo_feedback.png'))
            if runway:
                from .runway_demo import plot_runway
                written.append(plot_runway(runway, out / 'demo_runway.png'))
            sweep = run_sweep(args)
            if sweep:
                written.append(sweep)
        for path in written:
            print(f'wrote {path}')
        progress(f'done in {time.monotonic() - t_start:.0f} s')
        return 0
    except (NodeDied, HarnessError, ValueError, TimeoutError) as e:
        # ValueError includes PlanError (a plan the planner refused).
        print(f'{PROG}: error: {e}', file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f'{PROG}: interrupted', file=sys.stderr)
        return 130
    finally:
        if recorder is not None and recorder.poll() is None:  # an error ended the demo: no recorder left behind
            recorder.send_signal(signal.SIGINT)
            try:
                recorder.wait(timeout=10.0)
            except subprocess.TimeoutExpired:
                recorder.kill()
        if driver is not None:
            driver.close()


if __name__ == '__main__':
    sys.exit(main())
