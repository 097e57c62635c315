"""Where the load is for given cable angles: what a sway sensor reports and what the planner reads from it.

The contract's geometry ("The spatial crane"): the upper cable, of length L1,
points along ``u(theta1, phi1)`` and the lower, of length L2, along
``u(theta1 + theta2, phi1 + phi2)``, with ``theta`` the angle in the x-z plane
(positive when the load lags behind a positive cart acceleration: Fig. 1 of
the paper) and ``phi`` the angle out of it, positive towards +y:

    u(a, b) = (-sin a cos b, sin b, -cos a cos b).

The simulator and the planner both read the measured swing through these
functions, so they live here rather than in either; each keeps its own
dynamics. Floats or numpy arrays. Pure Python, no ROS import.
"""
from __future__ import annotations

import numpy as np


def cable_direction(a, b) -> tuple:
    """u(a, b): the unit vector along a cable at in-plane angle ``a`` and out-of-plane angle ``b``."""
    cb = np.cos(b)
    return -np.sin(a) * cb, np.sin(b), -np.cos(a) * cb


def load_excursion(theta1, theta2, L1, L2):
    """Horizontal offset (m) of the load m2 from its rest position below the cart, on the planar crane.

    x_cart - x_m2 = L1 sin(theta1) + L2 sin(theta1 + theta2) (Fig. 1);
    positive when the load lags behind the cart.
    """
    return L1 * np.sin(theta1) + L2 * np.sin(theta1 + theta2)


def mass_offsets(theta1, theta2, phi1, phi2, L1, L2) -> tuple:
    """((dx1, dy1), (dx2, dy2)): both masses' horizontal positions relative to the suspension point, the hook m1
    at the end of the upper cable and the load m2 at the end of the lower (what a crane on a shared runway
    publishes of them)."""
    u1, u2 = cable_direction(theta1, phi1), cable_direction(theta1 + theta2, phi1 + phi2)
    hook = (L1 * u1[0], L1 * u1[1])
    return hook, (hook[0] + L2 * u2[0], hook[1] + L2 * u2[1])


def load_offset(theta1, theta2, phi1, phi2, L1, L2) -> tuple:
    """(dx, dy): the load m2's horizontal position relative to the suspension point; its norm is the spatial
    crane's swing (contract)."""
    return mass_offsets(theta1, theta2, phi1, phi2, L1, L2)[1]


def load_swing(theta1, theta2, L1, L2, phi1=None, phi2=None):
    """The load's swing (m): on the planar crane (no ``phi``) its offset along x, signed, positive when it
    lags (``load_excursion``); with ``phi1``, ``phi2`` (a crane with a bridge) the norm of its horizontal
    offset from below the suspension point (contract)."""
    if phi1 is None:
        return load_excursion(theta1, theta2, L1, L2)
    return np.hypot(*load_offset(theta1, theta2, phi1, phi2, L1, L2))
