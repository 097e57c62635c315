"""Base motion profiles that input shapers filter (paper §4), as piecewise polynomials.

The paper shapes "a fifth-order polynomial trajectory, chosen so that initial
and final acceleration of the cart can be set to zero": the rest-to-rest
quintic, which is also the minimum-jerk point-to-point motion. Beside it, a
jerk-limited time-optimal profile under axis limits (``limited``, computed by
ruckig): the fastest rest-to-rest motion whose velocity, acceleration and jerk
stay within the limits, optionally stretched to a given duration.

A ``BaseProfile`` is a list of pieces, each a polynomial of degree <= 5 in the
time since the piece's start, so shaping it (``shaped``) stays exact.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.polynomial import polynomial as poly

from .plan import PlanError

#: P(s) = 10 s^3 - 15 s^4 + 6 s^5: from P = P' = P'' = 0 at s = 0 to P = 1, P' = P'' = 0 at s = 1.
#: Ascending coefficients of P and of its derivatives, indexed by order.
QUINTIC = tuple(poly.polyder([0.0, 0.0, 0.0, 10.0, -15.0, 6.0], k) for k in range(6))
#: Peaks of P', P'', P''' over [0, 1]: the quintic's |v|, |a|, |j| peaks are these times D/T^k.
QUINTIC_PEAKS = (15.0 / 8.0, 10.0 / math.sqrt(3.0), 60.0)
#: Taylor coefficients kept per piece (degree 5).
ORDER = 5
_BINOMIAL = np.array([[math.comb(n, m) for n in range(ORDER + 1)] for m in range(ORDER + 1)], dtype=float)
# Taylor shift of a degree-5 polynomial by dx: c'_m = sum_n C(n, m) dx^(n - m) c_n, as one product
_SHIFT_POWER = np.clip(np.arange(ORDER + 1)[None, :] - np.arange(ORDER + 1)[:, None], 0, None)  # [m, n] -> n - m
_SHIFT_MASK = np.triu(_BINOMIAL)
BASES = ('quintic', 'limits')


def quintic(t, displacement: float, duration: float):
    """Rest-to-rest quintic D P(t / T) (paper §4): position, velocity, acceleration, jerk.

    Exact at times ``t`` (any shape). Outside [0, T] the profile is at rest
    at 0 (before) or D (after). Jerk jumps at both ends; it is taken
    right-continuous, i.e. nonzero on [0, T) only, so the instant the motion
    ends is already at rest.
    """
    t = np.asarray(t, dtype=float)
    D, T = float(displacement), float(duration)
    # at the clipped ends P', P'' vanish exactly (integer coefficients), so v, a are at rest too
    s = np.clip(t / T, 0.0, 1.0)
    p, v, a, j = (D / T**k * poly.polyval(s, QUINTIC[k]) for k in range(4))
    return p, v, a, np.where((t >= 0.0) & (t < T), j, 0.0)


@dataclass(frozen=True)
class BaseProfile:
    """A rest-to-rest motion from 0 to ``displacement`` (m) over [0, ``duration``] (s), piecewise polynomial.

    Attributes:
        kind: ``quintic`` or ``limits``.
        breaks: start times (s) of the pieces, increasing, the first 0.
        coefficients: (pieces, 6) position coefficients of each piece in
            powers of the time since its start.
    """

    kind: str
    displacement: float
    duration: float
    breaks: np.ndarray = field(repr=False)
    coefficients: np.ndarray = field(repr=False)

    def piece(self, x) -> np.ndarray:
        """Index of the piece holding local time ``x`` (right-continuous)."""
        if self.breaks.size == 1:  # the quintic: the fastest search asks a dozen times per plan
            return np.zeros(np.shape(x), dtype=np.intp)
        return np.maximum(np.searchsorted(self.breaks, x, side='right') - 1, 0)

    def taylor(self, x, piece=None) -> np.ndarray:
        """Position Taylor coefficients (powers of dt, dt^k / k! folded in) about local times ``x``, (n, 6).

        ``piece`` picks the polynomial (default: the one holding x), so a time
        rounded onto a piece's edge can still be expanded on the piece it starts.
        """
        x = np.atleast_1d(np.asarray(x, dtype=float))
        k = self.piece(x) if piece is None else np.asarray(piece)
        dx = x - self.breaks[k]
        # shift each piece polynomial to x: c'_m = sum_n C(n, m) dx^(n - m) c_n; the powers
        # dx^0..dx^5 by products and gathered (a float power per matrix entry costs many times more)
        shift = _SHIFT_MASK * np.vander(dx, ORDER + 1, increasing=True)[:, _SHIFT_POWER]
        return np.einsum('imn,in->im', shift, self.coefficients[k])

    def peaks(self) -> tuple[float, float]:
        """(peak |acceleration|, peak |jerk|) over [0, duration], sampled on each piece (polynomials of degree
        <= 5: to ~1e-4 relative)."""
        edges = np.append(self.breaks, self.duration)
        t = np.concatenate([np.linspace(a, b, 97) for a, b in zip(edges[:-1], edges[1:], strict=True) if b > a])
        c = self.taylor(t)
        return float(np.abs(2.0 * c[:, 2]).max()), float(np.abs(6.0 * c[:, 3]).max())

    def along(self, displacement: float) -> 'BaseProfile':
        """The same motion in time, scaled to reach ``displacement`` (m): another axis's share of a straight move.

        Every axis of a straight move follows one path parameter (this profile over its own displacement),
        so the axes' positions keep the ratio of their displacements at every instant.
        """
        displacement = float(displacement)
        scale = 0.0 if displacement == 0.0 else displacement / self.displacement
        return BaseProfile(self.kind, displacement, self.duration, self.breaks, self.coefficients * scale)

    def stretched(self, duration: float) -> 'BaseProfile':
        """The same motion slowed down in time to last ``duration`` (s) (>= this one's): peaks fall as 1/s^k."""
        scale = float(duration) / self.duration
        if scale < 1.0 - 1e-12:
            raise PlanError(f'a {self.kind} base of {self.displacement:g} m cannot be shorter than '
                            f'{self.duration:.4f} s; {duration:.4f} s asked')
        return BaseProfile(self.kind, self.displacement, float(duration), self.breaks * scale,
                           self.coefficients / scale ** np.arange(ORDER + 1))


def quintic_base(displacement: float, duration: float) -> BaseProfile:
    """The paper's base: the rest-to-rest quintic D P(t/T) as one piece."""
    D, T = float(displacement), float(duration)
    coefficients = (D * QUINTIC[0] / T ** np.arange(ORDER + 1))[None, :]
    return BaseProfile('quintic', D, T, np.zeros(1), coefficients)


def quintic_duration(displacement: float, max_velocity=None, max_acceleration=None, max_jerk=None) -> float:
    """Shortest quintic base that keeps |v|, |a|, |j| within the limits given (0 without limits)."""
    D = abs(float(displacement))
    need = [0.0]
    for k, limit in enumerate((max_velocity, max_acceleration, max_jerk)):
        if limit is not None:
            need.append((QUINTIC_PEAKS[k] * D / limit) ** (1.0 / (k + 1)))
    return max(need)


def ruckig_pieces(trajectory) -> tuple[np.ndarray, np.ndarray]:
    """(start times s, position coefficients (pieces, 6)) of a one-axis ruckig ``Trajectory``: its
    constant-jerk phases as cubic pieces in powers of the time since each starts (empty phases dropped)."""
    profile = trajectory.profiles[0][0]
    t = np.asarray(profile.t, dtype=float)
    starts = np.concatenate(([0.0], np.cumsum(t)[:-1]))
    keep = t > 0.0
    coefficients = np.zeros((int(keep.sum()), ORDER + 1))
    p, v, a, j = (np.asarray(x, dtype=float)[:7][keep] for x in (profile.p, profile.v, profile.a, profile.j))
    coefficients[:, 0], coefficients[:, 1], coefficients[:, 2], coefficients[:, 3] = p, v, a / 2.0, j / 6.0
    return starts[keep], coefficients


def limited_base(displacement: float, max_velocity=None, max_acceleration=None, max_jerk=None,
                 duration: float | None = None) -> BaseProfile:
    """The jerk-limited time-optimal rest-to-rest profile under the limits (ruckig), optionally slowed to ``duration``.

    Without ``duration`` it is the fastest motion whose |v|, |a|, |j| stay
    within the limits; with it, that motion slowed down in time
    (``BaseProfile.stretched``), so it stays within them. PlanError if no
    velocity or acceleration limit is given (the fastest motion would be
    instantaneous) or if ``duration`` is shorter than the fastest.
    """
    from ruckig import InputParameter, Result, Ruckig, Trajectory
    if max_velocity is None and max_acceleration is None:
        raise PlanError('the limits base needs max_velocity or max_acceleration (or both)')
    D = float(displacement)
    if D == 0.0:
        return BaseProfile('limits', 0.0, float(duration or 0.0), np.zeros(1), np.zeros((1, ORDER + 1)))
    inp = InputParameter(1)
    inp.current_position, inp.target_position = [0.0], [D]
    # ruckig needs finite velocity and acceleration limits: an absent one is far beyond reach
    inp.max_velocity = [max_velocity if max_velocity is not None else 1e9]
    inp.max_acceleration = [max_acceleration if max_acceleration is not None else 1e9]
    inp.max_jerk = [max_jerk if max_jerk is not None else math.inf]
    trajectory = Trajectory(1)
    try:
        result = Ruckig(1).calculate(inp, trajectory)
    except ValueError as exc:  # a result code the binding does not know
        raise PlanError(f'no jerk-limited profile for D={D:g} m under the limits (ruckig: {exc})') from None
    if result not in (Result.Working, Result.Finished):
        raise PlanError(f'no jerk-limited profile for D={D:g} m under the limits (ruckig: {result.name})')
    starts, coefficients = ruckig_pieces(trajectory)
    fastest = BaseProfile('limits', D, float(trajectory.duration), starts, coefficients)
    return fastest if duration is None else fastest.stretched(duration)
