"""Base-motion profiles (docs/physics.md#base-motion): Omega(t), dOmega(t), attitude and periods.

Every profile is a sum of harmonics beta_axis(t) = A sin(w t + phase) about roll (X), pitch (Z) and yaw (Y),
composed as R = Ry(beta_Y) Rz(beta_P) Rx(beta_R).  Single-axis motions are the one-harmonic case.
All functions are vectorised over t.
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from .config import BaseMotionConfig
from .errors import InputError

AXES = ("roll", "pitch", "yaw")
MAX_DENOMINATOR = 64  # frequency ratios with a larger denominator count as incommensurate


@dataclass(frozen=True)
class Harmonic:
    axis: str  # roll | pitch | yaw
    amplitude: float  # rad
    frequency: float  # rad/s
    phase: float = 0.0


@dataclass(frozen=True)
class BaseMotion:
    """A periodic (or static) base motion; ``kind`` is informational (roll, pitch, yaw, combined, none)."""

    harmonics: tuple[Harmonic, ...] = ()
    kind: str = "none"

    @classmethod
    def single(cls, kind: str, amplitude: float, frequency: float) -> BaseMotion:
        if kind == "none" or amplitude == 0.0:
            return cls((), "none" if kind == "none" else kind)
        if kind not in AXES:
            raise InputError(f"unknown motion kind '{kind}' (roll, pitch, yaw, none or combined)")
        if not np.isfinite(frequency) or frequency <= 0:
            raise InputError(f"motion frequency must be a positive number of rad/s (got {frequency})")
        if not np.isfinite(amplitude):
            raise InputError(f"motion amplitude must be finite (got {amplitude})")
        return cls((Harmonic(kind, float(amplitude), float(frequency)),), kind)

    @classmethod
    def from_config(cls, bm: BaseMotionConfig) -> BaseMotion:
        if bm.kind == "combined":
            hs = tuple(Harmonic(h.axis, h.amplitude, h.frequency, h.phase) for h in bm.harmonics)
            return cls(tuple(h for h in hs if h.amplitude != 0.0), "combined")
        return cls.single(bm.kind, bm.amplitude, bm.frequency)

    # ---- angles -------------------------------------------------------------------------------
    def _angles(self, t: np.ndarray):
        """beta, beta_dot, beta_ddot: arrays (3, len(t)) in the order roll, pitch, yaw."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        b, bd, bdd = (np.zeros((3, t.size)) for _ in range(3))
        for h in self.harmonics:
            i = AXES.index(h.axis)
            arg = h.frequency * t + h.phase
            s, c = np.sin(arg), np.cos(arg)
            b[i] += h.amplitude * s
            bd[i] += h.amplitude * h.frequency * c
            bdd[i] -= h.amplitude * h.frequency**2 * s
        return b, bd, bdd

    def angular_velocity(self, t) -> tuple[np.ndarray, np.ndarray]:
        """Omega(t) and dOmega/dt(t) in base axes, shape (3, len(t)) each (rad/s, rad/s^2)."""
        (bR, bP, _), (dR, dP, dY), (ddR, ddP, ddY) = self._angles(t)
        sR, cR, sP, cP = np.sin(bR), np.cos(bR), np.sin(bP), np.cos(bP)
        Om = np.array([dR + dY * sP, dP * sR + dY * cR * cP, dP * cR - dY * sR * cP])
        dOm = np.array(
            [
                ddR + ddY * sP + dY * cP * dP,
                ddP * sR + dP * cR * dR + ddY * cR * cP - dY * sR * dR * cP - dY * cR * sP * dP,
                ddP * cR - dP * sR * dR - ddY * sR * cP - dY * cR * dR * cP + dY * sR * sP * dP,
            ]
        )
        return Om, dOm

    def attitude(self, t) -> np.ndarray:
        """Quaternions (x, y, z, w) of base->inertial R = Ry(yaw) Rz(pitch) Rx(roll), shape (len(t), 4)."""
        (bR, bP, bY), _, _ = self._angles(t)
        qy = _axis_quat(1, bY)
        qp = _axis_quat(2, bP)
        qr = _axis_quat(0, bR)
        return _qmul(_qmul(qy, qp), qr)

    # ---- periods ------------------------------------------------------------------------------
    @property
    def is_static(self) -> bool:
        return not self.harmonics

    def fundamental_period(self) -> float | None:
        """2 pi / w0 with w0 the common fundamental of all harmonics; None if incommensurate."""
        if self.is_static:
            return None
        freqs = [h.frequency for h in self.harmonics]
        base = freqs[0]
        ratios = [Fraction(f / base).limit_denominator(MAX_DENOMINATOR) for f in freqs]
        for f, r in zip(freqs, ratios, strict=True):
            if abs(float(r) * base - f) > 1e-9 * f:
                return None
        den = np.lcm.reduce([r.denominator for r in ratios])
        nums = [int(r * den) for r in ratios]
        w0 = base / den * np.gcd.reduce(nums)
        return 2.0 * np.pi / w0

    def parametric_period(self, coefficients) -> float | None:
        """Period of A(t): the fundamental period or its half if the parametric coefficients repeat.

        ``coefficients(t)`` returns the coefficient array (k, len(t)) of the system; pitch and yaw
        enter A(t) only squared, so their period halves (docs/physics.md#base-motion).
        """
        T0 = self.fundamental_period()
        if T0 is None:
            return None
        t = np.linspace(0.0, T0, 37)
        c0, c1 = coefficients(t), coefficients(t + T0 / 2)
        scale = max(np.abs(c0).max(), 1.0)
        return T0 / 2 if np.abs(c1 - c0).max() <= 1e-12 * scale else T0


def _axis_quat(axis: int, angle: np.ndarray) -> np.ndarray:
    q = np.zeros((angle.size, 4))
    q[:, axis] = np.sin(angle / 2)
    q[:, 3] = np.cos(angle / 2)
    return q


def _qmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    ax, ay, az, aw = a.T
    bx, by, bz, bw = b.T
    return np.stack(
        [
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz,
        ],
        axis=1,
    )
