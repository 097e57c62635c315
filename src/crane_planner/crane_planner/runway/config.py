"""The runway parameters a crane's planner and streamer both declare (``PARAMETERS``: the same values on both),
and ``RunwayConfig``, the values checked together (contract "Cranes sharing a runway").

Pure Python, no ROS import: each node merges the table into its own and turns its ranges into rcl descriptors.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from crane_msgs_py.crane.params import ParameterError, check_choice, parameter_range

from .occupancy import Shape

POLICIES = ('wait', 'refuse')
#: Topics (global: every crane's nodes on one runway share them, whatever their namespace).
OCCUPANCY_TOPIC = '/runway/occupancy'
STATE_TOPIC = '/runway/state'

#: name -> (default, description, descriptor fields; a range as (lo, hi)).
PARAMETERS = {
    'runway': (False, 'share a runway with other cranes: publish this crane\'s occupancy and state, plan around the '
                      'others\' and guard against them (the same value on the planner and the streamer); fixed at '
                      'start-up', {'read_only': True}),
    'crane_name': ('', 'this crane\'s name on the runway; empty: the namespace without its slashes; fixed at '
                       'start-up', {'read_only': True}),
    'runway_offset': ([0.0, 0.0], 'where this crane\'s crane_base origin lies in the frame runway [x, y] (m; x along '
                                  'the trolleys\' rails, y along the runway, which the bridges travel); fixed at '
                                  'start-up', {'additional_constraints': 'two finite numbers', 'read_only': True}),
    'runway_min_distance': (0.2, 'the least distance (m) kept between any two cranes\' girders, trolleys and loads, '
                                 '> 0', parameter_range(0.0, 100.0)),
    'runway_policy': ('wait', 'a goal that would come within runway_min_distance of another crane: wait (started '
                              'later by the least that keeps them apart) or refuse (naming the crane)',
                      {'additional_constraints': f'one of {", ".join(POLICIES)}'}),
    'runway_timeout': (0.5, 'another crane\'s state silent this long (s) while within reach stops this crane, > 0',
                       parameter_range(0.0, 60.0)),
    'girder_half_width': (0.05, 'half the girder\'s width (m) along the runway, >= 0', parameter_range(0.0, 10.0)),
    'load_half_size': (0.05, 'half the load\'s size (m) about each mass, >= 0', parameter_range(0.0, 10.0)),
}


@dataclass(frozen=True)
class RunwayConfig:
    """The runway parameters, checked (see ``PARAMETERS``)."""

    on: bool = False
    crane: str = ''
    offset: tuple = (0.0, 0.0)
    min_distance: float = 0.2
    policy: str = 'wait'
    timeout: float = 0.5
    shape: Shape = Shape()

    @classmethod
    def from_values(cls, values: dict, namespace: str = '') -> 'RunwayConfig':
        """From the parameters' values by name (defaults for any missing); ``namespace`` names the crane when
        ``crane_name`` is empty. Raises ParameterError naming the parameter."""
        v = {name: values.get(name, default) for name, (default, _, _) in PARAMETERS.items()}
        crane = str(v['crane_name']) or namespace.strip('/').replace('/', '_')
        offset = tuple(float(x) for x in v['runway_offset'])
        if len(offset) != 2 or not all(math.isfinite(x) for x in offset):
            raise ParameterError(f'runway_offset must be two finite numbers [x, y] (m), got {list(offset)}')
        if not (math.isfinite(v['runway_min_distance']) and v['runway_min_distance'] > 0.0):
            raise ParameterError(f'runway_min_distance must be > 0 (m), got {v["runway_min_distance"]}')
        if not (math.isfinite(v['runway_timeout']) and v['runway_timeout'] > 0.0):
            raise ParameterError(f'runway_timeout must be > 0 (s), got {v["runway_timeout"]}')
        check_choice('runway_policy', v['runway_policy'], POLICIES)
        if v['runway'] and not crane:
            raise ParameterError('crane_name is empty and the nodes run in no namespace: name this crane')
        try:
            shape = Shape(float(v['girder_half_width']), float(v['load_half_size']))
        except ValueError as e:
            raise ParameterError(str(e)) from None
        return cls(bool(v['runway']), crane, offset, float(v['runway_min_distance']), str(v['runway_policy']),
                   float(v['runway_timeout']), shape)
