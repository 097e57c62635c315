"""The crane's signals by name: the load's swing as one record.

The planning model (``dynamics.crane_ode``) carries the swing as states in a
fixed order: the planar crane's ``SWING_STATES``, with a bridge the spatial
crane's ``SPATIAL_SWING_STATES``. Everything else (a measurement from
``joint_states``, a ``continuation.MotionState``, the handover's prediction)
passes a ``Swing``, whose angles are named; ``Swing.of`` and ``Swing.values``
are the one place that converts to and from the model's order.

Pure Python, no ROS import, no CasADi: the serving machinery and the nodes'
translations import it cheaply.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields

from crane_msgs_py.crane.errors import PlanError

#: The swing's angles: both cables' in the x-z plane, and on the spatial crane out of it; a rate is 'd' + angle.
PLANAR_ANGLES = ('theta1', 'theta2')
SPATIAL_ANGLES = ('theta1', 'theta2', 'phi1', 'phi2')
#: The planar crane's swing states in the model's order: the angles, then their rates.
SWING_STATES = (*PLANAR_ANGLES, *(f'd{n}' for n in PLANAR_ANGLES))
#: The spatial crane's swing (contract "The spatial crane"): in-plane and out-of-plane angles, then their rates.
SPATIAL_SWING_STATES = (*SPATIAL_ANGLES, *(f'd{n}' for n in SPATIAL_ANGLES))
_OUT_OF_PLANE = ('phi1', 'phi2', 'dphi1', 'dphi2')


def swing_names(spatial: bool) -> tuple:
    """The swing's states in the model's order: the planar crane's, with a bridge (``spatial``) the spatial one's."""
    return SPATIAL_SWING_STATES if spatial else SWING_STATES


def swing_rates(spatial: bool) -> tuple:
    """The rates among ``swing_names(spatial)``, in their order: each angle's derivative."""
    return tuple(f'd{n}' for n in (SPATIAL_ANGLES if spatial else PLANAR_ANGLES))


def check_swing(swing, spatial: bool, what: str) -> 'Swing':
    """``swing`` (None: the load hanging still) if it is the ``spatial`` crane's ``Swing`` or the planar one's;
    else PlanError saying that ``what`` needs it."""
    swing = Swing.rest(spatial) if swing is None else swing
    if not isinstance(swing, Swing) or swing.spatial != spatial:
        raise PlanError(f'{what} needs the {"spatial" if spatial else "planar"} swing '
                        f'({", ".join(swing_names(spatial))}), got {swing!r}')
    return swing


@dataclass(frozen=True)
class Swing:
    """The load's swing at one instant (rad, rad/s).

    Attributes:
        theta1, theta2: the upper cable's angle from the vertical and the lower cable's relative to it, in the
            x-z plane (the cart's direction; Eqs. 18-19).
        dtheta1, dtheta2: their rates.
        phi1, phi2, dphi1, dphi2: out of that plane (towards +y, the bridge's direction) and their rates, on
            the spatial crane (a crane with a bridge); None on the planar crane, where they do not exist.
    """

    theta1: float = 0.0
    theta2: float = 0.0
    dtheta1: float = 0.0
    dtheta2: float = 0.0
    phi1: float | None = None
    phi2: float | None = None
    dphi1: float | None = None
    dphi2: float | None = None

    def __post_init__(self):
        given = [getattr(self, n) is not None for n in _OUT_OF_PLANE]
        if any(given) and not all(given):
            raise PlanError('a spatial swing needs all of phi1, phi2, dphi1, dphi2; a planar one none of them')
        for f in fields(self):
            value = getattr(self, f.name)
            if value is not None:
                value = float(value)
                if not math.isfinite(value):
                    raise PlanError('a swing must be finite')
                object.__setattr__(self, f.name, value)

    @classmethod
    def rest(cls, spatial: bool = False) -> 'Swing':
        """The load hanging still, on the spatial crane (``spatial``) or the planar one."""
        return cls(**dict.fromkeys(_OUT_OF_PLANE, 0.0)) if spatial else cls()

    @classmethod
    def of(cls, values, spatial: bool) -> 'Swing':
        """From the model's states: a mapping by name, or values in its order (``swing_names(spatial)``)."""
        names = swing_names(spatial)
        if not hasattr(values, 'keys'):
            values = tuple(values)
            if len(values) != len(names):
                raise PlanError(f'the swing of the {"spatial" if spatial else "planar"} crane is '
                                f'({", ".join(names)}), got {len(values)} values')
            values = dict(zip(names, values))
        return cls(**{n: values[n] for n in names})

    @property
    def spatial(self) -> bool:
        """Whether this is the spatial crane's swing (out of the x-z plane too)."""
        return self.phi1 is not None

    @property
    def names(self) -> tuple:
        """Its states in the model's order (``swing_names``)."""
        return swing_names(self.spatial)

    def values(self) -> tuple:
        """Its values in the model's order (``names``)."""
        return tuple(getattr(self, n) for n in self.names)

    def states(self) -> dict:
        """Its values by the model's state names."""
        return {n: getattr(self, n) for n in self.names}

    @property
    def phi(self) -> tuple[float, float] | None:
        """(phi1, phi2) on the spatial crane, else None."""
        return (self.phi1, self.phi2) if self.spatial else None

    def angles(self) -> tuple[float, float, float, float]:
        """(theta1, theta2, phi1, phi2): the planar swing is the spatial one with phi = 0."""
        return self.theta1, self.theta2, self.phi1 or 0.0, self.phi2 or 0.0

    def rates(self) -> tuple[float, float, float, float]:
        """(dtheta1, dtheta2, dphi1, dphi2), as ``angles``."""
        return self.dtheta1, self.dtheta2, self.dphi1 or 0.0, self.dphi2 or 0.0

    @property
    def still(self) -> bool:
        """Whether every angle and rate is 0 (to 1e-9)."""
        return max(abs(x) for x in self.values()) < 1e-9
