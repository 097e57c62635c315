"""The sway sensor as a camera is one: each sample measured at an instant, reported later, now and then lost.

Contract ("Closed-loop sway control"): ``joint_states`` carry the swing measured at their stamp; a camera's
processing reports each sample ``latency`` s after it was taken, with the stamp of its measurement and in
the order taken; ``dropout`` is the probability that a sample is lost; the angles carry the camera's noise
(``measurement.AngleNoise``). The sim node measures every ``joint_states`` sample through a ``Sensor``:
what a feedback on the measured swing gets is then what it would get from a rig. Pure, no ROS import.
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

from crane_msgs_py.crane.params import ParameterError, check_nonnegative

from .measurement import AngleNoise

#: The dropout's stream of a run's one ``seed``: ``numpy.random.default_rng([seed, DROPOUT_STREAM])``, apart
#: from the noise's (the seed itself, as ``AngleNoise`` has always drawn it) and the gusts'
#: (``disturbances.GUST_STREAM``), so that turning one on changes none of the others.
DROPOUT_STREAM = 1
#: A sample is due this much (s) early still: its time plus the latency, both sums of steps, may round past
#: the step that should release it.
DUE_TOLERANCE = 1e-9


@dataclass(frozen=True)
class SensorSettings:
    """What may change while the sensor runs: ``latency`` (s, >= 0), ``dropout`` (the probability of a
    sample lost, 0..1) and ``noise`` (rad, the standard deviation added to the angles)."""

    latency: float = 0.0
    dropout: float = 0.0
    noise: float = 0.0

    def __post_init__(self):
        object.__setattr__(self, 'latency', check_nonnegative('sensor_latency', self.latency))
        dropout = float(self.dropout)
        if not 0.0 <= dropout <= 1.0:  # (a NaN fails this too)
            raise ParameterError(f'sensor_dropout must be a probability in [0, 1], got {self.dropout}')
        object.__setattr__(self, 'dropout', dropout)
        object.__setattr__(self, 'noise', check_nonnegative('noise', self.noise))


@dataclass(frozen=True)
class Sample:
    """One measurement: when it was taken (``taken``, the sensor's clock, s), its ``stamp`` (what the caller
    stamps it with, e.g. ROS ns), the ``angles`` as measured (noise added) and whatever else it carries
    (``values``: read exactly, such as the axes' encoders)."""

    taken: float
    stamp: object
    angles: tuple
    values: tuple


class Sensor:
    """Samples taken by ``measure`` and handed back by ``released`` once due: ``latency`` after they were taken
    (the latency in force when they are released: a queue, so the order is always the order taken), each
    lost with probability ``dropout`` when taken, the angles with noise.

    Args:
        settings: a ``SensorSettings`` (default: no latency, no dropout, no noise: every sample is released
            at once, as measured).
        seed: the run's seed (an integer >= 0; None: unseeded): the noise draws from it as
            ``AngleNoise(noise, seed)`` always has, the dropout from its stream ``DROPOUT_STREAM``.
    """

    def __init__(self, settings: SensorSettings | None = None, seed: int | None = 0):
        self._noise = AngleNoise(0.0, seed)
        self._rng = np.random.default_rng(None if seed is None else [seed, DROPOUT_STREAM])
        self._queue: deque[Sample] = deque()
        self.taken = self.dropped = 0  # samples measured, of them lost
        self.settings = settings or SensorSettings()

    @property
    def settings(self) -> SensorSettings:
        return self._settings

    @settings.setter
    def settings(self, settings: SensorSettings) -> None:
        """New settings from now on: a changed latency applies to the samples still queued too; the noise's
        draws go on (its stream is not restarted)."""
        self._settings = settings
        self._noise.std = settings.noise

    def measure(self, now: float, stamp, angles, *values) -> Sample | None:
        """Take a sample at ``now`` (s, the clock ``released`` is asked by): the swing ``angles`` (a
        sequence; noise is drawn for every sample, lost or not, so a sample's noise does not depend on the
        dropout) and ``values``, stamped ``stamp``. The sample queued, or None if it was lost."""
        self.taken += 1
        measured = tuple(self._noise(*angles))
        dropout = self._settings.dropout
        if dropout > 0.0 and self._rng.random() < dropout:
            self.dropped += 1
            return None
        sample = Sample(float(now), stamp, measured, values)
        self._queue.append(sample)
        return sample

    def released(self, now: float) -> list[Sample]:
        """The samples due by ``now`` (taken at least ``latency`` before it), oldest first, out of the queue."""
        queue, out = self._queue, []
        due = now - self._settings.latency + DUE_TOLERANCE
        while queue and queue[0].taken <= due:
            out.append(queue.popleft())
        return out

    @property
    def pending(self) -> int:
        """How many samples are taken and not yet released."""
        return len(self._queue)
