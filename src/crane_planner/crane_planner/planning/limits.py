"""Axis limits of the reference: what no rest-to-rest motion can beat. Pure Python.

A motion of |D| in T needs a peak velocity above |D|/T, a peak acceleration
above 4|D|/T^2 (bang-bang) and a peak jerk above 32|D|/T^3 (bang-bang jerk):
the refusal of an infeasible request (``axis_limit_error``) and the lower end
of every fastest-plan search (``shortest_duration_bound``) are these bounds.
"""
from __future__ import annotations

import math
from collections.abc import Mapping

from crane_msgs_py.crane.axes import AxisLimits

from .plan import PlanError


def check_fastest_request(displacement: float, limits: AxisLimits) -> float:
    """``displacement`` as float if a fastest plan of it within ``limits`` is a question at all, else
    PlanError: without a velocity or acceleration limit a motion could be arbitrarily fast, and a motion of
    0 m takes no time."""
    if not limits.bounds_speed:
        raise PlanError(f'the fastest plan needs {limits.names[0]} or {limits.names[1]} (or both)')
    displacement = float(displacement)
    if displacement == 0.0:
        raise PlanError('the fastest plan needs a nonzero displacement')
    return displacement


def lead_axis(displacements: Mapping[str, float]) -> str:
    """The axis of a straight move that travels farthest (the first of them on a tie): the one the move's
    path is planned along, the others following it in proportion (``path_limits``)."""
    return max(displacements, key=lambda name: abs(float(displacements[name])))


def path_limits(displacements: Mapping[str, float], limits: Mapping[str, AxisLimits]) -> AxisLimits:
    """The lead axis's (``lead_axis``) limits that keep every axis of a straight move within its own.

    On a straight move axis i's position is D_i / D_lead times the lead's at every instant, so its
    velocity, acceleration and jerk are too: the lead's k-th limit is min_i limit_i,k |D_lead| / |D_i| over
    the moving axes (the lead's own exactly as given, so a move of one axis keeps its limits bit for bit).
    Named as the lead's. Axes absent from ``limits`` or standing still limit nothing.
    """
    lead = lead_axis(displacements)
    reach = abs(float(displacements[lead]))
    bound = [None, None, None]
    for name, D in displacements.items():
        if name not in limits or (float(D) == 0.0 and name != lead):  # (nothing moving: the lead's own)
            continue
        share = 1.0 if name == lead else reach / abs(float(D))
        for k, limit in enumerate(limits[name]):
            if limit is not None and (bound[k] is None or limit * share < bound[k]):
                bound[k] = limit * share
    names = limits[lead].names if lead in limits else AxisLimits().names
    return AxisLimits.named(names, bound)


def shortest_duration_bound(displacement: float, limits) -> float:
    """A lower bound (s) on any rest-to-rest motion of ``displacement`` within ``limits`` (``AxisLimits``).

    |D| / v_max (velocity), 2 sqrt(|D| / a_max) (bang-bang acceleration),
    (32 |D| / j_max)^(1/3) (bang-bang jerk) and, with both velocity and
    acceleration limits where the velocity limit is reached, |D|/v_max + v_max/a_max.
    """
    D = abs(float(displacement))
    v, a, j = limits
    bounds = [0.0]
    if v is not None:
        bounds.append(D / v)
    if a is not None:
        bounds.append(2.0 * math.sqrt(D / a))
    if j is not None:
        bounds.append((32.0 * D / j) ** (1.0 / 3.0))
    if v is not None and a is not None and v ** 2 < D * a:
        bounds.append(D / v + v / a)
    return max(bounds)


def axis_limit_error(displacement: float, duration: float, limits: AxisLimits):
    """A PlanError if no rest-to-rest motion of D in T can respect ``limits``, else None.

    The message names each limit as its axis does (``AxisLimits.names``: ``max_velocity``, ``max_hoist_velocity``...).

    Necessary conditions (exact bounds of the bang-bang motion; a smooth
    reference needs strictly more): peak velocity > |D|/T, peak acceleration
    > 4|D|/T^2, peak jerk > 32|D|/T^3 and, with both velocity and acceleration
    limits, T > |D|/v_max + v_max/a_max when the velocity limit is reached.
    """
    D, T = abs(displacement), duration
    max_velocity, max_acceleration, max_jerk = limits
    v_name, a_name, j_name = limits.names
    D_ = D * (1 + 1e-12)  # 0.1 m/s * 3 s is 0.30000000000000004 m
    if max_velocity is not None and max_velocity * T <= D_:
        return PlanError(f'infeasible: {v_name} {max_velocity:g} m/s is too low to move {D:g} m in '
                         f'{T:g} s (needs more than {D / T:g} m/s)')
    if max_acceleration is not None and max_acceleration * T ** 2 <= 4 * D_:
        return PlanError(f'infeasible: {a_name} {max_acceleration:g} m/s^2 is too low to move {D:g} m '
                         f'in {T:g} s (needs more than {4 * D / T ** 2:g} m/s^2)')
    if max_jerk is not None and max_jerk * T ** 3 <= 32 * D_:
        return PlanError(f'infeasible: {j_name} {max_jerk:g} m/s^3 is too low to move {D:g} m in {T:g} s '
                         f'(needs more than {32 * D / T ** 3:g} m/s^3)')
    if max_velocity is not None and max_acceleration is not None and max_velocity ** 2 < D * max_acceleration:
        t_min = D / max_velocity + max_velocity / max_acceleration
        if T <= t_min:
            return PlanError(f'infeasible: {v_name} {max_velocity:g} m/s and {a_name} '
                             f'{max_acceleration:g} m/s^2 together need more than {t_min:g} s to move {D:g} m')
    return None
