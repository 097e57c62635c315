"""What the streamer's loop streams: a source's setpoint each tick, then an ordered chain of corrections.

A *source* is whatever gives the axes' reference: the hold and the
accepted trajectories' motions (``reference_stream.ReferenceStream``), or
the operator's shaped velocity command (``operator.OperatorStream``). Each
samples a tick into a ``Setpoint`` and says whether it is at rest and where
it has left the axes, so the loop streams whichever is active without
naming it. A *correction* changes a source's setpoint after the source, in
the order of the chain (a feedback on the measured swing is one): it gets
the tick, its stamp and the setpoint and returns the corrected one. With no
corrections the source's setpoint is published as it is. A *watch* sees
every setpoint as it is published and the source that made it, changes
none, and may hold the source back (the runway guard refuses motions
towards another crane).

Pure Python, no ROS import.
"""
from __future__ import annotations

from typing import NamedTuple, Protocol, runtime_checkable


class Setpoint(NamedTuple):
    """One tick's reference of the streamed axes: position (m), velocity (m/s), acceleration (m/s^2), each a
    float with one joint, else a tuple in the stream's joint order.

    A named tuple: the loop makes one a tick, and it unpacks as the reference writer takes it."""

    position: float | tuple
    velocity: float | tuple
    acceleration: float | tuple


@runtime_checkable
class Source(Protocol):
    """The axes' reference, a tick at a time (see the module docstring)."""

    def sample(self, tick: int) -> Setpoint:
        """The setpoint due at ``tick`` (the loop's; the loop calls it once a tick, in order)."""

    @property
    def at_rest(self) -> bool:
        """Nothing moving nor about to: a mode may change here, and a ~/stop running to rest has ended."""

    @property
    def moving(self) -> bool:
        """The reference is moving now (what ``stream_state`` and the diagnostics report)."""

    @property
    def position(self) -> float | tuple:
        """Where the source has left the axes (m): its last setpoint's position."""


@runtime_checkable
class Correction(Protocol):
    """A change applied to every tick's setpoint after the source (see the module docstring)."""

    def correct(self, tick: int, stamp_ns: int, setpoint: Setpoint) -> Setpoint:
        """The corrected setpoint of ``tick``, published with the stamp ``stamp_ns`` (ROS time)."""


@runtime_checkable
class Watch(Protocol):
    """A rule that sees every published setpoint (see the module docstring)."""

    def watch(self, stamp_ns: int, setpoint: Setpoint, source: Source) -> None:
        """The setpoint published with the stamp ``stamp_ns`` (ROS time), made by ``source``."""


def corrected(corrections: tuple, tick: int, stamp_ns: int, setpoint: Setpoint) -> Setpoint:
    """``setpoint`` through ``corrections`` in their order (none: ``setpoint`` itself)."""
    for correction in corrections:
        setpoint = correction.correct(tick, stamp_ns, setpoint)
    return setpoint
