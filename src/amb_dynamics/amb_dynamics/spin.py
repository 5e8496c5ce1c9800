"""Spin-speed profile (config ``spin``): constant ``spin_speed_rpm``, or a ramp from start_rpm to end_rpm at
rate_rpm_s, then held (run-up or coast-down through the critical speeds)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from .config import RotorConfig

RPM = math.pi / 30.0


@dataclass(frozen=True)
class SpinProfile:
    """phi_dot(t) (rad/s): start + rate t until end is reached; constant if rate = 0."""

    start: float  # rad/s
    end: float  # rad/s
    rate: float  # rad/s^2, signed

    @classmethod
    def from_config(cls, cfg: RotorConfig) -> SpinProfile:
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
