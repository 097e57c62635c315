"""The planner node's parameters: the table it declares (``PARAMETERS``) and ``Config``, one validated set.

Pure Python, no ROS import: the node declares it (``node_parameters.declare``),
``devtools/make_params_files.py`` writes ``config/planner.yaml`` from the same
table and the benchmarks read its defaults.
"""
from __future__ import annotations

from dataclasses import dataclass

from crane_msgs_py.crane.axes import AXES
from crane_msgs_py.crane.params import (
    CraneParams,
    ParameterError,
    check_choice,
    check_nonnegative,
    check_positive,
    model_parameters,
    parameter_range,
    renamed_from,
)
from crane_msgs_py.messages.names import BRIDGE_JOINT, CART_JOINT, DEFAULT_FRAME_ID, HOIST_JOINT, check_joints

from ..planning import METHODS, ROBUST_PARAMETERS, PlanOptions
from ..planning.continuation import AxisState, MotionState, problem_start
from ..planning.dispatch import VariationalRequest, hoisting_options
from ..planning.hoisting import HOIST_SHAPER_DESIGNS
from ..planning.keep_out import KeepOut
from ..planning.methods import Family, methods_of, methods_supporting
from ..planning.profiles import BASES
from ..planning.routing import Route
from ..planning.signals import Swing
from ..runway.config import PARAMETERS as RUNWAY_PARAMETERS
from ..runway.config import RunwayConfig
from .execution import STREAM_TIMEOUT
from .moves import MoveBounds
from .transitions import stop_options

#: The crane model's parameters' upper bounds (each from 0) for rclpy's range check.
MODEL_BOUNDS = {'L1': 100.0, 'L2': 100.0, 'm1': 1e5, 'm2': 1e5, 'g': 100.0, 'tau': 10.0, 'c1': 1e3, 'c2': 1e3,
                'tau_hoist': 10.0}
#: Every axis's limits of the reference, a map over the joints of the registry (``Axis.limit_parameters``):
#: ``limits.cart.max_velocity``, ``limits.hoist.max_jerk``, ...; 0 = no limit. Each was named as the planning
#: options name it (``max_velocity``, ``max_hoist_jerk``, ...): that name is still taken for one release.
AXIS_LIMIT_PARAMETERS = {
    name: (0.0, f'the {a.name}\'s axis limit {what} of its reference ({unit}); 0 = no limit',
           {**parameter_range(0.0, hi), **renamed_from(former)})
    for a in AXES
    for name, former, unit, what, hi in zip(a.limit_parameters(), a.limit_names, a.limit_units,
                                            ('|v|', '|a|', 'on the jerk'), (1e3, 1e4, 1e6))}
#: name -> (default, description, descriptor fields; a range as (lo, hi)). Ranges are the
#: outer bounds rclpy enforces; the exact domain (e.g. > 0) is checked by
#: ``Config.from_values``, whose reason the node reports on /diagnostics.
PARAMETERS = {
    **model_parameters(bound=MODEL_BOUNDS.__getitem__),
    'method': ('rvf', f'method of a move that names none: one of {", ".join(METHODS)}',
               {'additional_constraints': f'one of {", ".join(METHODS)}'}),
    'robust_parameters': (['L1'], f'parameters RVF is made insensitive to, among {", ".join(ROBUST_PARAMETERS)}',
                          {'additional_constraints': f'distinct names among {", ".join(ROBUST_PARAMETERS)}'}),
    'shaper_frequencies': ([], 'shaper design frequencies (rad/s), one per mode; empty = the linearized '
                               "model's modal frequencies", {'additional_constraints': 'each > 0'}),
    'shaper_damping': (-1.0, "shaper design damping ratio, >= 0 and < 1; -1 = the model's modal damping "
                             'ratios (0 when c1 = c2 = 0; 0 with shaper_frequencies set)',
                       parameter_range(-1.0, 1.0)),
    'intervals': (0, 'collocation intervals of NVF/RVF, 4..2000; 0 = the solver default',
                  parameter_range(0, 2000)),
    'sample_period': (0.0, 'knot spacing of returned plans (s); 0 = knots where the plan needs them '
                           '(its breakpoints, and as few more as keep the streamer\'s quintic Hermite '
                           'interpolation within 1 um); the last knot is exactly at the end',
                      parameter_range(0.0, 1.0)),
    'frame_id': (DEFAULT_FRAME_ID, 'frame of returned trajectories', {}),
    'joints': (['cart'], "the actuated joints this planner serves: [cart], [cart, hoist], [cart, bridge] or "
                         "[cart, bridge, hoist] (the hoist's position is the upper cable's length L1; with the "
                         'bridge NVF and RVF plan on the spatial crane; every array of a Move is per joint in this '
                         'order); fixed at start-up',
               {'additional_constraints': 'cart, then any of bridge, hoist in this order', 'read_only': True}),
    'keep_out': ([], 'protected areas: axis-aligned boxes in crane_base (x along the cart, y along the bridge, z up, '
                     '0 at the suspension point), six numbers each, x0 x1 y0 y1 z0 z1 (min <= max, .inf allowed), '
                     'flat; both masses, swing included, are predicted on the planning model to keep at least '
                     'keep_out_margin out of every box over a plan and its settle window, else it is refused',
                 {'additional_constraints': 'a multiple of 6 numbers, each box min <= max per axis'}),
    'via_tolerance': (0.01, 'how near (m) a shaper\'s straight path must pass each via point of a move (NVF and RVF '
                            'pass them exactly), else the move is refused naming the point',
                      parameter_range(0.0, 10.0)),
    'keep_out_margin': (0.02, 'distance (m) both masses keep from every keep_out box, >= 0',
                        parameter_range(0.0, 100.0)),
    'publish_lead': (0.3, 'an executed trajectory is sent to the streamer this long (s) before its start '
                          'time, so that a goal canceled before then streams nothing (one starting as '
                          'soon as possible is sent at once)', parameter_range(0.0, 10.0)),
    'stream_timeout': (STREAM_TIMEOUT,
                       'an executed goal whose stream_state is silent this long (s) while its motion moves is '
                       'aborted naming the lost stream (the streamer died or stopped; the axes brake to rest '
                       'by their fault reaction); longer than the 1 s of ticks a stalled streamer catches up on',
                       parameter_range(0.05, 60.0)),
    'residual_tolerance': (0.002, 'a goal succeeds only if the load is quiet: its residual swing (m, the peak load '
                                  'excursion measured over its settle window) at most this, else it ends aborted with '
                                  'the residual in its message; a goal sent while the load swings more than half of it '
                                  'is planned from the measured swing (a shaper\'s after settle_method damps it), > 0',
                           parameter_range(0.0, 10.0)),
    'max_duration': (60.0, 'longest motion served (s), > 0', parameter_range(0.0, 3600.0)),
    'max_displacement': (10.0, 'largest |goal - start| served (m), > 0',
                         parameter_range(0.0, 1e4)),
    **AXIS_LIMIT_PARAMETERS,
    'hoist_robust_parameters': (['L2'], 'parameters RVF is made insensitive to in a move that hoists (the '
                                        f'payload\'s cable by default), among {", ".join(ROBUST_PARAMETERS)}',
                                {'additional_constraints': f'distinct names among {", ".join(ROBUST_PARAMETERS)}'}),
    'hoist_shaper': ('adaptive', 'how a shaper follows the rope length in a move that hoists: adaptive (fitted '
                                 'to the hoisting crane) or designed at the start, middle or end length',
                     {'additional_constraints': f'one of {", ".join(HOIST_SHAPER_DESIGNS)}'}),
    'shaper_base': ('quintic', "the motion shapers shape: 'quintic' (the paper's) or 'limits' (the jerk-limited "
                               'time-optimal profile under the axis limits; needs limits.cart.max_velocity or '
                               'limits.cart.max_acceleration)',
                    {'additional_constraints': f'one of {", ".join(BASES)}'}),
    'handover_lead': (0.042, 'a new NVF/RVF goal during a motion takes over this long (s) after it arrives, from '
                            'the state the motion is in then (a plan taking longer is planned again further ahead, '
                            'and the next goal of its method and joints starts from a lead its recent planning '
                            'times fit); a settle plans this far ahead too',
                      parameter_range(0.001, 1.0)),
    'shaper_handover_lead': (0.001, 'the same for a shaper; shorter than its planning and transport on purpose: '
                                    'a change reaching the streamer after its tick starts at the next one, '
                                    'delayed (up to 20 ms, no swing added): the earliest handover possible',
                             parameter_range(0.001, 1.0)),
    'handover_priority': (40, 'SCHED_FIFO priority (1..99) of the thread that takes ExecuteMove requests and plans '
                              'and sends a shaper\'s handover: Python that, at normal priority beside the 1 kHz nodes, '
                              'may wait for a core as long as it runs; the middleware\'s receive threads run one '
                              'below; 0 = normal scheduling (also without the privilege: a warning)',
                          parameter_range(0, 99)),
    'handover_warmup': (0.02, 'while a motion streams, every this many s the goals\' thread plans a shaper\'s '
                              'handover of it and serializes its trajectory without sending it, so that a real '
                              'goal\'s handover runs on warm caches: code left untouched for a while beside the '
                              '1 kHz nodes runs several times slower; 0 = off',
                        parameter_range(0.0, 10.0)),
    'settle_method': ('nvf', '~/settle plans with this method: nvf or rvf (a shaper cannot damp a swing it did not '
                             'cause)', {'additional_constraints': 'nvf or rvf'}),
    'max_solve_time': (1.0, 'budget of one NVF/RVF solve (s), > 0: a request not solved within it is '
                            'refused; every request is answered within this + 0.5 s',
                       parameter_range(0.0, 60.0)),
    'solver_pool_size': (8, 'NVF/RVF solver instances per method in the node process when solver_processes '
                            'is 0, 1..32, made as concurrent requests need them (a few MB each; the first of a '
                            'method builds its NLP, several times that); unused with worker processes',
                         parameter_range(1, 32)),
    'solver_processes': (3, 'worker processes solving NVF/RVF side by side, 0..16, started with the node '
                            '(tens of MB each beyond what they share); 0 = solve in threads of the node process '
                            "only, where solves take turns at IPOPT's linear solver (read-only)",
                         dict(parameter_range(0, 16), read_only=True)),
    **RUNWAY_PARAMETERS,  # (the streamer declares the same: the same values on both)
}


@dataclass(frozen=True)
class Config:
    """One consistent set of the node's parameters, validated; swapped whole on a change."""

    params: CraneParams
    options: PlanOptions
    method: str
    sample_period: float
    frame_id: str
    max_duration: float
    max_displacement: float
    solver_pool_size: int
    solver_processes: int
    joints: tuple
    publish_lead: float
    handover_lead: float = 0.042
    shaper_handover_lead: float = 0.001
    settle_method: str = 'nvf'
    handover_priority: int = 40
    handover_warmup: float = 0.02
    stream_timeout: float = STREAM_TIMEOUT
    keep_out: KeepOut = KeepOut()
    via_tolerance: float = 0.01
    residual_tolerance: float = 0.002
    runway: RunwayConfig = RunwayConfig()

    @property
    def bounds(self) -> MoveBounds:
        return MoveBounds(self.joints, self.method, self.max_displacement, self.max_duration, self.via_tolerance)

    @classmethod
    def from_values(cls, v: dict, namespace: str = '') -> 'Config':
        """From parameter values by name (``namespace`` names the crane on a runway when ``crane_name`` is
        empty); ParameterError names the bad one."""
        params = CraneParams.of(v)
        check_choice('method', v['method'], METHODS)
        intervals = int(v['intervals'])
        options = PlanOptions(
            omega=tuple(v['shaper_frequencies']) or None,
            damping=None if v['shaper_damping'] == -1.0 else v['shaper_damping'],
            robust=tuple(v['robust_parameters']), intervals=intervals or None,
            base=v['shaper_base'],
            max_solve_time=check_positive('max_solve_time', v['max_solve_time']),
            limits={a.name: a.limits(*(v[n] or None for n in a.limit_parameters())) for a in AXES},
            hoist_robust=tuple(v['hoist_robust_parameters']),
            hoist_shaper=v['hoist_shaper'])
        if not v['frame_id']:
            raise ParameterError('frame_id must not be empty')
        joints = check_joints(v['joints'])
        check_choice('settle_method', v['settle_method'], methods_supporting('settle'))
        return cls(params, options, v['method'], check_nonnegative('sample_period', v['sample_period']),
                   v['frame_id'], check_positive('max_duration', v['max_duration']),
                   check_positive('max_displacement', v['max_displacement']), int(v['solver_pool_size']),
                   int(v['solver_processes']), joints, check_nonnegative('publish_lead', v['publish_lead']),
                   check_positive('handover_lead', v['handover_lead']),
                   check_positive('shaper_handover_lead', v['shaper_handover_lead']), v['settle_method'],
                   int(v['handover_priority']), check_nonnegative('handover_warmup', v['handover_warmup']),
                   check_positive('stream_timeout', v['stream_timeout']),
                   KeepOut.from_values(v['keep_out'], v['keep_out_margin']),
                   check_nonnegative('via_tolerance', v['via_tolerance']),
                   check_positive('residual_tolerance', v['residual_tolerance']),
                   RunwayConfig.from_values(v, namespace))

    def warmups(self) -> list[VariationalRequest]:
        """Requests that build the NVF/RVF solvers of this configuration.

        A typical move, and with velocity or acceleration limits its fastest
        plan (the free-final-time NLP), so the first of either is answered warm;
        each for the cart alone and, with a bridge, for a diagonal move (the
        spatial crane's NLP); with a hoist for a move that hoists too; and a
        plan from a moving, swinging state (a new goal mid-move) and a stop; with keep-out boxes the routes
        past them.
        """
        D, duration = min(0.3, self.max_displacement), min(3.0, self.max_duration)
        hoisting = HOIST_JOINT in self.joints
        # the cart's alone as a number: the planner's limit twins (``worker_processes.toggled_limits``) are of those
        travel = [D] + ([{CART_JOINT: D, BRIDGE_JOINT: 2.0 * D / 3.0}] if BRIDGE_JOINT in self.joints else [])
        requests = []
        for displacement in travel:
            requests += [VariationalRequest('plan', method, displacement, duration, self.params, self.options)
                         for method in methods_of(Family.VARIATIONAL)]
            if self.options.max_velocity is not None or self.options.max_acceleration is not None:
                requests += [VariationalRequest('fastest', method, displacement, None, self.params, self.options)
                             for method in methods_of(Family.VARIATIONAL)]
            if hoisting:  # and a move that hoists by a tenth of the rope (another NLP)
                moving = displacement if isinstance(displacement, dict) else {CART_JOINT: displacement}
                requests += [VariationalRequest('plan', method, {**moving, HOIST_JOINT: -0.1 * self.params.L1},
                                                duration, self.params, hoisting_options(self.options))
                             for method in methods_of(Family.VARIATIONAL)]
        # a plan from a moving, swinging state and a stop (their own warm starts), over every served axis
        spatial = BRIDGE_JOINT in self.joints
        state = MotionState({CART_JOINT: AxisState(0.0, 0.1, 0.05),
                             **({BRIDGE_JOINT: AxisState(0.0, 0.05, 0.03)} if spatial else {}),
                             **({HOIST_JOINT: AxisState(self.params.L1)} if hoisting else {})},
                            Swing.of((0.02, 0.0, 0.01, 0.0, -0.05, 0.0, -0.02, 0.0) if spatial
                                     else (0.02, 0.0, -0.05, 0.0), spatial))
        start, model = problem_start(state, self.params)
        options = hoisting_options(self.options) if hoisting else self.options
        displacement = {CART_JOINT: D, **({BRIDGE_JOINT: 0.0} if spatial else {}),
                        **({HOIST_JOINT: 0.0} if hoisting else {})}
        for free_end in (False, True):  # (a stop's tries are solved within STOP_SOLVE_TIME each)
            requests += [VariationalRequest('plan', method, displacement, duration, model,
                                            stop_options(options) if free_end else options, start, free_end)
                         for method in methods_of(Family.VARIATIONAL)]
        # with keep-out boxes, NVF's NLPs of the routes past them the served axes allow (``moves.plan_keeping_out``);
        # RVF's builds on first use: warming it up too would keep a solver process busy at start-up
        # (its NLP, then its derivatives compiled) for a route few callers ask for
        routes = ([Route('over', HOIST_JOINT, -0.2 * self.params.L1, 0.3, 0.7)] if hoisting else []) + (
            [Route('around', BRIDGE_JOINT, 0.2, 0.3, 0.7)] if spatial else [])
        for route in routes if self.keep_out else ():
            moves = {CART_JOINT: D, **({BRIDGE_JOINT: 0.0} if spatial else {}),
                     **({HOIST_JOINT: 0.0} if hoisting else {})}
            requests += [VariationalRequest('plan', method, moves, duration, self.params,
                                            hoisting_options(self.options) if hoisting else self.options,
                                            route=route, keep_out=self.keep_out, origin={})
                         for method in ('nvf',)]
        return requests
