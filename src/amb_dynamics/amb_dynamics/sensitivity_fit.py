"""The zone at a peak the measurement cannot resolve: the design model calibrated to the measured S.

A lightly damped mode's peak of |S| is narrower than any affordable frequency resolution (the seed rotor's first
mode: 0.004 Hz half-power bandwidth), or lies outside the measured band.  Rather than guess, the digital-loop model
of the same operating point is calibrated to the coherent measured bins: the bearing's current gain ki and negative
stiffness ks (the two constants a commissioning engineer trusts least) are scaled by least squares on the complex
S, and the calibrated model's peak over the whole analysis band gives the zone (ISO 14839-3).  The fit reports its
scales, its residual and the peak; a poor fit (residual above ``GOOD_FIT``) is said so and gives no zone.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.optimize import least_squares

from .config import RotorConfig
from .iso14839 import sensitivity_zone
from .sensitivity import ModalResponse, find_peaks, loop_state_spaces, sensitivity_state_space
from .structure import StructuralModel

GOOD_FIT = 0.05  # RMS of |S_meas - S_model| / |S_meas| over the fitted bins
SCALE_BOUNDS = (0.5, 2.0)  # ki and ks within a factor 2 of the config's
BAND_HZ = (1.0, 500.0)  # where the calibrated model's peak is sought (below Nyquist)
GRID = 2000


def _scaled(model: StructuralModel, cfg: RotorConfig, ki_scale: float, ks_scale: float):
    b = cfg.bearings
    bearings = dataclasses.replace(
        b, current_stiffness=b.current_stiffness * ki_scale, displacement_stiffness=b.displacement_stiffness * ks_scale
    )
    gains = dataclasses.replace(model.gains, ki=model.gains.ki * ki_scale, ks=model.gains.ks * ks_scale)
    return dataclasses.replace(model, gains=gains), dataclasses.replace(cfg, bearings=bearings)


def fit_sensitivity(
    model: StructuralModel,
    cfg: RotorConfig,
    axis: int,
    frequency_hz: np.ndarray,
    S_measured: np.ndarray,
    weight: np.ndarray | None = None,
    speed_rpm: float | None = None,
) -> dict:
    """Calibrate (ki, ks) of the digital-loop model to measured S_jj of axis index ``axis`` at ``frequency_hz``.

    Returns {"ki_scale", "ks_scale", "rms_rel_residual", "good", "peak_abs", "peak_hz", "zone", "bins"}.
    """
    f = np.asarray(frequency_hz, dtype=float)
    S = np.asarray(S_measured, dtype=complex)
    w = np.ones_like(f) if weight is None else np.asarray(weight, dtype=float)
    speed = cfg.spin_speed_rpm if speed_rpm is None else speed_rpm

    def model_S(p):
        m, c = _scaled(model, cfg, *p)
        plant, ctrl = loop_state_spaces(m, c, speed, "sampled")
        return ModalResponse.of(sensitivity_state_space(plant, ctrl))(2 * np.pi * f)[:, axis, axis]

    def residual(p):
        r = w * (model_S(p) - S) / np.abs(S)
        return np.concatenate([r.real, r.imag])

    sol = least_squares(residual, x0=[1.0, 1.0], bounds=tuple(zip(SCALE_BOUNDS, SCALE_BOUNDS, strict=True)),
                        x_scale=[0.1, 0.1], xtol=1e-10)  # fmt: skip
    rms = float(np.sqrt(np.mean(np.abs((model_S(sol.x) - S) / S) ** 2)))
    out = {"ki_scale": float(sol.x[0]), "ks_scale": float(sol.x[1]), "rms_rel_residual": rms,
           "good": rms <= GOOD_FIT, "bins": int(f.size)}  # fmt: skip
    m, c = _scaled(model, cfg, *sol.x)
    plant, ctrl = loop_state_spaces(m, c, speed, "sampled")
    hi = min(BAND_HZ[1], 0.45 * cfg.controller.rate_hz)
    wg = 2 * np.pi * np.geomspace(BAND_HZ[0], hi, GRID)
    Sg = ModalResponse.of(sensitivity_state_space(plant, ctrl))(wg)
    peak = find_peaks(plant, ctrl, wg, Sg, (wg[0], wg[-1]))[axis]
    stable = bool(np.abs(np.linalg.eigvals(sensitivity_state_space(plant, ctrl).A)).max() < 1.0)
    zone = sensitivity_zone(peak.abs, cfg.iso14839.sensitivity_zone_limits) if stable else "unstable"
    out.update(peak_abs=peak.abs, peak_db=peak.db, peak_hz=peak.hz, zone=zone if out["good"] else None)
    if not out["good"]:
        out["reason"] = f"the calibrated model misses the measurement by {100 * rms:.1f} % RMS: no zone from it"
    return out
