"""Closed-loop eigen-analysis at a constant base rate (Omega = 0 by default) over spin speeds.

A mode is a complex-conjugate pair of the closed loop (docs/physics.md#controller), reported once with its damped
frequency Im(lambda) > 0; real (overdamped) roots are listed separately, and so are the pairs that spinning makes
of them: the gyroscopic coupling turns the two equal real roots of an overdamped bearing motion (one per lateral
direction) into a pair -a +- i b with b << a, a whirl that dies out long before it turns (damping ratio at or above
OVERDAMPED_ZETA: it decays by a factor e^140 or more per cycle).  Such a pair is no mode a rotor runs through, so
it is not in ``modes`` (nor in a Campbell diagram) but in ``overdamped_pairs``.  Whirl: forward if
sum_nodes Im(conj(phi_v) phi_w) < 0 (the orbit turns from +Y toward +Z), docs/physics.md#modes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .structure import StructuralModel
from .system import ClosedLoop, coefficients_from_rates

REAL_ROOT_TOL = 1e-9  # |Im lambda| <= tol * |lambda| counts as a real root
REPEAT_TOL = 1e-7  # eigenvalues this close (relative) form one whirl cluster
OVERDAMPED_ZETA = 0.999  # a pair this damped is an overdamped motion, not a mode (|Im| < 0.045 |Re|)


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
    overdamped: tuple[complex, ...] = ()  # pairs with damping ratio >= OVERDAMPED_ZETA (Im > 0 member), as real_roots

    @property
    def stable(self) -> bool:
        return (
            all(m.eigenvalue.real < 0 for m in self.modes)
            and all(r < 0 for r in self.real_roots)
            and all(z.real < 0 for z in self.overdamped)
        )

    def to_dict(self) -> dict:
        return {
            "speed_rpm": self.speed_rpm,
            "spin_rad_s": self.speed_rpm * np.pi / 30,
            "modes": [m.to_dict() for m in self.modes],
            "real_roots_1_s": list(self.real_roots),
            "overdamped_pairs_1_s": [[z.real, z.imag] for z in self.overdamped],
            "stable": self.stable,
        }


def whirl_form(model: StructuralModel, phis_q: np.ndarray) -> np.ndarray:
    """Hermitian whirl form H_ij = sum_nodes (conj(v_i) w_j - conj(w_i) v_j)/(2i) of eigenvectors (columns).

    For one vector H = sum Im(conj(v) w): negative = forward.  For a repeated eigenvalue (an isotropic rotor
    at rest) the eigenvectors of H are the pure forward and backward circular modes of the eigenspace.
    """
    phi = model.to_fe(phis_q.T).T
    v, w = phi[0::4], phi[1::4]
    return (v.conj().T @ w - w.conj().T @ v) / 2j


def whirl_labels(model: StructuralModel, phis_q: np.ndarray) -> list[str]:
    """forward/backward for a cluster of (numerically) equal eigenvalues, eigenvectors as columns."""
    signs = np.linalg.eigvalsh(whirl_form(model, phis_q))
    return ["forward" if x < 0 else "backward" for x in signs]


def modes_at_speed(
    model: StructuralModel, loop: ClosedLoop, speed_rpm: float, Omega: np.ndarray | None = None
) -> ModalResult:
    """Eigen-analysis of the closed loop spinning at ``speed_rpm`` on a base turning at constant ``Omega``."""
    Om = np.zeros(3) if Omega is None else np.asarray(Omega, dtype=float)
    c = coefficients_from_rates(Om, np.zeros(3), speed_rpm * np.pi / 30.0)
    lam, vecs = np.linalg.eig(loop.matrix(c))
    real_mask = np.abs(lam.imag) <= REAL_ROOT_TOL * np.maximum(np.abs(lam), 1.0)
    real = [float(z.real) for z in lam[real_mask]]
    upper = np.flatnonzero(~real_mask & (lam.imag > 0))
    upper = upper[np.argsort(lam[upper].imag)]
    modes, overdamped = [], []
    i = 0
    while i < upper.size:  # clusters of repeated eigenvalues share one whirl decomposition
        j = i + 1
        while j < upper.size and abs(lam[upper[j]] - lam[upper[i]]) <= REPEAT_TOL * abs(lam[upper[i]]):
            j += 1
        idx = upper[i:j]
        for k, whirl in zip(idx, whirl_labels(model, vecs[: loop.n, idx]), strict=True):
            z = lam[k]
            zeta = float(-z.real / abs(z))
            if zeta >= OVERDAMPED_ZETA:
                overdamped.append(complex(z))
            else:
                modes.append(Mode(float(z.imag), zeta, whirl, complex(z)))
        i = j
    overdamped.sort(key=lambda z: z.real, reverse=True)
    return ModalResult(float(speed_rpm), tuple(modes), tuple(sorted(real, reverse=True)), tuple(overdamped))


def campbell_data(model: StructuralModel, loop: ClosedLoop, speeds_rpm) -> list[ModalResult]:
    return [modes_at_speed(model, loop, s) for s in speeds_rpm]
