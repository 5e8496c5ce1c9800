"""The plant's sensor and amplifier models and its policy when commands stop (ROS-free).

Sensor: measured displacement = quantize(y(t_{k-d}) + noise), with d samples of delay, zero-mean Gaussian noise
(seeded, so a lockstep run stays reproducible) and a quantization step; all off by default.
Amplifier: the applied current is clipped at +/- current_limit.
Command policy (realtime): over [t_{k-1}, t_k] the plant applies the command that answers sample k-1-d, d the
loop's computation delay (controller.delay_samples: 0 or 1).  With d = 0 the emulation computes the step after the
command arrived (zero delay, as in the sampled-data model); with d = 1 a command acts from the next sample on, as a
DSP's DAC is updated at the next tick, so the loop's delay is exactly one sample whatever the command's transit
time within two periods.  A late command (answering an older sample) is held and counted; once the newest command
answers a sample more than ``hold_samples`` samples old, the current is set to zero (what an amplifier does when its
command link drops: de-energise; the rotor then settles on its touchdown bearings).  Levitation starts once the
loop keeps up: the plant holds its start state until ``start_samples`` consecutive commands were on time (a loop
whose first answers come late, while its processes warm up, would start with several samples of delay, which an
open-loop unstable rotor does not survive).
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
    """Which current to apply at sample k, given the commands received (each answers one published sample)."""

    def __init__(self, n_channels: int, hold_samples: int, delay_samples: int = 0, start_samples: int = 1):
        self.hold, self.delay, self.start = hold_samples, delay_samples, start_samples
        self.streak = 0  # consecutive on-time commands before levitation starts
        self.zero = np.zeros(n_channels)
        self.last: np.ndarray | None = None  # the command applied last (or, before any, None)
        self.last_k = -1  # the sample it answers
        self.pending: deque[tuple[int, np.ndarray]] = deque()  # (answered sample, current) newer than last_k
        self.held = 0  # samples applied with a late (held) command
        self.zeroed = 0  # samples with zero current because commands stopped
        self.waiting = 0  # ticks before levitation started (the plant holds its start state)
        self.losses = 0  # times the command stream went silent beyond the hold window
        self.state = "waiting"

    def command(self, current: np.ndarray, answered_k: int) -> None:
        """A command that answers published sample ``answered_k`` (the plant's sample index, not its wall-clock
        tick); one older than the newest received is ignored."""
        newest = self.pending[-1][0] if self.pending else self.last_k
        if answered_k >= newest:
            if self.pending and answered_k == newest:
                self.pending[-1] = (answered_k, current)
            else:
                self.pending.append((answered_k, current))

    def on_time(self, k: int) -> bool:
        """True once the command that answers sample k - 1 - delay has arrived: the step after sample k - 1 can be
        computed before its tick (``current(k)`` then returns that command)."""
        due = k - 1 - self.delay
        for answered, _ in self.pending:  # ascending
            if answered >= due:
                return answered == due
        return False

    def current(self, k: int) -> np.ndarray | None:
        """Current to apply over the step after published sample k - 1: the newest command that answers sample
        k - 1 - delay or an earlier one.  None until levitation starts (``start_samples`` consecutive on-time
        commands): the plant holds the rotor at its start state (at rest on the controller) until then."""
        due = k - 1 - self.delay
        while self.pending and self.pending[0][0] <= due:
            self.last_k, self.last = self.pending.popleft()
        if self.state == "waiting":
            self.streak = self.streak + 1 if self.last is not None and self.last_k == due else 0
            if self.streak < self.start:
                self.waiting += 1
                return None
        age = due - self.last_k  # samples of delay beyond the loop's
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
