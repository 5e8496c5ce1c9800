"""``amb-dynamics sensitivity``: model sensitivity S_jj per AMB axis with its ISO 14839-3 zone, per spin speed."""

from __future__ import annotations

import time

import numpy as np

from .config import load_config
from .control_law import describe
from .errors import InputError
from .iso14839 import db, sensitivity_zone
from .sensitivity import ModalResponse, find_peaks, loop_state_spaces, sensitivity_state_space
from .structure import build_structure

SCHEMA_VERSION = 1


def parse_band(text: str) -> tuple[float, float]:
    """'lo:hi' (Hz) -> (lo, hi) with 0 < lo < hi; InputError (one line) otherwise."""
    try:
        lo, hi = (float(v) for v in text.split(":"))
    except ValueError:
        raise InputError(f"--band {text!r}: expected lo:hi in Hz, e.g. 1:500") from None
    if not (np.isfinite(lo) and np.isfinite(hi)) or lo <= 0 or hi <= lo:
        raise InputError(f"--band {text!r} is empty: need 0 < lo < hi (Hz)")
    return lo, hi


def frequency_grid(lo_hz: float, hi_hz: float, points: int) -> np.ndarray:
    """Log-spaced grid (Hz)."""
    if points < 2:
        raise InputError(f"--points must be >= 2 (got {points})")
    return np.geomspace(lo_hz, hi_hz, points)


def model_sensitivity(model, cfg, speed_rpm: float, controller: str, band_hz, points: int, axes=None) -> dict:
    """S_jj of every (or the selected) AMB axis at one speed: grid (with each refined peak inserted) and peaks."""
    plant, ctrl = loop_state_spaces(model, cfg, speed_rpm, controller)
    resp = ModalResponse.of(sensitivity_state_space(plant, ctrl))
    stable, margin = loop_stability(resp.poles, plant.dt)
    f = frequency_grid(*band_hz, points)
    w = 2 * np.pi * f
    S = resp(w)
    peaks = find_peaks(plant, ctrl, w, S, (w[0], w[-1]))
    f_all = np.unique(np.concatenate([f, [p.hz for p in peaks]]))
    S_all = resp(2 * np.pi * f_all)
    limits = cfg.iso14839.sensitivity_zone_limits
    names = list(model.channels)
    out_axes, out_abs = {}, {}
    for j, name in enumerate(names):
        if axes and name not in axes:
            continue
        p = peaks[j]
        out_axes[name] = {
            "peak_abs": p.abs,
            "peak_db": p.db,
            "peak_hz": p.hz,
            "zone": sensitivity_zone(p.abs, limits) if stable else "unstable",
        }
        out_abs[name] = np.abs(S_all[:, j, j]).tolist()
    return {
        "speed_rpm": float(speed_rpm),
        "closed_loop": {"stable": stable, **margin},
        "axes": out_axes,
        "frequency_hz": f_all.tolist(),
        "abs": out_abs,
    }


def loop_stability(poles: np.ndarray, dt: float | None) -> tuple[bool, dict]:
    """Is the closed loop stable (every pole in the left half-plane, or inside the unit circle)?  S is a
    stability margin only then: ISO 14839-3 zones assume a stable loop."""
    if dt is None:
        worst = float(poles.real.max(initial=-np.inf))
        return worst < 0.0, {"max_real_per_s": worst}
    worst = float(np.abs(poles).max(initial=0.0))
    return worst < 1.0, {"spectral_radius": worst}


def run_sensitivity(args):
    t0 = time.perf_counter()
    cfg = load_config(args.config, list(args.overrides))
    model = build_structure(cfg)
    band = parse_band(args.band)
    names = list(model.channels)
    for ax in args.axis or []:
        if ax not in names:
            raise InputError(f"--axis {ax!r} does not exist (axes: {', '.join(names)})")
    if args.controller == "sampled":
        nyquist = cfg.controller.rate_hz / 2
        if band[1] >= nyquist:
            raise InputError(
                f"--band upper {band[1]:g} Hz must be below the Nyquist frequency {nyquist:g} Hz of the "
                f"{cfg.controller.rate_hz:g} Hz digital loop"
            )
    speeds = [model_sensitivity(model, cfg, v, args.controller, band, args.points, args.axis) for v in args.speed_rpm]
    limits = list(cfg.iso14839.sensitivity_zone_limits)
    data = {
        "schema_version": SCHEMA_VERSION,
        "config": str(cfg.source),
        "controller": args.controller,
        "band_hz": list(band),
        "zone_limits_abs": limits,
        "zone_limits_db": [db(x) for x in limits],
        "speeds": speeds,
    }
    if args.controller == "sampled":
        data.update(controller_rate_hz=cfg.controller.rate_hz, delay_samples=cfg.controller.delay_samples)
    lines = [f"{cfg.source}: sensitivity S_jj, {args.controller} controller, {band[0]:g}-{band[1]:g} Hz"]
    lines.append(f"controller: {describe(cfg)}")
    data["controller_law"] = describe(cfg)
    lines.append("speed (rpm)  axis       peak |S|   peak (dB)   at (Hz)     zone")
    for s in speeds:
        for name, a in s["axes"].items():
            lines.append(
                f"{s['speed_rpm']:11g}  {name:9s} {a['peak_abs']:9.4g}   {a['peak_db']:8.2f}   "
                f"{a['peak_hz']:10.5g}   {a['zone']}"
            )
    for s in speeds:
        if not s["closed_loop"]["stable"]:
            lines.append(
                f"closed loop UNSTABLE at {s['speed_rpm']:g} rpm ({_margin_text(s['closed_loop'])}): its S is no "
                "stability margin, and no zone is given"
            )
    lines.append("zone limits |S| (A/B, B/C, C/D): " + ", ".join(f"{x:g} ({db(x):.1f} dB)" for x in limits))
    if args.out:
        from .plots_sensitivity import sensitivity_figure

        png = sensitivity_figure(speeds, limits, f"{cfg.source}: {args.controller} controller", args.out)
        data["png"] = str(png)
        lines.append(f"PNG: {png}")
    data["seconds"] = time.perf_counter() - t0
    return data, "\n".join(lines)


def _margin_text(loop: dict) -> str:
    if "spectral_radius" in loop:
        return f"spectral radius {loop['spectral_radius']:.6g} >= 1"
    return f"pole with real part {loop['max_real_per_s']:.4g} 1/s"
