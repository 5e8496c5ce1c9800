"""Base-motion samples on the grid t_k = k Ts, computed in blocks (ROS-free).

The node publishes one sample per step; evaluating the profile for one t at a time costs more than the DDS
publish, so samples are computed ``BLOCK`` at a time, vectorised, exactly as the offline simulation evaluates
them (``BaseMotion.angular_velocity(np.arange(K) * Ts)``).
"""

from __future__ import annotations

import numpy as np

from amb_dynamics.motion import BaseMotion

BLOCK = 256


class SampleSource:
    """``sample(k)`` -> (quaternion xyzw (4,), Omega (3,), dOmega (3,)) at t_k = k Ts."""

    def __init__(self, motion: BaseMotion, Ts: float):
        self.motion, self.Ts = motion, Ts
        self._k0 = -1
        self._q = self._om = self._dom = None

    def _fill(self, k0: int) -> None:
        t = np.arange(k0, k0 + BLOCK) * self.Ts
        self._om, self._dom = (np.ascontiguousarray(a.T) for a in self.motion.angular_velocity(t))
        self._q = self.motion.attitude(t)
        self._k0 = k0

    def sample(self, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if not (self._k0 >= 0 and self._k0 <= k < self._k0 + BLOCK):
            self._fill(k - k % BLOCK)
        j = k - self._k0
        return self._q[j], self._om[j], self._dom[j]
