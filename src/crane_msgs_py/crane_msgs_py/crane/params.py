"""Crane model parameters: the one validated parameter set every package shares.

Pure Python (no ROS import). Defaults are Table 1 of Boscariol & Richiedei
(2018) with g = 9.81 m/s^2 and an axis-servo time constant tau = 0.01 s
(the contract's default model). SI units throughout.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields, replace

#: Names of the model parameters, in the contract's order.
PARAMETER_NAMES = ('L1', 'L2', 'm1', 'm2', 'g', 'tau', 'c1', 'c2', 'tau_hoist')
#: Those that may be 0 (the others must be > 0).
NONNEGATIVE_PARAMETERS = ('tau', 'c1', 'c2', 'tau_hoist')

#: Human descriptions (units included), reused for CLI help and ROS parameter descriptors.
PARAMETER_DESCRIPTIONS = {
    'L1': 'upper cable length L1 (m), > 0',
    'L2': 'lower cable length L2 (m), > 0',
    'm1': 'upper mass m1 (kg), > 0',
    'm2': 'lower mass (load) m2 (kg), > 0',
    'g': 'gravitational acceleration g (m/s^2), > 0',
    'tau': 'axis servo time constant tau (s) of Eq. 6, >= 0 (0 = ideal tracking)',
    'c1': 'viscous damping c1 of the upper pendulum joint (N m s/rad), >= 0 (0 = the paper\'s model)',
    'c2': 'viscous damping c2 of the lower pendulum joint (N m s/rad), >= 0 (0 = the paper\'s model)',
    'tau_hoist': 'hoist servo time constant (s), the hoist\'s Eq. 6, >= 0 (0 = ideal tracking); used with a hoist',
}


class ParameterError(ValueError):
    """A parameter value is out of its domain; the message names the parameter."""


def parameter_range(lo, hi) -> dict:
    """A node parameter's range [lo, hi] as a pure parameter table gives it: an integer range for int bounds,
    else a double one (``node_parameters.declare`` makes rcl's descriptor of the plain pair)."""
    if isinstance(lo, int) and isinstance(hi, int):
        return {'integer_range': (lo, hi)}
    return {'floating_point_range': (float(lo), float(hi))}


def model_parameters(describe=lambda description: description, bound=lambda name: 1e4) -> dict:
    """The crane model's parameters (``CraneParams``' fields) as entries of a node's parameter table: name ->
    (default, ``describe(the field's description)``, the range [0, ``bound(name)``]). The planner, the streamer
    and the simulator declare the same model, each in its own role."""
    return {name: (getattr(CraneParams, name), describe(PARAMETER_DESCRIPTIONS[name]),
                   parameter_range(0.0, bound(name))) for name in PARAMETER_NAMES}


#: The descriptor field of a parameter table's entry naming the parameter's former name (``renamed_from``).
RENAMED_FROM = 'renamed_from'


def renamed_from(old: str) -> dict:
    """Table fields saying a parameter was called ``old`` until now: for one release a node still takes ``old``
    (from a parameters file or a set), applies it to the new name and logs a deprecation warning naming it."""
    return {RENAMED_FROM: old}


def renamed(table: dict) -> dict:
    """Former name -> name of each renamed parameter of a parameter table (``renamed_from``)."""
    return {extra[RENAMED_FROM]: name for name, (_, _, extra) in table.items() if RENAMED_FROM in extra}


def check_finite(name: str, value, error: type = None) -> float:
    """Return ``value`` as float, or raise ``error`` (default ParameterError) naming ``name``."""
    error = error or ParameterError
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise error(f'{name} must be a number, got {value!r}') from None
    if not math.isfinite(v):
        raise error(f'{name} must be finite, got {v}')
    return v


def check_positive(name: str, value) -> float:
    v = check_finite(name, value)
    if v <= 0.0:
        raise ParameterError(f'{name} must be > 0, got {v}')
    return v


def check_nonnegative(name: str, value) -> float:
    v = check_finite(name, value)
    if v < 0.0:
        raise ParameterError(f'{name} must be >= 0, got {v}')
    return v


def check_count(name: str, value, error: type[ValueError] = ParameterError) -> int:
    """Return ``value`` as an int if it is an integer >= 1, else raise ``error`` naming ``name``."""
    if int(value) != value or value < 1:
        raise error(f'{name} must be an integer >= 1, got {value}')
    return int(value)


def check_choice(name: str, value, choices, error: type[ValueError] = ParameterError):
    """Return ``value`` if it is one of ``choices``, else raise ``error`` naming ``name`` and the choices."""
    if value not in choices:
        raise error(f'{name} must be one of {", ".join(choices)}, got {value!r}')
    return value


def check_parameter(name: str, value) -> float:
    """``value`` of model parameter ``name`` as float, checked against its domain (ParameterError)."""
    return (check_nonnegative if name in NONNEGATIVE_PARAMETERS else check_positive)(name, value)


@dataclass(frozen=True)
class CraneParams:
    """Double-pendulum crane (paper Fig. 1, Table 1) plus the axis servo of Eq. 6.

    Attributes:
        L1: upper cable length (m).
        L2: lower cable length (m).
        m1: upper mass (kg).
        m2: lower mass, the load (kg).
        g: gravitational acceleration (m/s^2).
        tau: first-order servo time constant (s); 0 means the cart follows
            the reference exactly.
        c1, c2: viscous damping (N m s/rad) of the upper joint (torque
            -c1 theta1' between cart and upper cable) and of the lower joint
            (torque -c2 theta2' between the cables); 0 is the paper's
            undamped model. The swing depends on them through c1/(m1+m2)
            and c2/m2.
        tau_hoist: the hoist axis's first-order servo time constant (s),
            Eq. 6 for the rope length; only used when hoisting (then L1 is
            the rope length at the start).
    """

    L1: float = 0.470
    L2: float = 0.391
    m1: float = 0.192
    m2: float = 0.201
    g: float = 9.81
    tau: float = 0.01
    c1: float = 0.0
    c2: float = 0.0
    tau_hoist: float = 0.01

    def __post_init__(self):
        for f in fields(self):
            # frozen dataclass: normalise to float through object.__setattr__
            object.__setattr__(self, f.name, check_parameter(f.name, getattr(self, f.name)))

    def replace(self, **changes) -> 'CraneParams':
        """A copy with ``changes`` applied (validated); unknown names are an error."""
        unknown = set(changes) - set(PARAMETER_NAMES)
        if unknown:
            raise ParameterError(f'unknown model parameter(s): {", ".join(sorted(unknown))}')
        return replace(self, **changes)

    def as_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def of(cls, values) -> 'CraneParams':
        """The model a node's parameters (or any mapping holding every ``PARAMETER_NAMES``) give."""
        return cls(**{name: values[name] for name in PARAMETER_NAMES})
