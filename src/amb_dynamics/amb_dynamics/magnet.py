"""Nonlinear force law of a differentially driven AMB axis (config ``bearings.force_law: nonlinear``).

Two opposed electromagnets per axis, biased with i0 and driven with +i and -i, nominal gap g0 each, the rotor
displaced by x toward the "+" magnet.  Magnet force per unit (i/g)^2 is k cos(alpha) (alpha the pole angle);
the config gives ki and ks, so the constant follows as c = k cos(alpha) = ki g0^2 / (4 i0):

    F(x, i) = c [ (i0 + i)^2 / (g0 - x)^2 - (i0 - i)^2 / (g0 + x)^2 ]      (N, on the rotor, along +x)

Linearised at (0, 0): dF/di = 4 c i0/g0^2 = ki and dF/dx = 4 c i0^2/g0^3 = -ks, so the law requires
|ks|/ki = i0/g0 (checked when the config is loaded).  With xi = x/g0, eta = i/i0 the law is odd in (xi, eta):

    F = ki i - ks x + ki i0 (2 xi^3 + 3 xi^2 eta + xi eta^2) + O(5th order),

so a small-amplitude nonlinear run differs from the linear one by a relative force error of order
2 xi^2 + 3 xi eta + eta^2 (1e-4 at 1 % of the gap and of the bias).  A coil current cannot reverse (coil
currents are clipped at 0) and with saturation each magnet's force is capped at cos(alpha) Ap Bsat^2 / mu0
(the flux density of each magnet limited at Bsat).  The gaps are floored at MIN_GAP_FRACTION g0 so that the
force stays finite if a rotor without touchdown bearings closes the gap (it then sits at the 100-gap stop).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

MU0 = 4e-7 * math.pi  # H/m
MIN_GAP_FRACTION = 1e-3


@dataclass(frozen=True)
class BearingLaw:
    """One AMB axis: ki (N/A), ks (N/m, < 0), bias i0 (A), nominal gap g0 (m), per-magnet cap f_sat (N)."""

    ki: float
    ks: float
    i0: float
    g0: float
    f_sat: float = math.inf

    @classmethod
    def from_config(cls, bearings) -> BearingLaw:
        """From a ``bearings`` config section.  g0 = i0 ki/|ks| exactly (air_gap agrees with it to 1e-6, checked
        on load), so that the linearisation is the config's ki and ks to rounding."""
        b = bearings
        f_sat = math.inf
        if b.saturation_flux_density is not None:
            f_sat = math.cos(math.radians(b.pole_angle_deg)) * b.pole_area * b.saturation_flux_density**2 / MU0
        g0 = b.bias_current * b.current_stiffness / -b.displacement_stiffness
        return cls(b.current_stiffness, b.displacement_stiffness, b.bias_current, g0, f_sat)

    @property
    def c(self) -> float:
        """Force constant k cos(alpha) = ki g0^2 / (4 i0) (N m^2/A^2)."""
        return self.ki * self.g0**2 / (4.0 * self.i0)

    def magnet_forces(self, x, i) -> tuple[np.ndarray, np.ndarray]:
        """Pull of the "+" and "-" magnets (N, both >= 0) at displacement x (m) and control current i (A)."""
        x, i = np.asarray(x, dtype=float), np.asarray(i, dtype=float)
        gmin = MIN_GAP_FRACTION * self.g0
        plus = self.c * np.maximum(self.i0 + i, 0.0) ** 2 / np.maximum(self.g0 - x, gmin) ** 2
        minus = self.c * np.maximum(self.i0 - i, 0.0) ** 2 / np.maximum(self.g0 + x, gmin) ** 2
        return np.minimum(plus, self.f_sat), np.minimum(minus, self.f_sat)

    def force(self, x, i) -> np.ndarray:
        """Net bearing force on the rotor along +x (N); elementwise over arrays of axes."""
        plus, minus = self.magnet_forces(x, i)
        return plus - minus

    def linear_force(self, x, i) -> np.ndarray:
        """The linear law of the paper's model, ki i - ks x (N)."""
        return self.ki * np.asarray(i, dtype=float) - self.ks * np.asarray(x, dtype=float)

    def current_gain(self, x, i) -> np.ndarray:
        """dF/di at (x, i) (N/A): 2c [(i0 + i)/(g0 - x)^2 + (i0 - i)/(g0 + x)^2]; ki at the centre."""
        x, i = np.asarray(x, dtype=float), np.asarray(i, dtype=float)
        return 2 * self.c * ((self.i0 + i) / (self.g0 - x) ** 2 + (self.i0 - i) / (self.g0 + x) ** 2)

    def negative_stiffness(self, x, i) -> np.ndarray:
        """-dF/dx at (x, i) (N/m, < 0): -2c [(i0 + i)^2/(g0 - x)^3 + (i0 - i)^2/(g0 + x)^3]; ks at the centre."""
        x, i = np.asarray(x, dtype=float), np.asarray(i, dtype=float)
        return -2 * self.c * ((self.i0 + i) ** 2 / (self.g0 - x) ** 3 + (self.i0 - i) ** 2 / (self.g0 + x) ** 3)

    def correction(self, x: np.ndarray, i: np.ndarray) -> np.ndarray:
        """force(x, i) - linear_force(x, i) for a few axes: the plant's per-step path, in floats (the same
        expressions as magnet_forces, a few times faster than its array form on four axes)."""
        c, i0, g0, gmin, f_sat, ki, ks = (
            self.c,
            self.i0,
            self.g0,
            MIN_GAP_FRACTION * self.g0,
            self.f_sat,
            self.ki,
            self.ks,
        )
        out = []
        for xx, ii in zip(x.tolist(), i.tolist(), strict=True):
            plus = min(c * max(i0 + ii, 0.0) ** 2 / max(g0 - xx, gmin) ** 2, f_sat)
            minus = min(c * max(i0 - ii, 0.0) ** 2 / max(g0 + xx, gmin) ** 2, f_sat)
            out.append(plus - minus - (ki * ii - ks * xx))
        return np.array(out)

    def capacity(self, current_limit: float, x: float = 0.0) -> float:
        """Largest force toward the "+" magnet at displacement x with |i| <= current_limit (N)."""
        return float(self.force(x, current_limit))
