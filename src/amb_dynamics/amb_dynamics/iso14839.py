"""ISO 14839 evaluation zones: stability margin (part 3, peak sensitivity) and shaft vibration (part 2, vs C_min).

Both grade a number against three ascending boundaries [A/B, B/C, C/D]: a value on a boundary belongs to the
zone below it.  The boundaries are config keys (``iso14839``); their defaults are the commonly cited values
(docs/commissioning.md says where they come from and what could not be confirmed).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import InputError

ZONES = ("A", "B", "C", "D")


def zone_of(value: float, limits) -> str:
    """Zone A-D of ``value`` against ascending boundaries ``limits`` = [A/B, B/C, C/D]."""
    limits = [float(x) for x in limits]
    if len(limits) != 3 or any(np.diff(limits) <= 0):
        raise InputError(f"zone limits must be three ascending numbers [A/B, B/C, C/D] (got {limits})")
    if not np.isfinite(value):
        raise InputError(f"cannot grade a non-finite value ({value})")
    for name, limit in zip(ZONES, limits, strict=False):
        if value <= limit:
            return name
    return "D"


def sensitivity_zone(peak_abs: float, limits_abs) -> str:
    """ISO 14839-3 zone of a peak |S| (absolute, not dB)."""
    return zone_of(peak_abs, limits_abs)


def db(x: float) -> float:
    """20 log10 x (dB)."""
    return float(20.0 * np.log10(x))


@dataclass(frozen=True)
class VibrationZone:
    """ISO 14839-2 grade of one axis: displacement (m) and its ratio to C_min, or why there is none."""

    axis: str
    displacement_m: float
    measure: str  # zero_peak | peak_to_peak
    ratio: float | None
    zone: str | None
    reason: str | None = None

    def to_dict(self) -> dict:
        return {
            "displacement_m": self.displacement_m,
            "measure": self.measure,
            "ratio_to_c_min": self.ratio,
            "zone": self.zone,
            **({"reason": self.reason} if self.reason else {}),
        }


def displacement_measure(y: np.ndarray, measure: str) -> float:
    """Zero-to-peak (max |y|, from the bearing centre) or peak-to-peak (max y - min y) of samples y (m)."""
    y = np.asarray(y, dtype=float)
    if y.size == 0 or not np.all(np.isfinite(y)):
        raise InputError("vibration zone: the displacement samples are empty or not finite")
    if measure == "zero_peak":
        return float(np.abs(y).max())
    if measure == "peak_to_peak":
        return float(y.max() - y.min())
    raise InputError(f"vibration measure must be zero_peak or peak_to_peak (got {measure!r})")


def vibration_zones(
    displacements: dict[str, np.ndarray],
    c_min: float | None,
    limits_ratio,
    measure: str = "zero_peak",
) -> dict[str, VibrationZone]:
    """ISO 14839-2 zone per axis: the displacement measure of each axis's samples (m) against limits x C_min.

    With ``c_min`` None there is no zone, and each entry says why in one line.
    """
    return {axis: _zone(axis, displacement_measure(y, measure), measure, c_min, limits_ratio)
            for axis, y in displacements.items()}  # fmt: skip


def _zone(axis: str, d: float, measure: str, c_min: float | None, limits) -> VibrationZone:
    if c_min is None:
        return VibrationZone(axis, d, measure, None, None, "no zone: iso14839.touchdown_clearance (C_min) is not set")
    if not c_min > 0:
        raise InputError(f"iso14839.touchdown_clearance must be > 0 m (got {c_min})")
    return VibrationZone(axis, d, measure, d / c_min, zone_of(d / c_min, limits))


def clearance_of(cfg) -> float | None:
    """C_min of a rotor config: ``iso14839.touchdown_clearance``, else the touchdown bearings' clearance, else
    None (no vibration zone)."""
    if cfg.iso14839.touchdown_clearance is not None:
        return float(cfg.iso14839.touchdown_clearance)
    return float(cfg.touchdown.clearance) if cfg.touchdown.clearance is not None else None


class TrailingPeaks:
    """Vibration of a sample stream over the trailing ``window_s``: per channel the largest and smallest value of
    the last completed blocks and the current one (block = window / ``blocks``), so the end of a run is graded
    without its start-up transient.  ``values()`` gives (zero_peak, peak_to_peak) per channel (m)."""

    def __init__(self, channels: int, Ts: float, window_s: float = 1.0, blocks: int = 4):
        if not (Ts > 0 and window_s > 0 and blocks >= 1):
            raise InputError("trailing peaks: Ts and window_s must be > 0 and blocks >= 1")
        self.block = max(1, round(window_s / blocks / Ts))
        self.hi = np.full((blocks + 1, channels), -np.inf)
        self.lo = np.full((blocks + 1, channels), np.inf)
        self.n = 0

    def add(self, y: np.ndarray) -> None:
        row = (self.n // self.block) % self.hi.shape[0]
        if self.n % self.block == 0:  # a new block replaces the oldest
            self.hi[row], self.lo[row] = -np.inf, np.inf
        np.maximum(self.hi[row], y, out=self.hi[row])
        np.minimum(self.lo[row], y, out=self.lo[row])
        self.n += 1

    def values(self) -> tuple[np.ndarray, np.ndarray]:
        hi, lo = self.hi.max(axis=0), self.lo.min(axis=0)
        if self.n == 0:
            return np.zeros_like(hi), np.zeros_like(hi)
        return np.maximum(np.abs(hi), np.abs(lo)), hi - lo

    @property
    def covered(self) -> int:
        """Samples the values cover (the whole stream while it is shorter than the window)."""
        # the completed blocks kept beside the current one, which is full at a block boundary
        return min(self.n, (self.hi.shape[0] - 1) * self.block + (self.n % self.block or self.block))

    def zones(self, channels, c_min: float | None, limits, measure: str = "zero_peak") -> dict[str, VibrationZone]:
        """ISO 14839-2 zone per channel of the trailing window (see :func:`vibration_zones`)."""
        if measure not in ("zero_peak", "peak_to_peak"):
            raise InputError(f"vibration measure must be zero_peak or peak_to_peak (got {measure!r})")
        zero_peak, p2p = self.values()
        d = zero_peak if measure == "zero_peak" else p2p
        return {ch: _zone(ch, float(v), measure, c_min, limits) for ch, v in zip(channels, d, strict=True)}
