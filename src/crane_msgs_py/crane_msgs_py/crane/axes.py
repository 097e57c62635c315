"""The crane's actuated axes as data: one record per axis, one ordered registry, one limits type.

An axis is a joint the trajectory server commands: the cart travelling
along the rail, the hoist setting the upper cable's length L1. Everything
that is per axis (the joint name in trajectories and joint_states, how its
limits are named, which ``cmd_vel`` field drives it in operator mode, whether
it travels or hoists) is read from here, so that a new axis is an entry in
``AXES`` plus its physics (the planner's model and the simulator's).

Every array of actuated joints lists them in ``AXES`` order (contract
"Joints and hoisting"). Pure Python, no ROS import.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from crane_msgs_py.crane.params import ParameterError

#: What an axis moves: ``travel`` the suspension point along ``direction``, ``hoist`` the upper cable's length.
KINDS = ('travel', 'hoist')
#: Unit vectors of the crane frame (x along the rail, y across it, z up) by their names.
DIRECTIONS = {'x': (1.0, 0.0, 0.0), 'y': (0.0, 1.0, 0.0), 'z': (0.0, 0.0, 1.0)}
#: The quantities an axis's reference is limited in, and their units over the axis's position unit.
LIMIT_QUANTITIES = (('velocity', '/s'), ('acceleration', '/s^2'), ('jerk', '/s^3'))
#: The nodes' map of per-joint limits, as ros2_controllers declares its ``constraints.<joint>.``:
#: ``limits.<joint>.max_velocity``, ... (``Axis.limit_parameters``).
LIMITS_MAP = 'limits'


@dataclass(frozen=True)
class Axis:
    """One actuated axis.

    Attributes:
        name: the joint's name in trajectories, references, joint_states and Moves.
        kind: ``travel`` (its position moves the suspension point along ``direction``) or
            ``hoist`` (its position is the upper cable's length L1; larger = load lower).
        direction: for a travel axis the unit vector it moves along in the crane frame (x along the
            rail, z up), given as such or as 'x'/'y'; None for the hoist.
        unit: its position's unit (SI).
        sim_joint: the simulator's (and a URDF's) joint of it.
        cmd_vel: the ``geometry_msgs/Twist`` field of ``cmd_vel`` that drives it in operator mode.
        cmd_vel_sign: the axis's velocity per unit of that field (the hoist: + up shortens the rope).
        limit_prefix: what its limits' names carry after ``max_`` (``max_velocity`` is the cart's, the
            first axis's, since before there were others; ``max_hoist_velocity`` the hoist's): the names of the
            planning options and the CLI, and the nodes' parameters' former names (``limit_parameters``).
    """

    name: str
    kind: str
    direction: tuple[float, float, float] | str | None = None
    unit: str = 'm'
    sim_joint: str = ''
    cmd_vel: str = ''
    cmd_vel_sign: float = 1.0
    limit_prefix: str | None = None

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ParameterError(f'axis {self.name}: kind must be one of {", ".join(KINDS)}, got {self.kind!r}')
        direction = DIRECTIONS.get(self.direction, self.direction) if isinstance(self.direction, str) else \
            self.direction
        if self.kind == 'travel':
            if isinstance(direction, str) or direction is None or len(direction) != 3 \
                    or not math.isclose(math.hypot(*direction), 1.0, abs_tol=1e-9):
                raise ParameterError(f'axis {self.name}: a travel axis needs a unit direction, '
                                     f'got {self.direction!r}')
            direction = tuple(float(c) for c in direction)
        elif direction is not None:
            raise ParameterError(f'axis {self.name}: the hoist moves along the cable, not along a direction')
        object.__setattr__(self, 'direction', direction)
        object.__setattr__(self, 'sim_joint', self.sim_joint or self.name)
        object.__setattr__(self, 'limit_prefix', f'{self.name}_' if self.limit_prefix is None else self.limit_prefix)

    @property
    def limit_names(self) -> tuple[str, str, str]:
        """How its velocity, acceleration and jerk limits are named (options, parameters, messages)."""
        return tuple(f'max_{self.limit_prefix}{quantity}' for quantity, _ in LIMIT_QUANTITIES)

    def limit_parameters(self, within: str = '') -> tuple[str, str, str]:
        """Its velocity, acceleration and jerk limits' node parameters: ``<within>.limits.<joint>.max_velocity``,
        ... (``LIMITS_MAP``; ``within`` a parameter namespace, e.g. ``operator``, or none)."""
        return tuple(f'{within}{"." if within else ""}{LIMITS_MAP}.{self.name}.max_{quantity}'
                     for quantity, _ in LIMIT_QUANTITIES)

    @property
    def limit_units(self) -> tuple[str, str, str]:
        return tuple(f'{self.unit}{per}' for _, per in LIMIT_QUANTITIES)

    def limits(self, max_velocity=None, max_acceleration=None, max_jerk=None) -> 'AxisLimits':
        """Its ``AxisLimits``, checked with each value named as this axis names it."""
        return AxisLimits.named(self.limit_names, (max_velocity, max_acceleration, max_jerk))


#: The cart: travel along the rail (the paper's axis).
CART = Axis('cart', 'travel', 'x', cmd_vel='linear.x', limit_prefix='')
#: The bridge: travel along its runway, across the cart's rail (the spatial crane's second horizontal axis).
BRIDGE = Axis('bridge', 'travel', 'y', cmd_vel='linear.y')
#: The hoist: the upper cable's length L1 (m). ``cmd_vel``'s linear.z is the load's vertical velocity, + up.
HOIST = Axis('hoist', 'hoist', cmd_vel='linear.z', cmd_vel_sign=-1.0)
#: Every axis a setup may have, in their order in every array of actuated joints. The first is always there.
AXES = (CART, BRIDGE, HOIST)
AXIS_NAMES = tuple(a.name for a in AXES)
_BY_NAME = {a.name: a for a in AXES}


def axis(name: str) -> Axis:
    """The axis named ``name``; ParameterError if there is none."""
    try:
        return _BY_NAME[name]
    except KeyError:
        raise ParameterError(f'no axis {name!r}; the axes are {", ".join(AXIS_NAMES)}') from None


def check_axes(names, what: str = 'joints') -> tuple[str, ...]:
    """``names`` as a tuple if they are the first axis and any of the others, each once, in ``AXES`` order;
    else ParameterError naming ``what``."""
    names = tuple(names)
    order = [AXIS_NAMES.index(n) if n in AXIS_NAMES else -1 for n in names]
    if not names or order[0] != 0 or -1 in order or order != sorted(set(order)):
        others = ', '.join(AXIS_NAMES[1:])
        raise ParameterError(f'{what} must be [{AXIS_NAMES[0]}] followed by any of [{others}] in this order, '
                             f'got {list(names)}')
    return names


# --------------------------------------------------------------------------- limits

def _limit(name: str, value) -> float | None:
    """A limit as stored: None for none (None, 0 or inf), else a float > 0; ParameterError naming ``name``."""
    if value is None:
        return None
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f'{name} must be a number, got {value!r}') from None
    if v == 0.0 or v == math.inf:
        return None
    if not v > 0.0 or math.isnan(v):
        raise ParameterError(f'{name} must be > 0 (0 or None: no limit), got {v}')
    return v


@dataclass(frozen=True)
class AxisLimits:
    """An axis's limits on its reference: |velocity|, |acceleration|, |jerk| (SI, per its unit).

    None = no limit (0 and inf are taken as None). It unpacks as the triple (v, a, j).
    """

    max_velocity: float | None = None
    max_acceleration: float | None = None
    max_jerk: float | None = None
    #: how the three are named in messages (``Axis.limit_names``)
    names: tuple[str, str, str] = field(default=CART.limit_names, compare=False, repr=False)

    def __post_init__(self):
        for attribute, name in zip(('max_velocity', 'max_acceleration', 'max_jerk'), self.names):
            object.__setattr__(self, attribute, _limit(name, getattr(self, attribute)))

    @classmethod
    def named(cls, names, values) -> 'AxisLimits':
        """The limits ``values`` (v, a, j), checked naming each by ``names``."""
        return cls(*values, names=tuple(names))

    def __iter__(self):
        return iter((self.max_velocity, self.max_acceleration, self.max_jerk))

    @property
    def any(self) -> bool:
        """Whether any of the three is limited."""
        return any(v is not None for v in self)

    @property
    def bounds_speed(self) -> bool:
        """Whether velocity or acceleration is limited: without either a motion could be arbitrarily fast."""
        return self.max_velocity is not None or self.max_acceleration is not None

    def require(self, needed, what: str, error: type[ValueError] = ParameterError) -> None:
        """``error`` naming ``what`` and the first of ``needed`` (attribute names) that is not limited."""
        for attribute in needed:
            if getattr(self, attribute) is None:
                name = self.names[('max_velocity', 'max_acceleration', 'max_jerk').index(attribute)]
                raise error(f'{what} needs a finite {name} > 0')
