"""``crane-demo``'s runway case: two cranes sharing a runway over ROS, each its own process group (contract "Cranes
sharing a runway"; docs/runway.md).

Crane a's ``crane_base`` lies at [0, 0] of the frame ``runway``, crane b's at [0, 2] (bridges 2 m apart), both with
the joints [cart, bridge], loads on the default 0.47 + 0.391 m cables, ``runway_min_distance`` 0.2 m, the planners
and the streamers on the runway. The situations, in this order:

- ``runway:<method>`` for each method asked (ZV and NVF by default), in turn out and back: both goals sent at
  the same moment, one crane into the space the other leaves, which it could not reach while the other is still
  there (out: a 1.87 m towards b in 3 s while b leaves 0.3 m in 5.5 s; back: a to 1.0 m in 3 s, b after it home in
  1.3 s):
  the follower waits (its ``PlanInfo`` names the other), neither stops, no overlap, no residual swing;
- ``runway:operator``: crane a's streamer in operator mode, its stick at full speed towards b and held there: the
  guard stops a short of the minimum without swing, refuses the stick towards b, and takes a away again.

Everything is measured from both sims' joint_states (each crane's girder, hook and load placed in ``runway`` by its
``runway_offset`` and crane_sim's own cable geometry): the least distance between the cranes over each situation,
each crane's residual swing after its motion (the operator: the swing once stopped). The sims are reset before each
situation (the loads at rest where they hang). A ROS tool: it starts the nodes and drives them through the
harness.
"""
from __future__ import annotations

import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from crane_msgs_py.crane.geometry import load_swing
from crane_msgs_py.crane.params import CraneParams

from ..runway.occupancy import Footprint, Shape, separation
from .harness import CraneHarness, HarnessError, measured_masses, start_crane_nodes, state_columns
from .processes import NodeGroup

A, B = 'crane_a', 'crane_b'
CRANES = (A, B)
#: Where each crane's crane_base lies in ``runway`` [x, y] (m): bridges 2 m apart.
OFFSETS = {A: (0.0, 0.0), B: (0.0, 2.0)}
JOINTS = ('cart', 'bridge')
MIN_DISTANCE = 0.2
RUNWAY = {'runway': True, 'runway_min_distance': MIN_DISTANCE}
MODEL = CraneParams()
#: The convoys, out and back in turn: (the crane that goes first, the one that follows, crane -> (bridge goal m,
#: duration s)). Found offline (crane-plan runway, checked on crane_sim): sent together, the follower would come
#: within 0.15 m (out by ZV: a's load, leading as it brakes, of b's girder) and 0.06 m (back by NVF: b's girder
#: of a's); it waits 0.6 s and 0.5 s.
CONVOYS = ((B, A, {A: (1.87, 3.0), B: (0.3, 5.5)}),
           (A, B, {A: (1.0, 3.0), B: (0.0, 1.3)}))
METHODS = ('zv', 'nvf')
#: The operator situation: the bridge's stick (m/s: its operator limit), published at this rate (Hz).
FULL_SPEED, STICK_RATE = 0.3, 20.0
#: The situations' names (``RunwayRun.situation``).
OPERATOR = 'runway:operator'
S = 1_000_000_000


@dataclass
class RunwayRun:
    """One situation: the distances in m, the swing in mm, times in s from its start."""

    situation: str                            # 'runway:<method>' or OPERATOR
    method: str                               # of the convoy ('-': the operator)
    follower: str                             # the crane that waited (the operator: the crane driven)
    delay: float                              # s the follower's goal started later (PlanInfo; operator: nan)
    waited_for: str                           # the crane it waited for (PlanInfo; operator: the guard's)
    stopped: bool                             # a goal failed (stopped, refused); operator: the guard stopped a
    closest_m: float                          # least distance between the cranes, measured
    residual_mm: dict                         # crane -> peak swing after its motion (the operator: a's, stopped)
    message: str                              # the guard's word (operator), the goals' results' messages
    t: np.ndarray = field(repr=False)         # s from the situation's start (crane a's joint_states)
    girder: dict = field(repr=False)          # crane -> its girder's y in runway (m) at ``t``
    load: dict = field(repr=False)            # crane -> its load's y in runway (m) at ``t``
    distance: np.ndarray = field(repr=False)  # m, at ``t``

    def row(self) -> dict:
        return {'case': self.situation, 'method': self.method, 'follower': self.follower, 'delay_s': self.delay,
                'waited_for': self.waited_for, 'stopped': self.stopped, 'closest_m': self.closest_m,
                **{f'residual_mm_{name}': value for name, value in self.residual_mm.items()}}


@dataclass(frozen=True)
class Settings:
    """What the case runs: the convoys' methods (of ``METHODS``), the seconds observed after a motion, whether
    the operator situation runs, and how long the nodes may take to come up (s)."""

    methods: tuple = METHODS
    settle: float = 1.0
    operator: bool = True
    startup_timeout: float = 120.0


class Stick:
    """A joystick on a crane's ``cmd_vel``: the bridge's velocity (m/s, ``velocity``) held, published at
    STICK_RATE from a thread of its own until ``close``."""

    def __init__(self, node, namespace: str):
        from geometry_msgs.msg import Twist
        self._twist, self._pub = Twist, node.create_publisher(Twist, f'{namespace}/cmd_vel', 10)
        self.velocity, self._stop = 0.0, threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self):
        while not self._stop.wait(1.0 / STICK_RATE):
            msg = self._twist()
            msg.linear.y = float(self.velocity)
            self._pub.publish(msg)

    def close(self):
        self.velocity = 0.0
        self._stop.set()
        self._thread.join()


def run_runway(env: dict, log_dir: Path, settings: Settings, log: Callable[[str], None],
               recorder: Callable[[], object] | None = None) -> list[RunwayRun]:
    """Both cranes' nodes (a node group each: separate process groups and DDS participants) in the private graph
    ``env``, node logs in ``log_dir``; the convoys, then the operator (``recorder``: called once the nodes are up,
    starts a recording and returns what stops it, called before the nodes stop). The runs in that order."""
    groups = {name: NodeGroup(env, log_dir / name) for name in CRANES}
    drivers, runs, stop_recording = {}, [], None
    try:
        for name, nodes in groups.items():
            offset = list(OFFSETS[name])
            start_crane_nodes(nodes, f'/{name}', joints=JOINTS,
                              planner_params={**RUNWAY, 'runway_offset': offset, 'solver_processes': 1},
                              streamer_params={**RUNWAY, 'runway_offset': offset})
        for name, nodes in groups.items():
            drivers[name] = CraneHarness(f'/{name}', nodes, log=log, node_name='crane_demo')
        for driver in drivers.values():
            driver.wait_until_up(settings.startup_timeout)
        log(f'both cranes up ({", ".join(f"/{name}" for name in CRANES)}, each its own process group)')
        situations = _Situations(drivers, settings, log)
        if recorder is not None:
            stop_recording = recorder()
        for k, method in enumerate(settings.methods):
            runs.append(situations.convoy(method, CONVOYS[k % 2]))
        if settings.operator:
            runs.append(situations.operator())
        return runs
    finally:
        if stop_recording is not None:  # (before the nodes: their going is no part of the case)
            stop_recording()
        for driver in reversed(list(drivers.values())):  # (a's harness owns the rclpy context: last)
            driver.close()
        for nodes in groups.values():
            nodes.stop(timeout=10.0)


@dataclass
class _Situations:
    drivers: dict
    settings: Settings
    log: Callable[[str], None]

    def convoy(self, method: str, convoy: tuple) -> RunwayRun:
        """Both goals of ``convoy`` (of ``CONVOYS``) by ``method`` sent at the same moment (a thread each), 1.5 s
        ahead."""
        from crane_msgs_py.messages.conversions import move_message
        leader, follower, goals = convoy
        for driver in self.drivers.values():
            # each from rest: a shaper on the nonlinear plant leaves a few tenths of a millimetre, which the next
            # goal from rest would carry to its end
            driver.reset_sim()
        a = self.drivers[A]
        start = a.now_ns() + round(1.5 * S)
        handles, threads = {}, []
        for name, (goal, duration) in goals.items():
            move = move_message([goal], duration, [], method, ['bridge'], start)
            threads.append(threading.Thread(target=lambda n=name, m=move, g=goal, d=duration: handles.__setitem__(
                n, self.drivers[n].planner.send_execute(method, None, g, d, start, self.settings.settle, timeout=30.0,
                                                        move=m))))
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join(40.0)
        if set(handles) != set(CRANES):
            raise HarnessError(f'runway {method}: a goal was not accepted')
        results = {}
        for name, handle in handles.items():
            future = handle.get_result_async()
            self.drivers[name].wait_until(future.done, 60.0, f'runway {method}: no result of {name}\'s goal')
            results[name] = future.result().result
        infos = {name: (r.info.runway_delay, r.info.runway_waited_for) for name, r in results.items()}
        waiter = max(CRANES, key=lambda name: infos[name][0])
        ends = {name: start + round((infos[name][0] + goals[name][1]) * S) for name in CRANES}
        t, found = self._measure(start, max(ends.values()) + round(self.settings.settle * S))
        residual = {name: _peak_swing_mm(found[name][1], ends[name]) for name in CRANES}
        run = _run(f'runway:{method}', method, waiter, infos[waiter][0], infos[waiter][1],
                   not all(r.success for r in results.values()), residual,
                   '; '.join(f'{name}: {r.message}' for name, r in results.items()), start, t, found)
        self.log(f'{run.situation:<16} {waiter} waited {run.delay:.2f} s for {run.waited_for or "nobody"} '
                 f'(the planned order: {follower} after {leader}); closest {run.closest_m:.4f} m (minimum '
                 f'{MIN_DISTANCE:g} m); residual {", ".join(f"{n} {v:.3f} mm" for n, v in residual.items())}'
                 + ('; a goal failed: ' + run.message if run.stopped else ''))
        return run

    def operator(self) -> RunwayRun:
        """Crane a's streamer in operator mode, its stick at FULL_SPEED towards b until a has stood still for a
        second, then away 0.3 m; the mode set back."""
        a = self.drivers[A]
        a.wait_until_still(joints=('bridge',))
        a.reset_sim()
        a.set_parameters('streamer', {'mode': 'operator'})
        stick = Stick(a.node, f'/{A}')
        try:
            begin, mark = a.now_ns(), a.planner.diagnostics.mark()
            y0 = a.last_state()[4]
            stick.velocity = FULL_SPEED  # towards b, held
            a.wait_until(lambda: a.last_state()[4] > y0 + 0.05, 10.0, 'the stick never moved crane a')
            a.wait_until_still(joints=('bridge',), window=1.0, timeout=30.0)  # (pushing on against the guard)
            end = a.now_ns()
            t, found = self._measure(begin, end)
            stopped_at = found[A][1]['bridge'][-1]
            rows = found[A][1]
            residual = {A: _peak_swing_mm(rows, end - S)}
            statuses = a.planner.diagnostics.statuses(name='crane_streamer: runway guard',
                                                      hardware_id=f'/{A}/crane_streamer', after=mark)
            said = statuses[-1].message if statuses else ''
            stick.velocity = -FULL_SPEED  # away: taken at once
            a.wait_until(lambda: a.last_state()[4] < stopped_at - 0.3, 10.0, 'crane a never went away from b')
            stick.velocity = 0.0
            a.wait_until_still(joints=('bridge',))
        finally:
            stick.close()
        a.sleep(1.5)  # (the operator's shaper played out: a mode changes only at rest)
        a.set_parameters('streamer', {'mode': 'trajectory'})
        run = _run(OPERATOR, '-', A, float('nan'), B if said.startswith(f'stop: {B}') else '', bool(said), residual,
                   said, begin, t, found)
        self.log(f'{OPERATOR:<16} {A} driven at {FULL_SPEED:g} m/s towards {B}: stopped at y {stopped_at:.4f} m, '
                 f'closest {run.closest_m:.4f} m, swing then {residual[A]:.3f} mm; the guard: {said or "nothing"}')
        return run

    def _measure(self, begin: int, end: int) -> tuple[np.ndarray, dict]:
        """Each crane's joint_states in [begin, end]: crane -> (Footprint in runway, the rows by column), b's
        interpolated to a's stamps; and a's stamps."""
        for driver in self.drivers.values():
            driver.sleep(max(0.0, (end - driver.now_ns()) * 1e-9))
        recs = {name: state_columns(driver.states_between(begin, end, timeout=30.0))
                for name, driver in self.drivers.items()}
        t = recs[A]['stamp']
        found = {}
        for name, rec in recs.items():
            if name != A:
                rec = {k: np.interp(t, rec['stamp'], v) for k, v in rec.items()}
            m1, m2 = measured_masses(rec, MODEL.L1, MODEL.L2)
            offset = np.array(OFFSETS[name])
            masses = np.stack([m1[:, :2], m2[:, :2]], axis=1) + offset
            found[name] = (Footprint(rec['bridge'] + offset[1], masses), rec)
        return t, found


def _run(situation, method, follower, delay, waited_for, stopped, residual, message, begin, t, found) -> RunwayRun:
    distance = separation(found[A][0], Shape(), found[B][0], Shape())
    return RunwayRun(situation, method, follower, float(delay), waited_for, bool(stopped), float(distance.min()),
                     residual, message, (t - begin) * 1e-9, {n: f.girder for n, (f, _) in found.items()},
                     {n: f.masses[:, 1, 1] for n, (f, _) in found.items()}, distance)


def _peak_swing_mm(rec: dict, after_ns: int) -> float:
    """The load's largest horizontal offset from below its trolley (mm) at the rows after ``after_ns``."""
    k = rec['stamp'] >= after_ns
    return 1e3 * float(np.max(load_swing(rec['theta1'][k], rec['theta2'][k], MODEL.L1, MODEL.L2, rec['phi1'][k],
                                         rec['phi2'][k]), initial=0.0))


def print_runway(runs: list[RunwayRun]) -> None:
    """The case's table: per situation who waited, for whom and how long, the least distance measured and the
    residual swing."""
    print(f'runway (crane-demo --cases runway): two cranes 2 m apart, runway_min_distance {MIN_DISTANCE:g} m, '
          'measured from both sims\' joint_states')
    print(f'{"situation":<18}{"waited":<28}{"stopped":<9}{"closest (m)":>12}{"residual a (mm)":>17}'
          f'{"residual b (mm)":>17}')
    for r in runs:
        waited = (f'{r.follower} {r.delay:.2f} s for {r.waited_for}' if r.situation != OPERATOR else
                  f'guard stopped {r.follower}' if r.stopped else 'guard silent')
        stopped = ('guard' if r.stopped else 'no') if r.situation == OPERATOR else 'yes' if r.stopped else 'no'
        cells = ''.join(f'{r.residual_mm[n]:17.4f}' if n in r.residual_mm else f'{"-":>17}' for n in CRANES)
        print(f'{r.situation:<18}{waited:<28}{stopped:<9}{r.closest_m:12.4f}{cells}')


def plot_runway(runs: list[RunwayRun], path) -> Path:
    """Per situation the runway seen over time (each crane's girder and load along the runway) and below it the
    least distance between the cranes against the minimum."""
    from .figures import plt, save_figure  # headless (Agg) matplotlib

    fig, axes = plt.subplots(2, len(runs), figsize=(4.8 * len(runs), 6.5), sharex='col', squeeze=False,
                             gridspec_kw={'height_ratios': (3, 2)})
    for col, r in enumerate(runs):
        top, bottom = axes[0, col], axes[1, col]
        for k, name in enumerate(CRANES):
            top.plot(r.t, r.girder[name], color=f'C{k}', lw=1.2, label=f'{name} girder')
            top.plot(r.t, r.load[name], color=f'C{k}', lw=0.9, ls='--', label=f'{name} load')
        bottom.plot(r.t, r.distance, color='k', lw=1.0, label=f'closest {r.closest_m:.3f} m')
        bottom.axhline(MIN_DISTANCE, color='r', lw=0.8, ls=':', label=f'minimum {MIN_DISTANCE:g} m')
        bottom.set_ylim(0.0, max(1.0, MIN_DISTANCE * 2))
        title = (f'{r.method.upper()}: both sent together; {r.follower} waits {r.delay:.2f} s'
                 if r.situation != OPERATOR else f'operator drives {r.follower} at {FULL_SPEED:g} m/s into {B}\'s way')
        top.set_title(title, fontsize=9)
        for ax in (top, bottom):
            ax.grid(True, alpha=0.3)
            ax.legend(fontsize=7)
        bottom.set_xlabel('time (s)')
    axes[0, 0].set_ylabel('y along the runway (m)')
    axes[1, 0].set_ylabel('distance between the cranes (m)')
    fig.suptitle('two cranes on one runway over ROS, measured from joint_states (crane-demo --cases runway)',
                 fontsize=10)
    return save_figure(fig, path)
