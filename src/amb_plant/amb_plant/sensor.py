"""The plant's sensor and amplifier models and its policy when commands stop (ROS-free).

Sensor: measured displacement = quantize(y(t_{k-d}) + noise), with d samples of delay, zero-mean Gaussian noise
(seeded, so a lockstep run stays reproducible) and a quantization step; all off by default.
Amplifier: the applied current is clipped at +/- current_limit.
Command policy (realtime): over [t_{k-1}, t_k] the plant applies the latest command; on time it answers sample
k-1 (zero delay, as in the sampled-data model).  A late command (answering an older sample) is held and counted;
once the newest command answers a sample more than ``hold_samples`` samples old, the current is set to zero (what
an amplifier does when its command link drops: de-energise; the rotor then settles on its touchdown bearings).
Before the first command: zero.
"""

from __future__ import annotations

from collections import deque

import numpy as np


class SensorModel:
    """Measured AMB displacement from the true one."""

    def __init__(self, noise_std: float = 0.0, quantum: float = 0.0, delay_samples: int = 0, seed: int = 0):
        self.noise_std, self.quantum, self.delay = noise_std, quantum, delay_samples
        self.rng = np.random.default_rng(seed)
        self._past: deque[np.ndarray] = deque(maxlen=delay_samples + 1)

    @property
    def ideal(self) -> bool:
        return self.noise_std == 0.0 and self.quantum == 0.0 and self.delay == 0

    def measure(self, y: np.ndarray) -> np.ndarray:
        if self.ideal:
            return y
        if not self._past:  # before d samples exist, the sensor reports the first one
            self._past.extend([y] * (self.delay + 1))
        self._past.append(y)
        out = self._past[0]
        if self.noise_std:
            out = out + self.noise_std * self.rng.standard_normal(out.shape)
        if self.quantum:
            out = self.quantum * np.round(out / self.quantum)
        return out


class CommandPolicy:
    """Which current to apply at sample k, given when the latest command arrived."""

    def __init__(self, n_channels: int, hold_samples: int):
        self.hold = hold_samples
        self.zero = np.zeros(n_channels)
        self.last: np.ndarray | None = None
        self.last_k = -1
        self.held = 0  # samples applied with a late (held) command
        self.zeroed = 0  # samples with zero current because commands stopped
        self.waiting = 0  # ticks before the first command (the plant holds its start state)
        self.losses = 0  # times the command stream went silent beyond the hold window
        self.state = "waiting"

    def command(self, current: np.ndarray, answered_k: int) -> None:
        """A command that answers published sample ``answered_k`` (the plant's sample index, not its wall-clock
        tick); an older one than the latest is ignored."""
        if answered_k >= self.last_k:
            self.last, self.last_k = current, answered_k
            self.state = "ok"

    def current(self, k: int) -> np.ndarray | None:
        """Current to apply over the step after published sample k - 1 (A); None before the first command:
        levitation starts with the controller, so the plant holds the rotor at its start state (at rest on the
        controller) until then."""
        if self.last is None:
            self.waiting += 1
            return None
        age = k - 1 - self.last_k  # samples of delay beyond the model's
        if age <= 0:
            self.state = "ok"
            return self.last
        if age <= self.hold:
            self.held += 1
            self.state = "holding"
            return self.last
        if self.state != "zeroed":
            self.losses += 1
        self.state = "zeroed"
        self.zeroed += 1
        return self.zero
