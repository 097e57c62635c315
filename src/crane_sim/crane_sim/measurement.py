"""What a swing sensor reports: the true angles plus seeded Gaussian noise (e.g. a camera's).

The paper measured the swing with a camera at 50 Hz; a real measurement is
noisy. Both the sim node (``noise``, ``seed``) and offline recordings
(``measured_angles``) use this one model, so identification is tested on
data that looks like a rig's. Pure numpy, no ROS import.
"""
from __future__ import annotations

import numpy as np

from crane_msgs_py.crane.params import check_nonnegative


class AngleNoise:
    """Adds independent zero-mean Gaussian noise of standard deviation ``std`` (rad) to angles.

    Seeded (``numpy.random.default_rng(seed)``), so a run is reproducible;
    ``std`` 0 returns the angles unchanged and draws nothing.
    """

    def __init__(self, std: float = 0.0, seed: int | None = 0):
        self.std = check_nonnegative('noise', std)
        self.seed = seed
        self._rng = np.random.default_rng(seed)

    def __call__(self, *angles):
        """The angles (floats or arrays) with noise added, as a tuple in the same order."""
        if self.std == 0.0:
            return angles
        return tuple(np.asarray(a, dtype=float) + self._rng.normal(0.0, self.std, np.shape(a)) for a in angles)


def measured_angles(result, std: float = 0.0, seed: int | None = 0) -> tuple[np.ndarray, np.ndarray]:
    """(theta1, theta2) of a ``simulator.SimResult`` as a sensor with noise ``std`` (rad) reports them."""
    return AngleNoise(std, seed)(result.theta1, result.theta2)
