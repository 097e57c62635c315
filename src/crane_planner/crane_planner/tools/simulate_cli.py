"""``crane-plan simulate``: a plan run through the plant with the streamer's sway feedback, open and closed loop.

The plan is made as ``crane-plan plan`` makes it; ``tools.closed_loop`` plays
it on crane_sim's plant (its ``--plant-*`` parameters) with the sim's sensor
(``--latency``, ``--noise``, ``--dropout``) and disturbances (``--push``,
``--wind``, ``--gust``), open loop and, with ``--feedback``, closed loop from
the same seed, and prints their residuals side by side: after the motion, and
once settled. ``--plot`` draws the swing and the correction against time,
``--csv`` writes them. No ROS.
"""
from __future__ import annotations

import argparse
import csv
import json
import math

import numpy as np

from crane_msgs_py.crane.axes import CART
from crane_msgs_py.messages.names import BRIDGE_JOINT, CART_JOINT

from ..streaming.source import Setpoint

#: The playout delay (s) of the sim by default (its ``playout_delay``): the plant runs that far behind the stream.
DEFAULT_DELAY = 0.1


def _push(text: str):
    """A push ``T:DX[:DY]``: at T s the load displaced DX (and DY) m."""
    from .closed_loop import Push
    try:
        values = [float(v) for v in text.split(':')]
    except ValueError:
        raise argparse.ArgumentTypeError(f'{text!r} is not T:DX[:DY] (numbers)') from None
    if len(values) not in (2, 3) or not all(math.isfinite(v) for v in values) or values[0] < 0.0:
        raise argparse.ArgumentTypeError(f'{text!r}: T:DX[:DY], T >= 0 s, DX and DY finite (m)')
    return Push(*values)


def _wind(text: str) -> tuple[float, float]:
    try:
        values = [float(v) for v in text.split(',')]
    except ValueError:
        raise argparse.ArgumentTypeError(f'{text!r} is not AX[,AY] (numbers)') from None
    if len(values) not in (1, 2) or not all(math.isfinite(v) for v in values):
        raise argparse.ArgumentTypeError(f'{text!r}: AX[,AY] (m/s^2), finite')
    return (values[0], values[1] if len(values) > 1 else 0.0)


def add_options(p: argparse.ArgumentParser) -> None:
    """``simulate``'s own options (the plan's, the model's and the plant's are ``plan``'s)."""
    g = p.add_argument_group('closed loop (the streamer\'s sway feedback; the sim\'s sensor and disturbances)')
    g.add_argument('--feedback', action='store_true', help='also run closed loop, and print both side by side')
    g.add_argument('--push', type=_push, action='append', metavar='T:DX[:DY]',
                   help='at T s (from the motion\'s start) displace the load DX (and DY, with --bridge) m, cables in '
                        'line, released from rest; repeatable')
    g.add_argument('--wind', type=_wind, default=(0.0, 0.0), metavar='AX[,AY]',
                   help='a steady horizontal acceleration on both masses (m/s^2)')
    g.add_argument('--gust', type=float, default=0.0, metavar='SD',
                   help='random gusts on both masses: standard deviation (m/s^2), 1 s correlation')
    g.add_argument('--latency', type=float, default=0.0, metavar='S', help='the camera\'s latency (s)')
    g.add_argument('--noise', type=float, default=0.0, metavar='RAD', help='the camera\'s angle noise (rad)')
    g.add_argument('--dropout', type=float, default=0.0, metavar='P', help='share of camera samples lost (0..1)')
    g.add_argument('--delay', type=float, default=DEFAULT_DELAY, metavar='S',
                   help=f'the sim\'s playout delay (s, default {DEFAULT_DELAY:g})')
    g.add_argument('--seed', type=int, default=0, metavar='N', help='seed of the noise, dropout and gusts')
    p.add_argument('--json', action='store_true', help='print the residuals as one JSON object')
    p.add_argument('--csv', metavar='FILE', help='write time, reference, correction and swing of each run (1 ms)')
    p.add_argument('--plot', metavar='FILE', help='write a PNG of the swing and the correction against time')


def _reference(plan, joints):
    """The plan's setpoint of ``joints`` at t s (relative, from 0), held at its end."""
    def setpoint(t: float) -> Setpoint:
        tt = min(t, plan.duration)
        rows = [plan.evaluate([tt]) if name == CART_JOINT else plan.evaluate_axis(name, [tt]) for name in joints]
        p = tuple(float(r.position[0]) for r in rows)
        v = tuple(0.0 if t >= plan.duration else float(r.velocity[0]) for r in rows)
        a = tuple(0.0 if t >= plan.duration else float(r.acceleration[0]) for r in rows)
        return Setpoint(p, v, a) if len(joints) > 1 else Setpoint(p[0], v[0], a[0])
    return setpoint


def run(args, plan, model, plant) -> dict:
    """Open loop and (``--feedback``) closed loop: {name: Trace}, and the window's bounds."""
    from crane_sim.disturbances import Disturbances
    from crane_sim.sensor import SensorSettings

    from .closed_loop import closed_loop
    joints = (CART_JOINT, BRIDGE_JOINT) if args.bridge is not None else (CART_JOINT,)
    sensor = SensorSettings(args.latency, args.dropout, args.noise)
    disturbances = Disturbances(args.wind, args.gust)
    duration = plan.duration + 2.0 * args.settle
    runs = {}
    for name, feedback in (('open', False), ('closed', True)) if args.feedback else (('open', False),):
        runs[name] = closed_loop(_reference(plan, joints), duration, model, plant, feedback, sensor, args.push or (),
                                 disturbances, args.delay, limits=CART.limits(*(getattr(args, n) for n in
                                                                                  CART.limit_names)),
                                 seed=args.seed, joints=joints)
    return runs


def cmd_simulate(args, make_plan) -> int:
    """``make_plan(args)``: (plan, model, plant) as ``crane-plan plan`` makes them."""
    if args.hoist is not None:
        raise ValueError('argument --hoist: simulate runs the cart and the bridge closed loop, not the hoist')
    for name in ('latency', 'noise', 'gust', 'delay'):
        if not (math.isfinite(getattr(args, name)) and getattr(args, name) >= 0.0):
            raise ValueError(f'argument --{name}: must be finite and >= 0, got {getattr(args, name)}')
    if not 0.0 <= args.dropout <= 1.0:
        raise ValueError(f'argument --dropout: must be in [0, 1], got {args.dropout}')
    if not args.settle > 0.0:
        raise ValueError(f'argument --settle: must be > 0 for simulate, got {args.settle}')
    plan, model, plant = make_plan(args)
    runs = run(args, plan, model, plant)
    T, settle = plan.duration, args.settle
    report = {}
    for name, trace in runs.items():
        a = trace.arrays()
        after = (a['t'] >= T) & (a['t'] < T + settle)
        settled = a['t'] >= T + settle
        correction = np.abs(a['correction']).max()
        report[name] = {'residual_after_motion_mm': 1e3 * float(np.abs(a['load'][after]).max()),
                        'residual_settled_mm': 1e3 * float(np.abs(a['load'][settled]).max()),
                        'peak_correction_mm': 1e3 * float(correction)}
    if args.json:
        print(json.dumps({'method': plan.method, 'duration': T, 'settle': settle, 'runs': report}))
    else:
        print(f'{plan.method}: {T:.3g} s, residual swing (mm) in the {settle:g} s after the motion and in the '
              f'{settle:g} s after that')
        print(f'{"":<8}{"after":>10}{"settled":>10}{"correction":>12}')
        for name, r in report.items():
            print(f'{name:<8}{r["residual_after_motion_mm"]:>10.3f}{r["residual_settled_mm"]:>10.3f}'
                  f'{r["peak_correction_mm"]:>12.2f}')
    if args.csv:
        _write_csv(args.csv, runs)
    if args.plot:
        _plot(args.plot, runs, plan)
    return 0


def _write_csv(path: str, runs: dict):
    names = list(runs)
    arrays = {name: runs[name].arrays() for name in names}
    t = arrays[names[0]]['t']
    header, cols = ['time'], [t]
    for name in names:
        a = arrays[name]
        header += [f'{name}_reference', f'{name}_correction', f'{name}_swing']
        cols += [np.atleast_2d(a['reference'].T)[0], np.atleast_2d(a['correction'].T)[0], a['load']]
    with open(path, 'w', newline='') as f:
        w = csv.writer(f)
        w.writerow(header)
        w.writerows(np.column_stack(cols).tolist())


def _plot(path: str, runs: dict, plan):
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, (swing, correction) = plt.subplots(2, 1, sharex=True, figsize=(8, 5.5))
    for name, trace in runs.items():
        a = trace.arrays()
        swing.plot(a['t'], 1e3 * a['load'], label=f'{name} loop')
        correction.plot(a['t'], 1e3 * np.atleast_2d(a['correction'].T)[0], label=f'{name} loop')
    for ax in (swing, correction):
        ax.axvline(plan.duration, color='grey', lw=0.8, ls='--')
        ax.grid(True, alpha=0.3)
        ax.legend(loc='upper right')
    swing.set_ylabel('load swing (mm)')
    correction.set_ylabel('cart correction (mm)')
    correction.set_xlabel('time (s)')
    swing.set_title(f'{plan.method}: the swing open and closed loop (the dashed line: the motion\'s end)')
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
