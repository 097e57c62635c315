"""Where a crane is and will be on a shared runway, and how far apart two cranes are (contract "Cranes sharing a
runway").

The common frame ``runway``: x along the trolleys' rails, y along the runway
(the bridges travel in y); a crane's ``crane_base`` origin lies at its
``runway_offset`` (x, y). Seen from above, a crane occupies

- its girder: the strip ``|y - girder| <= girder_half_width`` across the whole
  runway (a bridge spans it), and
- its load: both masses (the hook m1 and the load m2, swing included), each a
  disc of ``load_half_size`` (the load's half-size) about its position.

The distance between two cranes (``separation``) is the least distance
between those sets: girder to girder, each girder to the other's masses, and
mass to mass. Everything a crane hangs from its girder lies between its masses
and its girder, so the projection from above is what two cranes on one runway
can touch through; heights are not counted (a conservative choice: a load
passes under no other girder).

An ``Occupancy`` is that footprint over time: sampled at ``t`` (s from
``start_ns``), held at its first sample before and at its last after (a crane
stands where its plan ends until it publishes another). Pure numpy, no ROS
import.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: The frame every occupancy and state is given in.
RUNWAY_FRAME = 'runway'
#: Time step (s) at which a plan's occupancy is sampled: the masses of a crane within the default limits move
#: under 6 mm from one sample to the next (0.3 m/s), which ``Occupancy.largest_step`` reports.
OCCUPANCY_STEP = 0.02


@dataclass(frozen=True)
class Shape:
    """The parts of a crane that are not its plan: its girder's half-width (m, along y) and the load's
    half-size (m, about each mass)."""

    girder_half_width: float = 0.05
    load_half_size: float = 0.05

    def __post_init__(self):
        for name, value in vars(self).items():
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f'{name} must be a finite distance >= 0 (m), got {value}')


@dataclass(frozen=True)
class Footprint:
    """What a crane occupies seen from above at one or more instants: its girder's y (m, shape (k,)) and both
    masses' (x, y) (m, shape (k, 2, 2): [instant, mass m1/m2, x/y]), in ``runway``."""

    girder: np.ndarray
    masses: np.ndarray

    @classmethod
    def at_rest(cls, girder: float, x: float) -> 'Footprint':
        """A crane at rest: both masses hanging below the trolley at ``x`` on its girder at ``girder``."""
        return cls(np.array([girder]), np.array([[[x, girder], [x, girder]]]))


@dataclass(frozen=True)
class Occupancy:
    """A crane's footprint over time (see the module docstring).

    Args:
        crane: its name (``crane_name``).
        published_ns: when it was first published: first published, first served (ties by name).
        start_ns: the time (ns, ROS time) of the first sample.
        t: sample times (s from ``start_ns``), increasing, the first 0.
        footprint: at each sample.
        shape: the crane's girder and load.
    """

    crane: str
    published_ns: int
    start_ns: int
    t: np.ndarray
    footprint: Footprint
    shape: Shape

    def __post_init__(self):
        t = np.asarray(self.t, dtype=float)
        n = len(t)
        if n == 0 or t[0] != 0.0 or np.any(np.diff(t) <= 0.0):
            raise ValueError(f'occupancy of {self.crane!r}: times must start at 0 and increase')
        if self.footprint.girder.shape != (n,) or self.footprint.masses.shape != (n, 2, 2):
            raise ValueError(f'occupancy of {self.crane!r}: {n} times but footprints of another length')
        if not (np.all(np.isfinite(self.footprint.girder)) and np.all(np.isfinite(self.footprint.masses))):
            raise ValueError(f'occupancy of {self.crane!r}: a position is not finite')

    @property
    def end_ns(self) -> int:
        """When the last sample is reached: the crane stands there from then on."""
        return self.start_ns + round(float(self.t[-1]) * 1e9)

    def at(self, stamps_ns) -> Footprint:
        """The footprint at ROS times ``stamps_ns`` (ns, an array), linear between samples, held outside them."""
        s = (np.asarray(stamps_ns, dtype=np.int64) - self.start_ns) * 1e-9
        f = self.footprint
        girder = np.interp(s, self.t, f.girder)
        masses = np.stack([np.stack([np.interp(s, self.t, f.masses[:, m, c]) for c in range(2)], axis=-1)
                           for m in range(2)], axis=1)
        return Footprint(girder, masses)

    def delayed(self, delay: float) -> 'Occupancy':
        """The same occupancy ``delay`` s later (standing at its first sample meanwhile)."""
        return Occupancy(self.crane, self.published_ns, self.start_ns + round(delay * 1e9), self.t, self.footprint,
                         self.shape)

    def since(self, stamp_ns: int) -> 'Occupancy':
        """The same from its last sample at or before ``stamp_ns`` on (what is past dropped; all of it if
        ``stamp_ns`` is before its start)."""
        k = int(np.searchsorted(self.t, (stamp_ns - self.start_ns) * 1e-9, side='right')) - 1
        if k <= 0:
            return self
        f = self.footprint
        return Occupancy(self.crane, self.published_ns, self.start_ns + round(float(self.t[k]) * 1e9),
                         self.t[k:] - self.t[k], Footprint(f.girder[k:], f.masses[k:]), self.shape)

    def spliced(self, later: 'Occupancy') -> 'Occupancy':
        """This occupancy until ``later`` starts, then ``later`` (its crane, stamp and shape): a motion sent
        from a state of the one this occupancy predicts, which the crane follows until its handover."""
        cut = (later.start_ns - self.start_ns) * 1e-9
        keep = self.t < cut - 1e-9
        if not keep.any():
            return later
        t = np.concatenate((self.t[keep], cut + later.t))
        f, g = self.footprint, later.footprint
        return Occupancy(later.crane, later.published_ns, self.start_ns, t,
                         Footprint(np.concatenate((f.girder[keep], g.girder)),
                                   np.concatenate((f.masses[keep], g.masses))), later.shape)

    def largest_step(self) -> float:
        """The largest distance (m) the girder or a mass moves from one sample to the next."""
        f = self.footprint
        if len(self.t) < 2:
            return 0.0
        return float(max(np.abs(np.diff(f.girder)).max(), np.linalg.norm(np.diff(f.masses, axis=0), axis=-1).max()))

    def largest_bend(self) -> float:
        """The largest second difference (m) of the girder's or a mass's samples: a path of bounded
        acceleration lies within an eighth of it of the straight lines between its samples."""
        f = self.footprint
        if len(self.t) < 3:
            return 0.0
        return float(max(np.abs(np.diff(f.girder, 2)).max(), np.linalg.norm(np.diff(f.masses, 2, axis=0),
                                                                              axis=-1).max()))


def holding(crane: str, published_ns: int, footprint: Footprint, shape: Shape) -> Occupancy:
    """A crane standing still from ``published_ns`` on (one sample, held)."""
    return Occupancy(crane, published_ns, published_ns, np.zeros(1), footprint, shape)


def separation(a: Footprint, a_shape: Shape, b: Footprint, b_shape: Shape) -> np.ndarray:
    """The least distance (m) between two cranes' footprints at the same instants (shape (k,)): girder to
    girder, each girder to the other's masses, mass to mass, each less the half-widths and half-sizes; negative
    when they overlap."""
    ga, gb = a_shape.girder_half_width, b_shape.girder_half_width
    ha, hb = a_shape.load_half_size, b_shape.load_half_size
    girders = np.abs(a.girder - b.girder) - ga - gb
    a_to_b = np.abs(a.girder[:, None] - b.masses[:, :, 1]).min(axis=1) - ga - hb
    b_to_a = np.abs(b.girder[:, None] - a.masses[:, :, 1]).min(axis=1) - gb - ha
    pairs = np.linalg.norm(a.masses[:, :, None, :] - b.masses[:, None, :, :], axis=-1).min(axis=(1, 2)) - ha - hb
    return np.minimum(np.minimum(girders, pairs), np.minimum(a_to_b, b_to_a))


@dataclass(frozen=True)
class Closest:
    """Where two occupancies come closest over a time span: the distance (m), the other crane and the ROS time
    (ns) of that instant."""

    distance: float
    crane: str
    stamp_ns: int


def closest(mine: Occupancy, other: Occupancy, until_ns: int | None = None) -> Closest:
    """Where ``mine`` comes closest to ``other`` from ``mine``'s start to ``until_ns`` (default: the later of
    both ends), on ``mine``'s samples and ``other``'s (both held outside their spans)."""
    end = max(mine.end_ns, other.end_ns) if until_ns is None else until_ns
    stamps = np.concatenate((mine.start_ns + np.round(mine.t * 1e9).astype(np.int64),
                             other.start_ns + np.round(other.t * 1e9).astype(np.int64), [end]))
    stamps = np.unique(stamps[(stamps >= mine.start_ns) & (stamps <= end)])
    d = separation(mine.at(stamps), mine.shape, other.at(stamps), other.shape)
    k = int(np.argmin(d))
    return Closest(float(d[k]), other.crane, int(stamps[k]))
