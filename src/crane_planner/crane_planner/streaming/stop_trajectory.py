"""A stop's trajectory from its handover, as the streamer takes it over: the record both kinds of stop give.

A stop without swing (``serving.stops``, planned in a worker process) and
the axes' braking ramp (``braking_stop``, the last resort) are both knots
from a handover on, handed to ``ReferenceStream.accept``. Pure Python, no
ROS import.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class StopTrajectory:
    """A stop's trajectory from its handover: knot times ``t`` (s), per joint columns ((knots, joints):
    absolute m, m/s, m/s^2), the handover (ns of ROS time), its duration (s) and how it stops (``method``);
    where the axes stop is ``end``."""

    t: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    handover_ns: int
    duration: float
    method: str

    @property
    def end(self) -> float | tuple:
        """Where the axes stop (m): one joint's a float, several joints' a tuple in their order."""
        last = tuple(float(x) for x in self.position[-1])
        return last[0] if len(last) == 1 else last

    def arrays(self) -> tuple:
        """(t, position, velocity, acceleration) as ``ReferenceStream.accept`` takes them (one joint: 1-D)."""
        columns = (self.position, self.velocity, self.acceleration)
        if self.position.shape[1] == 1:
            columns = tuple(c[:, 0] for c in columns)
        return (self.t, *columns)
