"""``crane-plan``: plan, compare and sweep anti-sway cart references offline (no ROS).

Exit status 0 on success, 2 on bad input or an impossible plan (one line on
stderr naming the problem), never a traceback.
"""
from __future__ import annotations

import argparse
import csv
import json
import math
import sys
import time

import numpy as np

from crane_msgs_py.crane.axes import AXES, LIMIT_QUANTITIES
from crane_msgs_py.crane.params import PARAMETER_DESCRIPTIONS, PARAMETER_NAMES, CraneParams
from crane_msgs_py.messages.names import BRIDGE_JOINT, CART_JOINT, HOIST_JOINT
from crane_planner.planning import METHODS, ROBUST_PARAMETERS, Plan, PlanError, PlanOptions, dispatch
from crane_planner.planning.hoisting import HOIST_SHAPER_DESIGNS
from crane_planner.planning.keep_out import DEFAULT_MARGIN, KeepOut, KeepOutError, boxes_from_flat
from crane_planner.planning.plan import AxesPlan
from crane_planner.planning.profiles import BASES
from crane_planner.serving import Planner
from crane_planner.serving.moves import Move, MoveBounds, MoveError, check_move, check_rests_keep_out, plan_keeping_out

from .evaluate import (
    DEFAULT_SETTLE,
    OUT_OF_PLANE,
    plan_report,
    residual_load_mm,
    simulate_plan,
    simulate_plans,
    vary_parameter,
)
from .progress import Progress

PROG = 'crane-plan'
#: Seconds ``choose`` observes after each motion by default (``sweep`` and ``plan``: DEFAULT_SETTLE).
CHOOSE_SETTLE = 5.0


class UsageError(Exception):
    """Bad command line; reported as one line on stderr with exit status 2."""


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # argparse would print usage too: the contract wants one line
        raise UsageError(message)


def _finite(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'{text!r} is not a number') from None
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f'must be finite, got {text}')
    return v


def _positive_int(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'{text!r} is not an integer') from None
    if v <= 0:
        raise argparse.ArgumentTypeError(f'must be > 0, got {v}')
    return v


def _method_list(text: str) -> list[str]:
    methods = [m.strip() for m in text.split(',') if m.strip()]
    bad = [m for m in methods if m not in METHODS]
    if bad or not methods:
        raise argparse.ArgumentTypeError(
            f'unknown method(s) {", ".join(bad) or repr(text)}; choose from {", ".join(METHODS)}')
    return methods


def _robust_list(text: str) -> tuple[str, ...]:
    names = tuple(n.strip() for n in text.split(',') if n.strip())
    bad = [n for n in names if n not in ROBUST_PARAMETERS]
    if bad or not names:
        raise argparse.ArgumentTypeError(
            f'unknown parameter(s) {", ".join(bad) or repr(text)}; choose from {", ".join(ROBUST_PARAMETERS)}')
    return names


class _Deprecated(argparse.Action):
    """An option's former spelling: still accepted, hidden from --help, and said to be deprecated."""

    def __init__(self, option_strings, dest, spelling: str, **kwargs):
        self.spelling = spelling
        super().__init__(option_strings, dest, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None):
        print(f'{parser.prog}: {option_string} is deprecated, use {self.spelling}', file=sys.stderr)
        setattr(namespace, self.dest, values)


def _add_crane_options(g):
    """An option per model parameter, spelled with dashes as every option is (--tau-hoist); a name's former
    underscore spelling (--tau_hoist) still accepted."""
    defaults = CraneParams()
    for name in PARAMETER_NAMES:
        option = '--' + name.replace('_', '-')
        g.add_argument(option, dest=name, type=_finite, default=getattr(defaults, name),
                       metavar='X', help=f'{PARAMETER_DESCRIPTIONS[name]} (default {getattr(defaults, name)})')
        if option != f'--{name}':
            g.add_argument(f'--{name}', dest=name, type=_finite, default=argparse.SUPPRESS, help=argparse.SUPPRESS,
                           action=_Deprecated, spelling=option)


def _add_model_options(p: argparse.ArgumentParser):
    g = p.add_argument_group('model (the planning model; defaults: paper Table 1, tau 0.01 s)')
    _add_crane_options(g)
    g.add_argument('--omega', type=_finite, nargs=2, metavar=('W1', 'W2'),
                   help='shaper design frequencies (rad/s); default: linearized model')
    g.add_argument('--damping', type=_finite, metavar='Z',
                   help="shaper design damping ratio (default: the model's modal damping ratios, "
                        '0 without --c1/--c2; 0 with --omega)')
    g.add_argument('--robust', type=_robust_list, metavar='P[,P...]',
                   help=f'parameters RVF is made insensitive to, from {",".join(ROBUST_PARAMETERS)} (default L1; '
                        'L2 with --hoist)')
    g.add_argument('--intervals', type=_positive_int, metavar='N',
                   help='collocation intervals for nvf/rvf (default: solver default)')
    g.add_argument('--solver', choices=('direct', 'indirect'), default='direct',
                   help='nvf/rvf solver: direct collocation + IPOPT, or the paper\'s indirect TPBVP')
    g.add_argument('--base', choices=BASES, default='quintic',
                   help="shapers' base motion: the paper's quintic, or the jerk-limited time-optimal profile under "
                        'the limits (default quintic)')
    h = p.add_argument_group('hoisting (with --hoist: the rope length moves during the move)')
    h.add_argument('--hoist', type=_finite, nargs=2, metavar=('L1_START', 'L1_GOAL'),
                   help='the upper cable goes from L1_START to L1_GOAL (m) during the move (it sets the model\'s '
                        'L1 to L1_START); the hoist follows its own servo --tau-hoist')
    h.add_argument('--hoist-shaper', choices=HOIST_SHAPER_DESIGNS, default='adaptive',
                   help='how a shaper follows the rope length: adaptive (fitted to the hoisting crane, the '
                        'default) or designed at the start, middle or end length')
    _add_axis_limits(p, g, h)


def _add_axis_limits(p, model_group, hoist_group):
    """Every axis's limits as options named as the axis names them (--max-velocity: the cart's,
    --max-hoist-velocity: the hoist's); the cart's with the model options, the hoist's with hoisting."""
    for a in AXES:
        group = model_group if a is AXES[0] else hoist_group if a.kind == 'hoist' else \
            p.add_argument_group(f'the {a.name} axis')
        for name, (quantity, _), unit in zip(a.limit_names, LIMIT_QUANTITIES, a.limit_units):
            group.add_argument('--' + name.replace('_', '-'), type=_finite, metavar=quantity[0].upper(),
                               help=f'{a.name} axis limit on |{quantity}| of its reference ({unit}); '
                                    f'a path constraint for nvf/rvf, a check for shapers')


#: Plant parameters the evaluation may change (``--plant-X``) and ``sweep`` may vary (g stays).
PLANT_PARAMETERS = ('L1', 'L2', 'm1', 'm2', 'tau', 'c1', 'c2')
#: Those ``sweep`` varies relative to the model's value (the dampings' default is 0).
SWEEP_PARAMETERS = ('L1', 'L2', 'm1', 'm2', 'tau')


def _add_plant_options(p: argparse.ArgumentParser):
    g = p.add_argument_group('evaluation (the simulated plant; defaults to the model)')
    for name in PLANT_PARAMETERS:
        g.add_argument(f'--plant-{name}', type=_finite, metavar='X', help=f'plant {PARAMETER_DESCRIPTIONS[name]}')
    g.add_argument('--settle', type=_finite, default=DEFAULT_SETTLE, metavar='S',
                   help=f'seconds observed after the motion (default {DEFAULT_SETTLE:g})')


def _add_displacements(p: argparse.ArgumentParser):
    p.add_argument('--displacement', type=_finite, required=True, metavar='D', help='cart displacement (m), along x')
    p.add_argument('--bridge', type=_finite, metavar='DY',
                   help='bridge displacement (m), along y: the crane is spatial, the move goes from 0 to (D, DY); '
                        'residuals are the norm of the load\'s horizontal offset')


def _bound(text: str) -> float:
    """A box side (m): a number, or -inf/inf for a side without end."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'{text!r} is not a number') from None
    if math.isnan(v):
        raise argparse.ArgumentTypeError('must be a number or +-inf, got nan')
    return v


def _add_keep_out(p: argparse.ArgumentParser):
    g = p.add_argument_group('routes (the masses, swing included, kept out of boxes; via points)')
    g.add_argument('--keep-out', type=_bound, nargs=6, action='append', metavar=('X0', 'X1', 'Y0', 'Y1', 'Z0', 'Z1'),
                   help='a box in crane_base (m; x along the cart, y along the bridge, z up, 0 at the suspension '
                        'point at the start; inf for a side without end), repeatable: both masses, predicted on '
                        'the planning model over the motion and the settle window, must keep --margin out of it, '
                        'else the plan is refused naming the box')
    g.add_argument('--margin', type=_finite, default=DEFAULT_MARGIN, metavar='M',
                   help=f'distance (m) the masses keep from every box (default {DEFAULT_MARGIN:g})')
    g.add_argument('--via', type=_via_point, action='append', metavar='P',
                   help='a point the reference passes without stopping, repeatable, in order: comma-separated '
                        'positions (m) of cart[,bridge][,hoist] as the move has them; nvf and rvf pass it exactly, '
                        'a shaper\'s straight path must pass within --via-tolerance')
    g.add_argument('--via-tolerance', type=_finite, default=0.01, metavar='M',
                   help='how near (m) a shaper\'s straight path must pass each via point (default 0.01)')


def _box_sides_as_values(argv: list) -> list:
    """argv with the six values after each ``--keep-out`` that argparse would take for options (``-inf``)
    marked as values (a leading space, which ``float`` ignores)."""
    argv = list(argv)
    for k, token in enumerate(argv):
        if token == '--keep-out':
            for i in range(k + 1, min(k + 7, len(argv))):
                if argv[i].lower() in ('-inf', '-infinity'):
                    argv[i] = ' ' + argv[i]
    return argv


def _keep_out(args) -> KeepOut:
    """The boxes and margin of ``--keep-out``/``--margin``; a bad one is a UsageError naming the option."""
    try:
        return KeepOut(boxes_from_flat([v for box in args.keep_out or () for v in box], '--keep-out'), args.margin)
    except KeepOutError as e:
        raise UsageError(f'argument {str(e).replace("keep_out_margin", "--margin")}') from None


def _via_point(text: str) -> tuple[float, ...]:
    """A via point: comma-separated positions (m) of the move's joints (cart[, bridge][, hoist])."""
    try:
        point = tuple(float(v) for v in text.split(','))
    except ValueError:
        raise argparse.ArgumentTypeError(f'{text!r} is not comma-separated numbers') from None
    if not all(math.isfinite(v) for v in point):
        raise argparse.ArgumentTypeError(f'{text!r}: positions must be finite')
    return point


def _served_plan(planner: Planner, method: str, args, model: CraneParams, options: PlanOptions) -> Plan:
    """With --keep-out or --via: the plan as the planner node serves it (``serving.moves.plan_keeping_out``):
    through the via points, past the boxes (NVF/RVF route over or around them); a refusal names the option."""
    joints = [CART_JOINT] + ([BRIDGE_JOINT] if args.bridge is not None else []) + ([HOIST_JOINT] if args.hoist else [])
    start = {CART_JOINT: 0.0, BRIDGE_JOINT: 0.0, HOIST_JOINT: args.hoist[0] if args.hoist else model.L1}
    goal = {CART_JOINT: args.displacement, BRIDGE_JOINT: args.bridge or 0.0,
            HOIST_JOINT: args.hoist[1] if args.hoist else model.L1}
    duration = 0.0 if getattr(args, 'fastest', False) else args.duration
    move = Move(method, tuple(joints), tuple(start[j] for j in joints), tuple(goal[j] for j in joints), duration,
                via=tuple(args.via or ()))
    bounds = MoveBounds(tuple(joints), method, math.inf, math.inf, args.via_tolerance)
    labels = {'via': 'argument --via: ', 'start': 'the start: ', 'goal': 'the goal: '}
    try:
        checked = check_move(move, bounds, None, model.L1)
        check_rests_keep_out(checked, model, args.keep_out_areas)
        return plan_keeping_out(planner, checked, bounds, model, options, args.keep_out_areas)
    except MoveError as exc:
        raise PlanError(labels.get(exc.field, '') + exc.reason) from None


def _add_task_options(p: argparse.ArgumentParser, fastest: bool = False):
    _add_keep_out(p)
    _add_displacements(p)
    if not fastest:
        p.add_argument('--duration', type=_finite, required=True, metavar='T', help='motion duration (s), > 0')
        return
    when = p.add_mutually_exclusive_group(required=True)
    when.add_argument('--duration', type=_finite, metavar='T', help='motion duration (s), > 0')
    when.add_argument('--fastest', action='store_true',
                      help='the shortest duration within the axis limits (needs --max-velocity or --max-acceleration)')


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog=PROG, description=__doc__.splitlines()[0].split(': ', 1)[1])
    sub = parser.add_subparsers(dest='command', required=True, parser_class=_Parser,
                                metavar='{plan,compare,sweep,choose,identify,report,simulate,runway}')

    p = sub.add_parser('plan', help='make one plan and evaluate it on the plant')
    p.add_argument('--method', choices=METHODS, required=True)
    _add_task_options(p, fastest=True)
    _add_model_options(p)
    _add_plant_options(p)
    p.add_argument('--json', action='store_true', help='print the contract JSON object')
    p.add_argument('--csv', metavar='FILE',
                   help='write time, position, velocity, acceleration, jerk, theta1, theta2 (1 ms); with --bridge '
                        'also bridge_position, bridge_velocity, bridge_acceleration; with --hoist also '
                        'hoist_position (the rope length L1), hoist_velocity, hoist_acceleration; with --bridge '
                        'then phi1, phi2')
    p.add_argument('--plot', metavar='FILE',
                   help='write a PNG of the plan profiles and the swing (with --bridge a top view of the load\'s path)')

    from .simulate_cli import add_options as add_simulate_options
    p = sub.add_parser('simulate', help='run one plan on the plant with the sway feedback, open and closed loop, '
                                        'with pushes, wind, gusts and a camera\'s latency, noise and dropout')
    p.add_argument('--method', choices=METHODS, required=True)
    _add_task_options(p)
    _add_model_options(p)
    _add_plant_options(p)
    add_simulate_options(p)

    p = sub.add_parser('compare', help='make and evaluate plans of several methods')
    _add_task_options(p)
    p.add_argument('--methods', type=_method_list, metavar='M,M,...',
                   help=f'methods to compare (default: all of {",".join(METHODS)} that fit the duration)')
    _add_model_options(p)
    _add_plant_options(p)
    p.add_argument('--json', action='store_true', help='print a JSON list of plan objects')
    p.add_argument('--plot', metavar='FILE', help='write a PNG: velocity, acceleration and load swing per method')

    p = sub.add_parser('sweep', help='residual load swing while one plant parameter varies')
    p.add_argument('--param', choices=SWEEP_PARAMETERS, default='L1')
    p.add_argument('--span', type=_finite, default=0.3, metavar='R',
                   help='relative span, values x (1 +- R) (default 0.3)')
    p.add_argument('--points', type=int, default=61, metavar='N', help='number of values (>= 2, default 61)')
    _add_task_options(p)
    p.add_argument('--methods', type=_method_list, metavar='M,M,...',
                   help='methods to sweep (default: all that fit the duration)')
    _add_model_options(p)
    _add_plant_options(p)
    p.add_argument('--json', action='store_true', help='print the sweep JSON object')
    p.add_argument('--csv', metavar='FILE', help='write value and one residual column (mm) per method')
    p.add_argument('--plot', metavar='FILE', help='write a PNG of residual load swing vs the parameter')

    p = sub.add_parser('choose', help='per method: the fastest move within the axis limits and its worst swing '
                                      'over an uncertainty band; marks the fastest within a tolerance')
    _add_displacements(p)
    p.add_argument('--span', type=_finite, default=0.2, metavar='R',
                   help='relative uncertainty of L1: plants at L1 x (1 +- R) (default 0.2)')
    p.add_argument('--span-L2', type=_finite, metavar='R',
                   help='relative uncertainty of L2 too: each L1 also with L2 x (1 - R), L2, L2 x (1 + R)')
    p.add_argument('--points', type=int, default=21, metavar='N', help='L1 values of the band (>= 2, default 21)')
    p.add_argument('--tolerance-mm', type=_finite, default=1.0, metavar='X',
                   help='largest acceptable residual load swing over the band (mm, default 1)')
    p.add_argument('--methods', type=_method_list, metavar='M,M,...', help='methods to weigh (default: all)')
    p.add_argument('--settle', type=_finite, default=CHOOSE_SETTLE, metavar='S',
                   help=f'seconds observed after each motion (default {CHOOSE_SETTLE:g}: about three periods '
                        'of the slow mode, where the two modes have met in phase)')
    _add_model_options(p)
    p.add_argument('--json', action='store_true', help='print the choice as one JSON object')
    p.add_argument('--plot', metavar='FILE', help='write a PNG: worst residual vs fastest duration per method')

    p = sub.add_parser('report', help='figures and a residual-swing table from a rosbag2 recording')
    p.add_argument('bag', metavar='BAG_DIR', help='a recording of crane-record or crane-demo --record')
    p.add_argument('--out', default='.', metavar='DIR', help='folder for the figures (default .)')
    p.add_argument('--settle', type=_finite, metavar='S',
                   help='seconds after each motion the residual is taken over (default: until the next motion)')
    p.add_argument('--json', action='store_true', help='print the table as JSON')

    p = sub.add_parser('identify', help='estimate L1, L2, mass ratio, joint damping and tau from a recorded move')
    source = p.add_mutually_exclusive_group(required=True)
    source.add_argument('--csv', metavar='FILE', help='recording with columns t, cart, theta1, theta2 [, reference]')
    source.add_argument('--bag', metavar='DIR',
                        help='rosbag2 recording (MCAP or SQLite) of joint_states [and reference]')
    _add_crane_options(p.add_argument_group(
        'nominal model (its total mass m1 + m2 and g are kept; defaults: paper Table 1)'))
    p.add_argument('--json', action='store_true', help='print the estimates as one JSON object')
    p.add_argument('--params-out', metavar='FILE', help='write a ROS 2 params file for the planner node')
    p.add_argument('--plot', metavar='FILE', help='write a PNG of the measured and fitted swing')

    from .runway_cli import add_options as add_runway_options
    p = sub.add_parser('runway', help='plan several cranes\' moves on one runway together, first published, first '
                                      'served, and draw a runway view')
    add_runway_options(p)
    return parser


def _model_and_options(args) -> tuple[CraneParams, PlanOptions]:
    model = CraneParams.of(vars(args))
    if args.hoist is not None:
        if not args.hoist[0] > 0.0:
            raise UsageError(f'argument --hoist: L1_START must be > 0, got {args.hoist[0]:g}')
        model = model.replace(L1=args.hoist[0])  # the plant starts there too
    options = PlanOptions(omega=tuple(args.omega) if args.omega else None, damping=args.damping,
                          robust=args.robust or ('L1',), hoist_robust=args.robust or ('L2',),
                          intervals=args.intervals, solver=args.solver,
                          base=args.base, hoist_shaper=args.hoist_shaper,
                          limits={a.name: a.limits(*(getattr(args, n) for n in a.limit_names)) for a in AXES})
    return model, options


def _plant(args, model: CraneParams) -> CraneParams:
    changes = {n: getattr(args, f'plant_{n}') for n in PLANT_PARAMETERS
               if getattr(args, f'plant_{n}') is not None}
    return model.replace(**changes)


def _timed_plan(planner: Planner, method, args, model, options) -> tuple[Plan, float]:
    # dispatch with the planner's solvers, as Planner.plan and .fastest do, which take no bridge (yet)
    t0 = time.perf_counter()
    axes = {'hoist': args.hoist, 'bridge': args.bridge}
    if args.keep_out_areas or args.via:
        plan = _served_plan(planner, method, args, model, options)
    elif getattr(args, 'fastest', False):
        plan = dispatch.fastest(method, args.displacement, model, options, planner.variational, **axes)
    else:
        plan = dispatch.plan(method, args.displacement, args.duration, model, options, planner.variational, **axes)
    return plan, time.perf_counter() - t0


def _print_table(reports: list[dict]):
    clearance = any('min_clearance' in r for r in reports)
    head = (f'{"method":<7}{"plan s":>8}{"peak v":>9}{"peak a":>9}{"rms a":>9}{"peak j":>9}'
            f'{"peak th1":>10}{"peak th2":>10}{"resid mm":>10}' + (f'{"clear mm":>10}' if clearance else ''))
    print(head)
    print('-' * len(head))
    for r in reports:
        pk, rm = r['peak'], r['rms']
        print(f'{r["method"]:<7}{r["plan_time_s"]:>8.3f}{pk["velocity"]:>9.4f}{pk["acceleration"]:>9.4f}'
              f'{rm["acceleration"]:>9.4f}{pk["jerk"]:>9.3f}{pk["theta1"]:>10.5f}{pk["theta2"]:>10.5f}'
              f'{r["residual"]["load_mm"]:>10.4f}' + (f'{r["min_clearance"] * 1e3:>10.1f}' if clearance else ''))
    print('units: m/s, m/s^2, m/s^3, rad, mm (peaks and RMS over the motion, residual after it'
          + (', clearance: the masses\' smallest distance to a keep-out box' if clearance else '') + ')')


def _check_settle(args):
    if args.settle < 0:
        raise UsageError(f'argument --settle: must be >= 0, got {args.settle}')


def cmd_plan(args) -> int:
    _check_settle(args)
    model, options = _model_and_options(args)
    plant = _plant(args, model)
    plan, plan_time = _timed_plan(Planner(), args.method, args, model, options)
    ev = simulate_plan(plan, plant, args.settle)
    report = plan_report(ev, plan_time)
    if args.json:
        print(json.dumps(report))
    else:
        _print_table([report])
    if args.csv:
        _write_plan_csv(args.csv, ev)
        _say(args, f'wrote {args.csv}')
    if args.plot:
        from .figures import plot_plan
        plot_plan(ev, args.plot, args.keep_out_areas)
        _say(args, f'wrote {args.plot}')
    return 0


def _say(args, text: str):
    # With --json stdout carries only JSON; notes go to stderr.
    print(text, file=sys.stderr if getattr(args, 'json', False) else sys.stdout)


def _write_plan_csv(path: str, ev):
    """The cart's reference and the simulated swing; then each further axis's reference (the hoist's position:
    the rope length), in ``AXES`` order; with a bridge the out-of-plane swing last (contract)."""
    plan_s = ev.plan.evaluate(ev.sim.t)
    header = ['time', 'position', 'velocity', 'acceleration', 'jerk', 'theta1', 'theta2']
    cols = [ev.sim.t, plan_s.position, plan_s.velocity, plan_s.acceleration, plan_s.jerk, ev.sim.theta1[0],
            ev.sim.theta2[0]]
    for name in ev.plan.joint_names[1:] if isinstance(ev.plan, AxesPlan) else ():
        axis_s = ev.plan.evaluate_axis(name, ev.sim.t)
        header += [f'{name}_position', f'{name}_velocity', f'{name}_acceleration']
        cols += [axis_s.position, axis_s.velocity, axis_s.acceleration]
    for name in OUT_OF_PLANE if 'phi1' in ev.sim.states else ():
        header.append(name)
        cols.append(ev.sim.states[name][0])
    with open(path, 'w', newline='') as f:
        w = csv.writer(f)
        w.writerow(header)
        w.writerows(np.column_stack(cols).tolist())


def _plans(args, model, options, progress=None) -> tuple[list[Plan], list[float]]:
    """Plans of ``args.methods``; with the default (all) methods, impossible ones are skipped with a note."""
    planner, plans, times = Planner(), [], []
    explicit = args.methods_given
    for method in args.methods:
        try:
            plan, plan_time = _timed_plan(planner, method, args, model, options)
        except PlanError as e:
            if explicit:
                raise
            print(f'{PROG}: skipped {method}: {e}', file=sys.stderr)
            continue
        finally:
            if progress is not None:
                progress.step(f'planned {method}')
        plans.append(plan)
        times.append(plan_time)
    if not plans:
        raise PlanError('no method could make this plan')
    return plans, times


def cmd_compare(args) -> int:
    _check_settle(args)
    model, options = _model_and_options(args)
    plant = _plant(args, model)
    plans, times = _plans(args, model, options)
    evaluations = simulate_plans(plans, plant, args.settle)
    reports = [plan_report(ev, t) for ev, t in zip(evaluations, times)]
    if args.json:
        print(json.dumps(reports))
    else:
        hoisting = f' while L1 goes {args.hoist[0]:g} -> {args.hoist[1]:g} m' if args.hoist else ''
        print(f'{_describe_move(args)} in {args.duration:g} s{hoisting}; model {_describe(model)}; '
              f'plant {_describe(plant)}')
        _print_table(reports)
    if args.plot:
        from .figures import plot_compare
        plot_compare(evaluations, args.plot)
        _say(args, f'wrote {args.plot}')
    return 0


def _describe_move(args) -> str:
    """The move's displacement: the cart's (m), with a bridge the pair (x, y)."""
    if args.bridge is None:
        return f'{args.displacement:g} m'
    return f'({args.displacement:g}, {args.bridge:g}) m'


def _describe(p: CraneParams) -> str:
    return ' '.join(f'{n}={getattr(p, n):g}' for n in PARAMETER_NAMES)


def cmd_sweep(args) -> int:
    if args.points < 2:
        raise UsageError(f'argument --points: a sweep needs at least 2 points, got {args.points}')
    if not 0.0 < args.span < 1.0:
        raise UsageError(f'argument --span: must be in (0, 1), got {args.span}')
    _check_settle(args)
    model, options = _model_and_options(args)
    base_plant = _plant(args, model)
    values, plants = vary_parameter(base_plant, args.param, args.span, args.points)
    with Progress(len(args.methods) + 1, 'sweep', PROG) as progress:
        plans, _ = _plans(args, model, options, progress)
        evaluations = simulate_plans(plans, plants, args.settle)
        progress.step(f'simulated {len(plans)} x {len(plants)} runs')
    result = {'param': args.param, 'values': values.tolist(), 'methods': {
        ev.plan.method: {'load_mm': residual_load_mm(ev).tolist()} for ev in evaluations}}
    if args.json:
        print(json.dumps(result))
    else:
        _print_sweep(result)
    if args.csv:
        with open(args.csv, 'w', newline='') as f:
            w = csv.writer(f)
            w.writerow([args.param] + [f'{m}_load_mm' for m in result['methods']])
            w.writerows(np.column_stack([values] + [v['load_mm'] for v in result['methods'].values()]).tolist())
        _say(args, f'wrote {args.csv}')
    if args.plot:
        from .figures import plot_sweep
        plot_sweep(result, args.plot, nominal=getattr(model, args.param))
        _say(args, f'wrote {args.plot}')
    return 0


def _print_sweep(result: dict):
    methods = list(result['methods'])
    print(f'residual load swing (mm) vs plant {result["param"]}')
    print(f'{result["param"]:>10}' + ''.join(f'{m:>9}' for m in methods))
    for i, v in enumerate(result['values']):
        print(f'{v:>10.4f}' + ''.join(f'{result["methods"][m]["load_mm"][i]:>9.3f}' for m in methods))


def cmd_identify(args) -> int:
    from crane_planner.identification import identify, read_bag, read_csv
    model = CraneParams.of(vars(args))
    source = args.csv or args.bag
    with Progress(2, 'identify', PROG) as progress:
        recording = read_csv(args.csv) if args.csv else read_bag(args.bag)
        progress.step(f'read {recording.t.size} samples')
        result = identify(recording, model)
        progress.step(f'fitted in {result.iterations} iterations')
    if args.json:
        print(json.dumps(result.as_json()))
    else:
        _print_identification(source, recording, result)
    for warning in result.warnings:
        print(f'{PROG}: warning: {warning}', file=sys.stderr)
    if args.params_out:
        with open(args.params_out, 'w') as f:
            f.write(result.params_yaml())
        _say(args, f'wrote {args.params_out} (planner: --ros-args --params-file {args.params_out})')
    if args.plot:
        from .figures import plot_identification
        plot_identification(recording, result, args.plot)
        _say(args, f'wrote {args.plot}')
    return 0


def _print_identification(source: str, rec, result):
    v, s = result.values, result.std
    print(f'identified from {source}: {rec.t.size} samples at {1.0 / rec.period:.4g} Hz over {rec.duration:.2f} s')
    print(f'{"parameter":<22}{"estimate":>12}{"std error":>12}')
    rows = [('L1 (m)', 'L1', 4), ('L2 (m)', 'L2', 4), ('mass ratio m2/(m1+m2)', 'mass_ratio', 4),
            ('c1 (N m s/rad)', 'c1', 6), ('c2 (N m s/rad)', 'c2', 6)]
    if v['tau'] is not None:
        rows.append(('tau (s)', 'tau', 5))
    for label, key, digits in rows:
        print(f'{label:<22}{v[key]:>12.{digits}f}{s[key]:>12.{digits}f}')
    for k in (1, 2):
        w, z = v[f'omega{k}'], v[f'zeta{k}']
        print(f'mode {k}: omega {w:.4f} +- {s[f"omega{k}"]:.4f} rad/s ({w / (2 * math.pi):.4f} Hz), '
              f'zeta {z:.4f} +- {s[f"zeta{k}"]:.4f}')
    print(f'rms residual {1e3 * result.rms_residual_rad:.3f} mrad; {result.iterations} iterations, '
          f'{result.fit_time_s:.2f} s')
    print(f'planner model: {_describe(result.params)}')


def cmd_choose(args) -> int:
    from .choose import band, choose
    if args.points < 2:
        raise UsageError(f'argument --points: the band needs at least 2 points, got {args.points}')
    for name in ('span', 'span_L2'):
        value = getattr(args, name)
        if value is not None and not 0.0 <= value < 1.0:
            raise UsageError(f'argument --{name.replace("_", "-")}: must be in [0, 1), got {value}')
    if args.tolerance_mm < 0:
        raise UsageError(f'argument --tolerance-mm: must be >= 0, got {args.tolerance_mm}')
    _check_settle(args)
    model, options = _model_and_options(args)
    travel = [CART_JOINT] if args.bridge is None else [CART_JOINT, BRIDGE_JOINT]
    if not any(options.limits_of(name).bounds_speed for name in travel):
        raise UsageError('choose needs axis limits: --max-velocity and/or --max-acceleration'
                         + ('' if args.bridge is None else ' (or the bridge\'s)'))
    plants = band(model, args.span, args.points, args.span_L2)
    with Progress(len(args.methods) + 1, 'choose', PROG) as progress:
        result = choose(args.displacement, model, options, args.methods, plants, args.tolerance_mm, args.settle,
                        progress=progress.step, hoist=args.hoist, bridge=args.bridge)
    if args.json:
        print(json.dumps(result.as_json()))
    else:
        _print_choice(args, result)
    if args.plot:
        from .figures import plot_choice
        plot_choice(result, args.plot)
        _say(args, f'wrote {args.plot}')
    return 0


def _print_choice(args, result):
    L1s = sorted({a for a, _ in result.plants})
    L2s = sorted({b for _, b in result.plants})
    bridge = '' if args.bridge is None else (f', bridge v {args.max_bridge_velocity or "-"} m/s, '
                                             f'a {args.max_bridge_acceleration or "-"} m/s^2, '
                                             f'j {args.max_bridge_jerk or "-"} m/s^3')
    print(f'{_describe_move(args)}, limits v {args.max_velocity or "-"} m/s, a {args.max_acceleration or "-"} m/s^2, '
          f'j {args.max_jerk or "-"} m/s^3{bridge}; band L1 {L1s[0]:.3f}-{L1s[-1]:.3f} m'
          + (f', L2 {L2s[0]:.3f}-{L2s[-1]:.3f} m' if len(L2s) > 1 else '') + f' ({len(result.plants)} plants)')
    head = f'{"method":<7}{"T* s":>8}{"peak v":>9}{"peak a":>9}{"peak j":>9}{"worst mm":>10}  verdict'
    print(head)
    print('-' * len(head))
    for c in result.candidates:
        if c.duration is None:
            print(f'{c.method:<7}{"-":>8}{"-":>9}{"-":>9}{"-":>9}{"-":>10}  {c.verdict}')
            continue
        mark = '*' if c.method == result.chosen else ' '
        print(f'{c.method:<6}{mark}{c.duration:>8.3f}{c.peak_velocity:>9.4f}{c.peak_acceleration:>9.4f}'
              f'{c.peak_jerk:>9.3f}{c.worst_residual_mm:>10.3f}  {c.verdict}')
    print(f'chosen: {result.chosen or "none (no method within the tolerance)"}')


def cmd_report(args) -> int:
    from pathlib import Path

    from .report import motion_table, read_bag, write_figures
    if args.settle is not None and args.settle < 0:
        raise UsageError(f'argument --settle: must be >= 0, got {args.settle}')
    with Progress(2, 'report', PROG) as progress:
        data = read_bag(args.bag)
        progress.step(f'read {len(data.states)} joint_states, {len(data.reference)} references')
        rows = motion_table(data, args.settle)
        written = write_figures(data, Path(args.out))
        progress.step(f'{len(written)} figures')
    if args.json:
        print(json.dumps({'L1': data.L1, 'L2': data.L2, 'motions': rows}))
    else:
        print(f'{args.bag}: {len(data.states)} joint_states over {data.states[-1, 0]:.1f} s, '
              f'{len(data.reference)} reference samples, {len(rows)} motions; L1 {data.L1:.3f} m, L2 {data.L2:.3f} m')
        print(f'{"start s":>9}{"T s":>8}{"goal m":>9}{"observed s":>12}{"residual mm":>13}')
        for r in rows:
            residual = '-' if r['residual_mm'] is None else f'{r["residual_mm"]:.3f}'
            print(f'{r["start_s"]:>9.3f}{r["duration_s"]:>8.3f}{r["goal_m"]:>9.4f}{r["observed_s"]:>12.2f}'
                  f'{residual:>13}')
    for path in written:
        _say(args, f'wrote {path}')
    return 0


def cmd_simulate(args) -> int:
    from .simulate_cli import cmd_simulate as simulate

    def make_plan(args):
        model, options = _model_and_options(args)
        plan, _ = _timed_plan(Planner(), args.method, args, model, options)
        return plan, model, _plant(args, model)
    return simulate(args, make_plan)


def cmd_runway(args) -> int:
    from .runway_cli import cmd_runway as runway
    return runway(args, lambda text: _say(args, text))


COMMANDS = {'plan': cmd_plan, 'compare': cmd_compare, 'sweep': cmd_sweep, 'choose': cmd_choose,
            'identify': cmd_identify, 'report': cmd_report, 'simulate': cmd_simulate, 'runway': cmd_runway}


def main(argv=None) -> int:
    try:
        args = build_parser().parse_args(_box_sides_as_values(sys.argv[1:] if argv is None else list(argv)))
        args.methods_given = getattr(args, 'methods', None) is not None
        if hasattr(args, 'keep_out'):
            args.keep_out_areas = _keep_out(args)
        if args.command != 'plan' and not args.methods_given:
            args.methods = list(METHODS)
        return COMMANDS[args.command](args)
    except (UsageError, ValueError) as e:
        # ValueError covers ParameterError and PlanError: bad values, impossible plans.
        print(f'{PROG}: error: {e}', file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f'{PROG}: interrupted', file=sys.stderr)
        return 130
    except OSError as e:
        print(f'{PROG}: error: {e}', file=sys.stderr)
        return 2


if __name__ == '__main__':
    sys.exit(main())
