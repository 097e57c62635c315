"""The planning methods the facade serves, as a registry (contract: Methods).

Each method is one ``MethodSpec``: its family (how it is planned: an NLP of
the variational family, or a shaper's impulse train, whose design function
the entry names) and what it supports. The planner and the service ask the
entry (``method_spec(name).supports.routes``, ``spec.family is
Family.SHAPER``), never a list of names. A new method is one entry here plus
its mathematics (a shaper's design function in ``shapers``; a variational
method's cost in ``problem``). Layout after Klipper's ``shaper_defs.py``.

Kept apart from the solvers so that naming a method loads neither CasADi
nor the solvers themselves.
"""
from __future__ import annotations

import enum
from collections.abc import Callable
from dataclasses import dataclass

from crane_msgs_py.crane.errors import PlanError

from .shapers import SHAPERS, Shaper


class Family(enum.Enum):
    """How a method plans: what the planner hands its request to."""

    #: the paper's optimal control (NVF, RVF): an NLP solved on a ``variational.VariationalSolver``
    VARIATIONAL = 'variational'
    #: an input shaper cascaded over both pendulum modes, shaping a base motion (``shaped``)
    SHAPER = 'shaper'


@dataclass(frozen=True)
class Supports:
    """What a method plans beyond a rest-to-rest move of the cart (the contract's rules for it)."""

    #: a move that changes the rope length (contract: Joints and hoisting)
    hoisting: bool
    #: the bridge beside the cart (contract: The spatial crane)
    bridge: bool
    #: routes around or over keep-out boxes when the direct move would enter one (contract: Routes)
    routes: bool
    #: via points passed exactly; else a straight path must pass within ``via_tolerance`` of them
    exact_vias: bool
    #: a route past keep-out boxes that also passes via points
    routes_with_vias: bool
    #: a new goal or a stop during a motion, from the reference's state then (contract: Motion from any state)
    start_in_motion: bool
    #: ... also while the running motion changes the rope length
    retarget_while_hoisting: bool
    #: damping a swing the method did not cause (``~/settle``, a settle after a handover)
    settle: bool
    #: the shortest plan within the axis limits (``--fastest``, a move without a duration)
    fastest: bool
    #: ... with a hoist
    fastest_hoisting: bool


#: What NVF and RVF plan: any state to rest on the coupled model, under path constraints.
VARIATIONAL_SUPPORTS = Supports(hoisting=True, bridge=True, routes=True, exact_vias=True, routes_with_vias=True,
                                start_in_motion=True, retarget_while_hoisting=True, settle=True, fastest=True,
                                fastest_hoisting=True)
#: What a shaper plans: a shaped straight move (a route's axis stepping aside and back), its own motion retargeted
#: or stopped while the rope length holds.
SHAPER_SUPPORTS = Supports(hoisting=True, bridge=True, routes=True, exact_vias=False, routes_with_vias=False,
                           start_in_motion=True, retarget_while_hoisting=False, settle=False, fastest=True,
                           fastest_hoisting=False)


@dataclass(frozen=True)
class MethodSpec:
    """One planning method: its name, family, what it supports and how it is planned."""

    name: str
    family: Family
    supports: Supports
    #: a shaper's design function of one mode (omega rad/s, zeta) -> ``Shaper``; None for a variational method
    design: Callable[[float, float], Shaper] | None = None
    #: whether the plan is made insensitive to the ``robust`` parameters (RVF's sensitivity states)
    robust: bool = False


def _variational(name: str, robust: bool = False) -> MethodSpec:
    return MethodSpec(name, Family.VARIATIONAL, VARIATIONAL_SUPPORTS, robust=robust)


def _shaper(name: str) -> MethodSpec:
    return MethodSpec(name, Family.SHAPER, SHAPER_SUPPORTS, design=SHAPERS[name])


#: Every method by name, in the order the contract lists them.
REGISTRY: dict[str, MethodSpec] = {spec.name: spec for spec in (
    _variational('nvf'),
    _variational('rvf', robust=True),
    _shaper('zv'),
    _shaper('nzv'),
    _shaper('zvd'),
    _shaper('ei'),
    _shaper('mzv'),
    _shaper('zvdd'),
)}


def method_spec(name: str) -> MethodSpec:
    """The entry of method ``name``; PlanError naming the choices if there is none."""
    try:
        return REGISTRY[name]
    except (KeyError, TypeError):
        raise PlanError(f'unknown method {name!r}; choose from {", ".join(METHODS)}') from None


def find_method(name: str) -> MethodSpec | None:
    """The entry of method ``name``, None for a name that is no method."""
    return REGISTRY.get(name) if isinstance(name, str) else None


def family_of(name: str) -> Family | None:
    """The family of method ``name``, None for a name that is no method."""
    spec = find_method(name)
    return None if spec is None else spec.family


def lacks(name: str, what: str) -> bool:
    """Whether ``name`` is a method whose ``Supports`` does not say ``what`` (a field's name): False for a name
    that is no method, which the request's check refuses by its own message."""
    spec = find_method(name)
    return spec is not None and not getattr(spec.supports, what)


def methods_of(family: Family) -> tuple[str, ...]:
    """The names of ``family``'s methods, in the registry's order."""
    return tuple(name for name, spec in REGISTRY.items() if spec.family is family)


def methods_supporting(what: str) -> tuple[str, ...]:
    """The names of the methods whose ``Supports`` says ``what`` (a field's name), in the registry's order."""
    return tuple(name for name, spec in REGISTRY.items() if getattr(spec.supports, what))


#: Every method's name, and each family's, in the registry's order (names to list; ask the entry what one does).
METHODS = tuple(REGISTRY)
VARIATIONAL_METHODS = methods_of(Family.VARIATIONAL)
SHAPER_METHODS = methods_of(Family.SHAPER)

#: Parameters RVF may be made insensitive to.
ROBUST_PARAMETERS = ('L1', 'L2', 'm1', 'm2', 'tau')
