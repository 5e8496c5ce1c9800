"""Closed-loop eigen-analysis at a constant base rate (Omega = 0 by default) over spin speeds.

A mode is a complex-conjugate pair of the continuous closed loop (PHYSICS.md 3.2), reported once with its damped
frequency Im(lambda) > 0; real (overdamped) roots are listed separately.  Whirl: forward if
sum_nodes Im(conj(phi_v) phi_w) < 0 (the orbit turns from +Y toward +Z), PHYSICS.md T15.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .structure import StructuralModel
from .system import ClosedLoop, coefficients_from_rates

REAL_ROOT_TOL = 1e-9  # |Im lambda| <= tol * |lambda| counts as a real root


@dataclass(frozen=True)
class Mode:
    frequency_rad_s: float  # damped natural frequency Im(lambda)
    damping_ratio: float  # -Re(lambda)/|lambda|
    whirl: str  # forward | backward
    eigenvalue: complex

    def to_dict(self) -> dict:
        return {
            "frequency_rad_s": self.frequency_rad_s,
            "frequency_hz": self.frequency_rad_s / (2 * np.pi),
            "damping_ratio": self.damping_ratio,
            "whirl": self.whirl,
            "eigenvalue": [self.eigenvalue.real, self.eigenvalue.imag],
        }


@dataclass(frozen=True)
class ModalResult:
    speed_rpm: float
    modes: tuple[Mode, ...]
    real_roots: tuple[float, ...]  # 1/s, sorted by decreasing value (least damped first)

    def to_dict(self) -> dict:
        return {
            "speed_rpm": self.speed_rpm,
            "spin_rad_s": self.speed_rpm * np.pi / 30,
            "modes": [m.to_dict() for m in self.modes],
            "real_roots_1_s": list(self.real_roots),
            "stable": all(m.eigenvalue.real < 0 for m in self.modes) and all(r < 0 for r in self.real_roots),
        }


def whirl_direction(model: StructuralModel, phi_q: np.ndarray) -> str:
    """forward/backward from the displacement part of an eigenvector (generalised coordinates)."""
    phi = model.to_fe(phi_q)
    v, w = phi[0::4], phi[1::4]
    return "forward" if np.sum(np.imag(np.conj(v) * w)) < 0 else "backward"


def modes_at_speed(
    model: StructuralModel, loop: ClosedLoop, speed_rpm: float, Omega: np.ndarray | None = None
) -> ModalResult:
    """Eigen-analysis of the closed loop spinning at ``speed_rpm`` on a base turning at constant ``Omega``."""
    Om = np.zeros(3) if Omega is None else np.asarray(Omega, dtype=float)
    c = coefficients_from_rates(Om, np.zeros(3), speed_rpm * np.pi / 30.0)
    lam, vecs = np.linalg.eig(loop.matrix(c))
    modes, real = [], []
    for j, z in enumerate(lam):
        if abs(z.imag) <= REAL_ROOT_TOL * max(abs(z), 1.0):
            real.append(float(z.real))
        elif z.imag > 0:
            whirl = whirl_direction(model, vecs[: loop.n, j])
            modes.append(Mode(float(z.imag), float(-z.real / abs(z)), whirl, complex(z)))
    modes.sort(key=lambda m: m.frequency_rad_s)
    return ModalResult(float(speed_rpm), tuple(modes), tuple(sorted(real, reverse=True)))


def campbell_data(model: StructuralModel, loop: ClosedLoop, speeds_rpm) -> list[ModalResult]:
    return [modes_at_speed(model, loop, s) for s in speeds_rpm]
