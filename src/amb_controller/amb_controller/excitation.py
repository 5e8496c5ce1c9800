"""Excitation injected into the control current, for identification (ROS-free).

``sine``: A sin(2 pi f t_k); ``noise``: white Gaussian of standard deviation A, seeded (reproducible in lockstep,
where each sample is answered once and in order).  Added to the PID output on the selected channels, before the
current limit.  Off (``none``) by default.
"""

from __future__ import annotations

import math

import numpy as np

KINDS = ("none", "sine", "noise")


class Excitation:
    def __init__(self, kind: str, amplitude: float, frequency_hz: float, channels, n_channels: int, seed: int = 0):
        self.kind, self.amplitude, self.frequency_hz = kind, amplitude, frequency_hz
        self.mask = np.zeros(n_channels)
        self.mask[list(channels)] = 1.0
        self.rng = np.random.default_rng(seed)

    @property
    def active(self) -> bool:
        return self.kind != "none" and self.amplitude != 0.0

    def __call__(self, t: float) -> np.ndarray:
        """Excitation current (A) at time t (s), shape (n_channels,)."""
        if self.kind == "sine":
            return self.mask * (self.amplitude * math.sin(2.0 * math.pi * self.frequency_hz * t))
        return self.mask * (self.amplitude * self.rng.standard_normal(self.mask.size))
