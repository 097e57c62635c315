"""What acts on the load besides the crane: a steady wind and gusts (contract "Closed-loop sway control").

Both are horizontal accelerations (m/s^2) acting alike on both masses, a uniform field: for the
swing the same as the suspension point accelerating the other way (``crane_sim.simulator``, whose
``CraneSimulator.disturbance`` and ``simulate(disturbance=...)`` take them). A wind is steady; a gust
is a seeded Ornstein-Uhlenbeck process per horizontal direction (x, and y with a bridge): Gaussian,
of a given standard deviation, correlated over a given time, the simplest model of turbulence with
a finite correlation time (a white noise would have no effect a pendulum could feel, nor a bounded
variance after integration). Pure numpy, no ROS import.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from crane_msgs_py.crane.params import ParameterError, check_nonnegative, check_positive

from .simulator import interpolate

#: The gusts' stream of a run's one ``seed``: ``numpy.random.default_rng([seed, GUST_STREAM])``, apart from
#: the noise's (the seed itself) and the sensor's dropout, so that turning one on changes none of the others.
GUST_STREAM = 2


class Gust:
    """A seeded Ornstein-Uhlenbeck process per plane, standard deviation ``sd`` (m/s^2), correlation time
    ``time_constant`` (s), stepped by its exact discretisation

        w[k+1] = w[k] e^(-h/T) + sd sqrt(1 - e^(-2h/T)) N(0, 1),

    so any step ``h`` samples the same process (its autocorrelation e^(-|lag|/T)). It starts stationary
    (w ~ N(0, sd^2)) when ``sd`` first becomes positive. Kept as a unit process times ``sd``: a changed
    ``sd`` scales the gust at once, a changed ``time_constant`` changes how it goes on; ``sd`` 0 draws
    nothing and holds 0 (a run without gusts stays the run it was).

    Args:
        sd, time_constant: as above.
        planes: 1 (x) or 2 (x and y: a crane with a bridge).
        seed: the run's seed (an integer >= 0; None: unseeded), its stream ``GUST_STREAM``: reproducible.
    """

    def __init__(self, sd: float = 0.0, time_constant: float = 1.0, planes: int = 1, seed=0):
        if planes not in (1, 2):
            raise ParameterError(f'a gust acts in 1 or 2 planes, got {planes}')
        self.planes = planes
        self._rng = np.random.default_rng(None if seed is None else [seed, GUST_STREAM])
        self._unit: list[float] | None = None  # the unit process, drawn stationary once sd is first positive
        self._coefficients: tuple = (None, 0.0, 0.0)  # (h, decay, spread) of the last step size
        self.configure(sd, time_constant)

    def configure(self, sd: float, time_constant: float) -> None:
        """A new standard deviation (m/s^2) and correlation time (s), from now on."""
        self.sd = check_nonnegative('gust', sd)
        self.time_constant = check_positive('gust_time', time_constant)
        self._coefficients = (None, 0.0, 0.0)
        if self._unit is None and self.sd > 0.0:  # the stationary start
            self._unit = self._rng.standard_normal(self.planes).tolist()

    @property
    def value(self) -> tuple[float, ...]:
        """The gust now (m/s^2), one per plane."""
        if self.sd == 0.0:
            return (0.0,) * self.planes
        return tuple(self.sd * z for z in self._unit)

    def _weights(self, h: float) -> tuple[float, float]:
        """(e^(-h/T), sqrt(1 - e^(-2h/T))) for a step ``h``, kept for the next step of the same size."""
        if self._coefficients[0] != h:
            decay = math.exp(-check_positive('step', h) / self.time_constant)
            self._coefficients = (h, decay, math.sqrt(-math.expm1(-2.0 * h / self.time_constant)))
        return self._coefficients[1:]

    def step(self, h: float) -> tuple[float, ...]:
        """The gust ``h`` s later (m/s^2), one per plane."""
        if self.sd == 0.0:
            return (0.0,) * self.planes
        decay, spread = self._weights(h)
        draws = self._rng.standard_normal(self.planes).tolist()
        self._unit = [decay * z + spread * n for z, n in zip(self._unit, draws)]
        return self.value

    def path(self, steps: int, h: float) -> np.ndarray:
        """The gust now and after each of ``steps`` steps of ``h`` s: (planes, steps + 1), the values
        ``step`` would give one by one (the same draws), and the gust moved on as far."""
        out = np.zeros((self.planes, steps + 1))
        if self.sd == 0.0:
            return out
        decay, spread = self._weights(h)
        draws = self._rng.standard_normal((steps, self.planes))
        z = np.empty((steps + 1, self.planes))
        z[0] = self._unit
        for k in range(steps):  # a recursion: each value from the last
            z[k + 1] = decay * z[k] + spread * draws[k]
        self._unit = z[-1].tolist()
        return self.sd * z.T


@dataclass(frozen=True)
class Disturbances:
    """The disturbances' settings (all off by default): a steady ``wind`` (ax, ay) (m/s^2), and gusts of
    standard deviation ``gust`` (m/s^2) and correlation time ``gust_time`` (s) (``Gust``)."""

    wind: tuple[float, float] = (0.0, 0.0)
    gust: float = 0.0
    gust_time: float = 1.0

    def __post_init__(self):
        try:
            wind = tuple(float(v) for v in self.wind)
        except (TypeError, ValueError):
            wind = ()
        if len(wind) != 2 or not all(math.isfinite(v) for v in wind):
            raise ParameterError(f'wind must be two finite accelerations [ax, ay] (m/s^2), got {self.wind}')
        object.__setattr__(self, 'wind', wind)
        object.__setattr__(self, 'gust', check_nonnegative('gust', self.gust))
        object.__setattr__(self, 'gust_time', check_positive('gust_time', self.gust_time))

    def check_planes(self, bridge: bool) -> 'Disturbances':
        """These settings, if a crane with (``bridge``) or without a bridge can take them: without one the
        load swings in the x-z plane alone, and a wind along y would act on nothing it models."""
        if not bridge and self.wind[1] != 0.0:
            raise ParameterError(f'wind along y ({self.wind[1]:g} m/s^2) needs the bridge: the crane without one '
                                 'swings in the x-z plane alone')
        return self

    def plus(self, gust) -> tuple[float, float]:
        """The acceleration (ax, ay) (m/s^2) of the wind plus a gust's value (one per plane: x, then y)."""
        ax, ay = self.wind
        return ax + gust[0], ay + gust[1] if len(gust) > 1 else ay

    @property
    def active(self) -> bool:
        """Whether anything acts at all."""
        return self.wind != (0.0, 0.0) or self.gust > 0.0

    def sampled(self, t0: float, t_end: float, h: float, bridge: bool = False, seed=0) -> 'SampledDisturbance':
        """The wind plus a gust path (``Gust`` seeded with ``seed``, sampled every ``h`` s from ``t0`` past
        ``t_end``) as ``simulate``'s ``disturbance``: rows x and y (y with a ``bridge`` only)."""
        self.check_planes(bridge)
        steps = max(1, math.ceil((t_end - t0) / check_positive('h', h) - 1e-9))
        t = t0 + h * np.arange(steps + 1)
        w = np.zeros((2, steps + 1))
        w[:2 if bridge else 1] = Gust(self.gust, self.gust_time, 2 if bridge else 1, seed).path(steps, h)
        return SampledDisturbance(t, w + np.array(self.wind)[:, None])


class SampledDisturbance:
    """A disturbance given by samples ``w`` (2, m) (rows x, y; or (2, n_batch, m) per plant) at times ``t``
    (m,), linear between them and held beyond: a callable ``w(times)`` as ``simulate`` takes one."""

    def __init__(self, t, w):
        self.t = np.asarray(t, dtype=float)
        self.w = np.asarray(w, dtype=float)
        if self.t.ndim != 1 or self.t.size == 0 or np.any(np.diff(self.t) <= 0.0):
            raise ParameterError('a sampled disturbance needs strictly increasing times')
        if self.w.shape[0] != 2 or self.w.shape[-1] != self.t.size or self.w.ndim not in (2, 3):
            raise ParameterError(f'a sampled disturbance needs samples of shape (2, {self.t.size}) or '
                                 f'(2, n_batch, {self.t.size}), got {self.w.shape}')

    def __call__(self, times) -> np.ndarray:
        return interpolate(self.t, self.w, times, 'linear')
