"""Spin profile (config ``spin``): the spin angle, rate and acceleration relative to the base at time t.

``constant``: phi' = spin_speed_rpm.  ``ramp``: the speed goes linearly from start_rpm to end_rpm at rate_rpm_s
(run-up or coast-down), then holds end_rpm; phi is its exact integral (phi(0) = 0).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

RPM = np.pi / 30.0  # rad/s per rpm


def spin_state(cfg, t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(phi rad, phi' rad/s, phi'' rad/s^2) at times t (s), arrays of the shape of t."""
    t = np.asarray(t, dtype=float)
    sp = cfg.spin
    if sp.profile == "constant":
        w = cfg.spin_speed_rpm * RPM
        return w * t, np.full_like(t, w), np.zeros_like(t)
    w0, w1 = sp.start_rpm * RPM, sp.end_rpm * RPM
    a = np.sign(w1 - w0) * sp.rate_rpm_s * RPM
    t_end = (w1 - w0) / a
    tr = np.clip(t, 0.0, t_end)
    phi = w0 * tr + 0.5 * a * tr**2 + w1 * np.maximum(t - t_end, 0.0)
    rate = w0 + a * tr
    acc = np.where((t >= 0.0) & (t < t_end), a, 0.0)
    return phi, rate, acc


@dataclass(frozen=True)
class SpinProfile:
    """The spin profile of config ``spin`` per step (scalars; spin.spin_state is the array form)."""

    start: float  # rad/s
    end: float  # rad/s
    rate: float  # rad/s^2, signed

    @classmethod
    def from_config(cls, cfg) -> SpinProfile:
        sp = cfg.spin
        if sp.profile == "ramp":
            sign = 1.0 if sp.end_rpm > sp.start_rpm else -1.0
            return cls(sp.start_rpm * RPM, sp.end_rpm * RPM, sign * sp.rate_rpm_s * RPM)
        return cls(cfg.spin_rad_s, cfg.spin_rad_s, 0.0)

    @property
    def ramp_time(self) -> float:
        """Duration of the ramp (s); 0 for a constant speed."""
        return 0.0 if self.rate == 0.0 else (self.end - self.start) / self.rate

    def speed(self, t: float) -> float:
        """phi_dot (rad/s) at time t (s)."""
        if self.rate == 0.0 or t >= self.ramp_time:
            return self.end
        return self.start + self.rate * t

    def accel(self, t: float) -> float:
        """phi_ddot (rad/s^2) at time t: the ramp rate while ramping, else 0."""
        return self.rate if self.rate != 0.0 and t < self.ramp_time else 0.0
