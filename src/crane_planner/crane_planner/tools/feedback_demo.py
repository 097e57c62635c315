"""``crane-demo``'s feedback case: the streamer's closed-loop sway control (its ``feedback``) against open loop,
over ROS with the real nodes (contract "Closed-loop sway control").

Two node sets run the same situations in the same order, the streamer's ``feedback`` off on the first and on on
the second. Not one set with ``feedback`` switched (that works: a correction left fades out), because the sim
seeds its gusts once, at its start-up (``seed``): only a fresh sim blows the same gusts again. Each set comes up
in 5-10 s (one solver process: the case plans one move at a time).

- ``feedback:perturbed``: the sim's upper cable 0.42 m, the planner's and the streamer's model 0.47 m (paper
  §5.2); NVF and ZV (of the methods asked), 0.3 m in 2.5 s, there and back: the residual after the motion;
- ``feedback:push``: the load pushed 30 mm (the sim's ``~/push``) at 40 % of a 3 s NVF move, the camera 50 ms
  late (the sim's ``sensor_latency``): the residual after the motion, and the cart's distance from its goal once
  the goal has ended;
- ``feedback:wind``: at rest, a wind of 0.3 m/s² with gusts of 0.2 m/s² (correlation time 1 s) for 20 s: the
  RMS of the load's offset about its mean after the first 5 s (the lean into the wind is no swing).

The residual is the peak load offset over ``settle`` s after the motion's end, from joint_states, alike open and
closed loop; the goal's result reports its own, with feedback over the window after the correction has settled
back to zero. Between situations open loop resets the sim; closed loop waits until the load is quiet and the
correction back to nothing (a reset while a correction moves the cart would leave it off). A ROS tool: it starts
the nodes and drives them through the harness.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from crane_msgs_py.crane.geometry import load_excursion
from crane_msgs_py.crane.params import CraneParams

from .harness import CraneHarness, start_crane_nodes, state_columns
from .processes import NodeGroup

PERTURBED, PUSH, WIND = 'feedback:perturbed', 'feedback:push', 'feedback:wind'
SITUATIONS = (PERTURBED, PUSH, WIND)
#: The methods of the perturbed situation (of those asked; every one with --cases all or --methods).
METHODS = ('nvf', 'zv')
LOOPS = {False: 'open', True: 'closed'}
MODEL = CraneParams()
#: The perturbed plant's upper cable (m): paper §5.2, as the demo's perturbed case.
PLANT_L1 = 0.42
#: The push: the load displaced this far (m, the sim's push_swing) at this fraction of an NVF move this long (s),
#: the camera this late (s).
PUSH_SWING, PUSH_AT, PUSH_DURATION, LATENCY = 0.03, 0.4, 3.0, 0.05
#: The sim's playout_delay (s, its default): its plant plays each reference this long after the reference's
#: stamp, so a push lands on the motion that long after it is asked for.
PLAYOUT_DELAY = 0.1
#: The wind (m/s²), the gusts' standard deviation (m/s²) and correlation time (s), how long they blow (s) and
#: how much of it the RMS leaves out (s).
WIND_ACCELERATION, GUST, GUST_TIME, WIND_TIME, WIND_SKIP = 0.3, 0.2, 1.0, 20.0, 5.0


@dataclass
class FeedbackRun:
    """One situation run open or closed loop (the swing in mm)."""

    situation: str                               # one of SITUATIONS
    method: str                                  # of the move ('-': the wind, at rest)
    closed: bool                                 # the streamer's feedback on
    duration: float                              # s of the motion (the wind: the part the RMS leaves out)
    residual_mm: float                           # peak |load offset| over the settle window after the motion (nan)
    action_residual_mm: float                    # as the goal's result reports it (nan: wind)
    cart_error_mm: float                         # push: the cart's distance from its goal once the goal ended (nan)
    rms_mm: float                                # wind: RMS of the load offset about its mean after WIND_SKIP (nan)
    correction_peak_mm: float                    # the largest |correction| of the cart's reference in the record
    t: np.ndarray = field(repr=False)            # s from the motion's start (the wind's onset)
    load_mm: np.ndarray = field(repr=False)      # the load's offset from below the cart (mm), joint_states at ``t``
    correction_t: np.ndarray = field(repr=False)  # s, as ``t``: stream_state
    correction_mm: np.ndarray = field(repr=False)  # the feedback's correction of the cart's reference (mm)

    def row(self) -> dict:
        return {'case': self.situation, 'method': self.method, 'loop': LOOPS[self.closed],
                'residual_mm': self.residual_mm, 'action_residual_mm': self.action_residual_mm,
                'cart_error_mm': self.cart_error_mm, 'rms_mm': self.rms_mm,
                'correction_peak_mm': self.correction_peak_mm}


@dataclass(frozen=True)
class Settings:
    """What the case runs (crane-demo's options): the nodes' namespace, the perturbed situation's methods, its
    move (m in s: the push's lasts PUSH_DURATION), the seconds observed after a motion, the situations (in
    SITUATIONS' order: the wind last) and how long the nodes may take to come up (s)."""

    namespace: str = '/crane_demo'
    methods: tuple = METHODS
    displacement: float = 0.3
    duration: float = 2.5
    settle: float = 2.0
    situations: tuple = SITUATIONS
    startup_timeout: float = 90.0


def run_feedback(env: dict, log_dir: Path, settings: Settings, log: Callable[[str], None]) -> list[FeedbackRun]:
    """Every situation open loop on a node set of its own, then closed loop on another (``env``: the private ROS
    graph's, node logs in ``log_dir``): the runs in that order."""
    runs = []
    for closed in (False, True):
        with NodeGroup(env, log_dir / f'feedback-{LOOPS[closed]}') as nodes:
            start_crane_nodes(nodes, settings.namespace, streamer_params={'feedback': closed},
                              planner_params={'solver_processes': 1})
            driver = CraneHarness(settings.namespace, nodes, log=log, node_name='crane_demo')
            try:
                driver.wait_until_up(settings.startup_timeout)
                case = _Situations(driver, closed, settings, log)
                for situation in (s for s in SITUATIONS if s in settings.situations):
                    runs += case.run(situation)
            finally:
                driver.close()
    return runs


@dataclass
class _Situations:
    """The situations on one node set, the streamer's feedback on (``closed``) or off."""

    driver: CraneHarness
    closed: bool
    settings: Settings
    log: Callable[[str], None]

    def run(self, situation: str) -> list[FeedbackRun]:
        if situation == PERTURBED:
            return [self.perturbed(method) for method in self.settings.methods]
        return [self.push() if situation == PUSH else self.wind()]

    def perturbed(self, method: str) -> FeedbackRun:
        self._plant(L1=PLANT_L1)
        run = self._move(PERTURBED, method, self.settings.duration, PLANT_L1)
        self._calm(PLANT_L1)
        return run

    def push(self) -> FeedbackRun:
        self._plant(L1=MODEL.L1, sensor_latency=LATENCY, push_swing=PUSH_SWING)
        run = self._move(PUSH, 'nvf', PUSH_DURATION, MODEL.L1, push_at=PUSH_AT * PUSH_DURATION)
        self._calm(MODEL.L1)
        self._plant(sensor_latency=0.0)
        return run

    def wind(self) -> FeedbackRun:
        """The wind and the gusts at rest for WIND_TIME s, then stopped; the load is left swinging (the case's last
        situation: its nodes stop next)."""
        driver = self.driver
        onset = driver.now_ns()
        driver.set_parameters('sim', {'wind': [WIND_ACCELERATION, 0.0], 'gust': GUST, 'gust_time': GUST_TIME})
        end = onset + round(WIND_TIME * 1e9)
        driver.sleep(max(0.0, (end - driver.now_ns()) * 1e-9))
        t, load, ct, correction = self._record(onset, end, MODEL.L1)
        driver.set_parameters('sim', {'wind': [0.0, 0.0], 'gust': 0.0})
        about = load[t >= WIND_SKIP]
        rms = float(np.sqrt(np.mean((about - about.mean()) ** 2)))
        return self._said(FeedbackRun(WIND, '-', self.closed, WIND_SKIP, np.nan, np.nan, np.nan, rms,
                                      _peak(correction), t, load, ct, correction))

    # -- the parts

    def _move(self, situation: str, method: str, duration: float, L1: float, push_at: float | None = None):
        """A move there and back (to ``displacement`` from near 0, else to 0), pushed ``push_at`` s into it."""
        driver = self.driver
        here = driver.held()
        displacement, settle = self.settings.displacement, self.settings.settle
        goal = displacement if abs(here) < displacement / 2 else 0.0
        start, _, _ = driver.move(method, None, goal, duration, settle=settle)
        if push_at is not None:
            driver.sleep(max(0.0, (start + round((push_at + PLAYOUT_DELAY) * 1e9) - driver.now_ns()) * 1e-9))
            driver.push_sim()
        result = driver.move_result(start, timeout=40.0)  # with feedback: once the correction has settled
        last = driver.last_state()  # (the record's end: with feedback, once the goal has ended)
        t, load, ct, correction = self._record(start, max(start + round((duration + settle) * 1e9), last[0]), L1)
        window = (t >= duration) & (t <= duration + settle)
        cart_error = 1e3 * abs(last[3] - goal) if push_at is not None else np.nan
        return self._said(FeedbackRun(situation, method, self.closed, duration, float(np.abs(load[window]).max()),
                                      1e3 * result.residual_swing, cart_error, np.nan, _peak(correction), t, load,
                                      ct, correction))

    def _record(self, origin: int, end: int, L1: float):
        """(t, load offset mm) of joint_states and (t, correction mm) of stream_state in [origin, end], t in s
        from ``origin``."""
        rows = state_columns(self.driver.states_between(origin, end, timeout=30.0))
        corrections = self.driver.corrections_between(origin, end)
        return ((rows['stamp'] - origin) * 1e-9, 1e3 * load_excursion(rows['theta1'], rows['theta2'], L1, MODEL.L2),
                (corrections[:, 0] - origin) * 1e-9, 1e3 * corrections[:, 1])

    def _plant(self, **values):
        self.driver.set_parameters('sim', values)

    def _calm(self, L1: float):
        """The load at rest for the next situation: open loop the sim reset, closed loop the feedback's work
        awaited (the load quiet, the correction back to nothing)."""
        if self.closed:
            self.driver.wait_until_quiet(L1, MODEL.L2, timeout=30.0)
        else:
            self.driver.reset_sim()

    def _said(self, run: FeedbackRun) -> FeedbackRun:
        figure = (f'swing RMS {run.rms_mm:.2f} mm' if run.situation == WIND else
                  f'residual {run.residual_mm:.2f} mm (goal\'s result {run.action_residual_mm:.2f} mm)')
        cart = f', cart {run.cart_error_mm:.2f} mm off its goal' if run.situation == PUSH else ''
        self.log(f'{run.situation:<19} {run.method:<3} {LOOPS[run.closed]:<6} loop: {figure}{cart}, '
                 f'correction up to {run.correction_peak_mm:.2f} mm')
        return run


def _peak(values: np.ndarray) -> float:
    return float(np.abs(values).max()) if values.size else 0.0


def print_feedback(runs: list[FeedbackRun]) -> None:
    """The case's table: each situation's figures open loop and closed loop side by side."""
    print('feedback (crane-demo --cases feedback): the streamer\'s feedback off (open loop) and on (closed loop), each '
          'on nodes of its own; the residual: the peak load offset over the settle window after the motion, the '
          'goal\'s result\'s with feedback over the window once the correction has settled')
    print(f'{"situation":<20}{"method":<8}{"figure (mm)":<46}{"open":>9}{"closed":>9}')
    pairs = {}
    for r in runs:
        pairs.setdefault((r.situation, r.method), {})[r.closed] = r
    for (situation, method), pair in pairs.items():
        if situation == WIND:
            lines = [(f'swing RMS about its mean, {WIND_SKIP:g}-{WIND_TIME:g} s', 'rms_mm')]
        else:
            lines = [('residual after the motion', 'residual_mm'),
                     ('residual as the goal\'s result reports it', 'action_residual_mm')]
            lines += [('the cart from its goal once the goal ended', 'cart_error_mm')] if situation == PUSH else []
        lines.append(('largest correction of the cart\'s reference', 'correction_peak_mm'))
        for k, (what, name) in enumerate(lines):
            cells = ''.join(f'{getattr(pair[c], name):9.2f}' if c in pair else f'{"-":>9}' for c in (False, True))
            print(f'{situation if k == 0 else "":<20}{method if k == 0 else "":<8}{what:<46}{cells}')


def plot_feedback(runs: list[FeedbackRun], path) -> Path:
    """Per situation (and method) the load's offset open and closed loop over time, and below it the closed
    loop's correction of the cart's reference."""
    from .figures import plt, save_figure  # headless (Agg) matplotlib

    panels = list(dict.fromkeys((r.situation, r.method) for r in runs))
    fig, axes = plt.subplots(2, len(panels), figsize=(4.6 * len(panels), 6.5), sharex='col', squeeze=False,
                             gridspec_kw={'height_ratios': (3, 2)})
    titles = {PERTURBED: f'perturbed: the plant\'s L1 {PLANT_L1:g} m, the model\'s {MODEL.L1:g} m',
              PUSH: f'push: {1e3 * PUSH_SWING:g} mm at {100 * PUSH_AT:g} % of the move, camera {1e3 * LATENCY:g} ms '
                    'late',
              WIND: f'wind {WIND_ACCELERATION:g} m/s², gusts {GUST:g} m/s² ({GUST_TIME:g} s), at rest'}
    for col, (situation, method) in enumerate(panels):
        swing, correction = axes[0, col], axes[1, col]
        pair = [r for r in runs if (r.situation, r.method) == (situation, method)]
        for r in pair:
            figure = r.rms_mm if situation == WIND else r.residual_mm
            swing.plot(r.t, r.load_mm, lw=1.2 if r.closed else 0.9, color='C1' if r.closed else 'C0',
                       label=f'{LOOPS[r.closed]} loop ({"RMS" if situation == WIND else "residual"} {figure:.2f} mm)')
            if r.closed:
                correction.plot(r.correction_t, r.correction_mm, color='C1', lw=1.0)
        for ax in (swing, correction):
            ax.axvline(pair[0].duration, color='k', lw=0.6, ls=':')
            if situation == PUSH:
                ax.axvline(PUSH_AT * PUSH_DURATION, color='r', lw=0.6, ls=':')
            ax.grid(True, alpha=0.3)
        swing.set_title(titles[situation] + ('' if situation == WIND else f'\n{method.upper()}'), fontsize=9)
        swing.legend(fontsize=7)
        correction.set_xlabel('time (s) from the wind\'s onset' if situation == WIND else 'time (s) from the motion '
                              'start')
    axes[0, 0].set_ylabel('load offset (mm), joint_states')
    axes[1, 0].set_ylabel('closed loop: correction of\nthe cart\'s reference (mm)')
    fig.suptitle('closed-loop sway control over ROS: the streamer\'s feedback off (open loop) and on (closed loop); '
                 'dotted: the end of the motion (red: the push), the wind\'s RMS from there '
                 '(crane-demo --cases feedback)', fontsize=10)
    return save_figure(fig, path)
