"""The period of the base motion from measured angular velocity (the monitor's /base/imu), for the estimator.

The dominant component of Omega(t) is cut at its mean; the up-crossings (linearly interpolated) give a
candidate period, which is accepted as the fundamental period T0 once the whole vector Omega(t) repeats
after it (k up-crossings per period are tried for combined motions).  The period T of A(t) and the forcing
model follow docs/physics.md#base-motion: with no roll rate (Omega_x = 0) and a half-wave antisymmetric Omega
(Omega(t + T0/2) = -Omega(t), pitch or yaw) A(t) repeats after T0/2 and f(t + T0/2) = -f(t) ('alternating');
otherwise T = T0, with no forcing for a pure roll and a general periodic forcing else.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError

REPEAT_TOL = 1e-3  # relative RMS mismatch for "Omega repeats after this lag"
ZERO_RATE = 1e-9  # components below this fraction of the largest are zero (no roll, pure roll)
MAX_CROSSINGS_PER_PERIOD = 8
SNAP_TOL = 1e-3  # samples: a period this close to a whole number of samples is snapped to it


@dataclass(frozen=True)
class PeriodEstimate:
    """base_period T0 (s), period T of A(t) (s), forcing model for the estimator, whether T was snapped."""

    base_period: float
    period: float
    forcing: str
    snapped: bool = False

    def to_dict(self) -> dict:
        return {
            "base_period_s": self.base_period,
            "period_s": self.period,
            "forcing": self.forcing,
            "snapped_to_samples": self.snapped,
        }


def _upcrossings(t: np.ndarray, x: np.ndarray) -> np.ndarray:
    i = np.nonzero((x[:-1] < 0.0) & (x[1:] >= 0.0))[0]
    return t[i] - x[i] * (t[i + 1] - t[i]) / (x[i + 1] - x[i])


def _repeat_error(t: np.ndarray, W: np.ndarray, lag: float, sign: float = 1.0) -> float:
    """RMS of Omega(t + lag) - sign * Omega(t) over the record, relative to the RMS of Omega."""
    sel = t + lag <= t[-1]
    if np.count_nonzero(sel) < 8:
        return np.inf
    shifted = np.column_stack([np.interp(t[sel] + lag, t, W[:, c]) for c in range(3)])
    err = np.sqrt(np.mean(np.square(shifted - sign * W[sel])))
    return float(err / max(np.sqrt(np.mean(np.square(W))), 1e-300))


def _interpolation_error(W: np.ndarray) -> float:
    """RMS error of linear interpolation between the samples, relative to the RMS of Omega: |second difference| / 8
    per sample.  Sparse or irregular base rates (a realtime run's /base/imu, wall-clock stamps) interpolate less
    exactly than the lockstep 1 kHz ones, and the repeat test must not take that for a motion that does not repeat."""
    if W.shape[0] < 3:
        return 0.0
    d2 = W[2:] - 2.0 * W[1:-1] + W[:-2]
    return float(np.sqrt(np.mean(np.square(d2))) / 8.0 / max(np.sqrt(np.mean(np.square(W))), 1e-300))


def estimate_base_period(t: np.ndarray, Omega: np.ndarray, sample_time: float | None = None) -> PeriodEstimate:
    """Fundamental period and period of A(t) from angular-velocity samples.

    Parameters
    ----------
    t : np.ndarray, shape (K,)
        Sample times (s), increasing.
    Omega : np.ndarray, shape (K, 3)
        Base angular velocity in base axes (rad/s).
    sample_time : float, optional
        Ts (s) of the state samples: T is snapped to a whole number of samples when within ``SNAP_TOL``.
    """
    t = np.asarray(t, dtype=float)
    W = np.asarray(Omega, dtype=float)
    if W.ndim != 2 or W.shape[1] != 3 or W.shape[0] != t.shape[0]:
        raise InputError(f"angular velocity must have shape ({t.shape[0]}, 3), got {W.shape}")
    if t.shape[0] < 16 or not (np.isfinite(t).all() and np.isfinite(W).all()) or np.any(np.diff(t) <= 0):
        raise InputError("base-rate record too short, not finite or not increasing in time")
    peak = np.abs(W).max(axis=0)
    if peak.max() == 0.0:
        raise InputError("the base does not rotate: no base period (set the period parameter)")
    c = int(np.argmax(np.sqrt(np.mean(np.square(W - W.mean(axis=0)), axis=0))))
    up = _upcrossings(t, W[:, c] - W[:, c].mean())
    if up.size < 3:
        raise InputError("fewer than two base-motion periods recorded: cannot estimate the period yet")
    tol = REPEAT_TOL + 2.0 * _interpolation_error(W)
    base = None
    for k in range(1, min(MAX_CROSSINGS_PER_PERIOD, up.size - 1) + 1):
        lag = float(np.median(up[k:] - up[:-k]))
        if _repeat_error(t, W, lag) < tol:
            m = (up.size - 1) // k  # average over as many whole periods as recorded
            base = float((up[m * k] - up[0]) / m)
            break
    if base is None:
        raise InputError("the base motion does not repeat within the record: no periodic Floquet analysis")
    no_roll = peak[0] <= ZERO_RATE * peak.max()
    pure_roll = peak[1] <= ZERO_RATE * peak.max() and peak[2] <= ZERO_RATE * peak.max()
    if no_roll and _repeat_error(t, W, base / 2.0, sign=-1.0) < tol:
        period, forcing = base / 2.0, "alternating"
    else:
        period, forcing = base, ("none" if pure_roll else "constant")
    snapped = False
    if sample_time is not None:
        n = period / sample_time
        if abs(n - round(n)) < SNAP_TOL and round(n) >= 2:
            base *= round(n) / n
            period, snapped = round(n) * sample_time, True
    return PeriodEstimate(base, period, forcing, snapped)
