"""``amb-bag sensitivity BAG --axis amb1_y``: the measured sensitivity S_jj of a recorded injection (ISO 14839-3).

Reads /amb/injection (the controller's E and disturbed signal y_m of one axis, one message per sample), keeps the
injection from ``settle`` after its first non-zero sample to its end, and estimates S = y_m/E with H1 and coherence
(:mod:`amb_dynamics.sensitivity_estimate`).  A periodic E (a multisine of period 1/resolution) is analysed with
rectangular segments of exactly one period (every line on a bin, no leakage); anything else with Hann segments of
1/resolution s and 50 % overlap.  With a rotor config the model of the digital loop is evaluated beside it.
"""

from __future__ import annotations

import numpy as np

from amb_dynamics.errors import AmbError
from amb_dynamics.iso14839 import db, sensitivity_zone
from amb_dynamics.sensitivity_estimate import estimate_sensitivity

from . import msgdefs
from .errors import BagError
from .reader import Bag

INJECTION = "/amb/injection"
NOISE_BOUND = 4.0  # differences in random errors that noise gives over about a hundred coherent bins


def read_injection(path, axis: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t s, E m, y_m m) of ``axis`` from the bag, sorted by stamp."""
    from rclpy.serialization import deserialize_message

    bag = Bag(path)
    if INJECTION not in bag.topics:
        raise BagError(f"{path}: no {INJECTION} in the bag (record a run with a controller injection)")
    rows, axes = [], set()
    want = [f"{axis}_injection", f"{axis}_disturbed"]
    for _topic, type_name, _log, _pub, data in bag.messages([INJECTION]):
        msg = deserialize_message(data, msgdefs.message_class(type_name))
        names = list(msg.name)
        axes.add(names[0].rsplit("_", 1)[0] if names else "?")
        if names == want and len(msg.position) == 2:
            st = msg.header.stamp
            rows.append((st.sec + 1e-9 * st.nanosec, msg.position[0], msg.position[1]))
    if not rows:
        raise BagError(f"{path}: no injection on axis {axis!r} (the bag has: {', '.join(sorted(axes)) or 'none'})")
    arr = np.asarray(sorted(rows), dtype=float)
    return arr[:, 0], arr[:, 1], arr[:, 2]


def measured_sensitivity(
    t: np.ndarray, e: np.ndarray, ym: np.ndarray, resolution_hz: float = 0.5, settle_s: float = 1.0, band=None
):
    """H1 estimate of the injection record; returns (MeasuredSensitivity, notes)."""
    dt = np.diff(t)
    if dt.size < 8 or np.any(dt <= 0):
        raise BagError("injection record too short or its stamps are not increasing")
    Ts = float(np.median(dt))
    if np.max(np.abs(dt - Ts)) > 1e-6 * Ts:
        raise BagError(f"injection samples are not equally spaced (lost samples?): spacing {dt.min():g}-{dt.max():g} s")
    fs = 1.0 / Ts
    on = np.flatnonzero(e != 0.0)
    if on.size == 0:
        raise BagError("the injected signal is zero throughout")
    i0, i1 = on[0] + round(settle_s * fs), on[-1] + 1
    P = round(fs / resolution_hz)
    e_s, y_s = e[i0:i1], ym[i0:i1]
    notes = []
    periodic = e_s.size >= 2 * P and np.max(np.abs(e_s[P:] - e_s[:-P])) <= 1e-9 * np.max(np.abs(e_s))
    try:
        if periodic:
            n = (e_s.size // P) * P
            m = estimate_sensitivity(e_s[:n], y_s[:n], fs, nperseg=P, band_hz=band, window="boxcar", noverlap=0)
            notes.append(f"periodic injection (period {P / fs:g} s): rectangular one-period segments")
        else:
            m = estimate_sensitivity(e_s, y_s, fs, nperseg=P, band_hz=band)
            notes.append(f"non-periodic injection: Hann segments of {P / fs:g} s, 50 % overlap")
    except AmbError as exc:
        raise BagError(str(exc)) from None
    return m, notes


def sensitivity_report(m, notes, axis: str, limits, model_abs=None, min_coherence: float = 0.9) -> dict:
    """JSON document of a measured S_jj (and the model beside it, if given)."""
    peak = m.peak(min_coherence)
    out = {"axis": axis, **m.to_dict(), "min_coherence": min_coherence, "peak": peak, "notes": list(notes)}
    if peak["peak_abs"] is not None:
        peak["peak_db"] = db(peak["peak_abs"])
        peak["zone"] = sensitivity_zone(peak["peak_abs"], limits) if peak["resolved"] else None
        if not peak["resolved"]:
            out["notes"].append("no zone from an unresolved peak: see the calibrated model's (fitted_model)")
    if model_abs is not None:
        good = m.coherence >= min_coherence
        rel = np.abs(m.abs - model_abs) / model_abs
        out["model_abs"] = np.asarray(model_abs).tolist()
        out["coherent_bins"] = int(good.sum())
        out["max_rel_error_where_coherent"] = float(rel[good].max()) if good.any() else None
        # the same difference in units of the estimate's own random error: below about 3.5 is measurement noise
        z = rel / m.random_error
        out["max_difference_in_random_errors"] = float(z[good].max()) if good.any() else None
        if good.any() and z[good].max() > NOISE_BOUND:
            k = int(np.flatnonzero(good)[np.argmax(z[good])])
            out["notes"].append(
                f"measured and model differ by {z[k]:.1f} random errors ({100 * rel[k]:.1f} %) at "
                f"{m.frequency_hz[k]:.4g} Hz: more than noise gives; is the rig the config?"
            )
    return out


def add_fitted_model(report: dict, m, cfg, axis: str, speed_rpm: float | None = None) -> None:
    """An unresolved peak: calibrate the digital-loop model to the coherent bins (ki, ks scales) and give the zone at
    its peak (``report["fitted_model"]``; :mod:`amb_dynamics.sensitivity_fit`)."""
    from amb_dynamics.sensitivity_fit import fit_sensitivity
    from amb_dynamics.structure import build_structure

    good = m.coherence >= report["min_coherence"]
    if report["peak"]["resolved"] or good.sum() < 3:
        return
    model = build_structure(cfg)
    j = model.channels.index(axis)
    fit = fit_sensitivity(model, cfg, j, m.frequency_hz[good], m.S[good], speed_rpm=speed_rpm)
    report["fitted_model"] = fit
    if fit["good"]:
        report["notes"].append(
            f"zone {fit['zone']} at the calibrated model's peak |S| {fit['peak_abs']:.4g} at {fit['peak_hz']:.4g} Hz "
            f"(ki x{fit['ki_scale']:.4f}, ks x{fit['ks_scale']:.4f}, {100 * fit['rms_rel_residual']:.2f} % RMS "
            f"residual over {fit['bins']} coherent bins)"
        )
    else:
        report["notes"].append(fit["reason"])


def model_abs_at(cfg, axis: str, frequency_hz: np.ndarray, speed_rpm: float | None = None) -> np.ndarray:
    """|S_jj| of the model of the digital loop (the config's rate, delay and spin) at the measured frequencies."""
    from amb_dynamics.sensitivity import ModalResponse, loop_state_spaces, sensitivity_state_space
    from amb_dynamics.structure import build_structure

    model = build_structure(cfg)
    if axis not in model.channels:
        raise BagError(f"axis {axis!r} does not exist in the config (axes: {', '.join(model.channels)})")
    j = model.channels.index(axis)
    speed = cfg.spin_speed_rpm if speed_rpm is None else speed_rpm
    plant, ctrl = loop_state_spaces(model, cfg, speed, "sampled")
    S = ModalResponse.of(sensitivity_state_space(plant, ctrl))(2 * np.pi * np.asarray(frequency_hz))
    return np.abs(S[:, j, j])


def run_bag_sensitivity(args) -> int:
    """The `amb-bag sensitivity` command (errors as BagError: one line)."""
    import json

    from amb_dynamics.analysis_sensitivity import parse_band
    from amb_dynamics.config import load_config

    from .reader import Bag
    from .runconfig import recorded_config

    try:
        band = parse_band(args.band) if args.band else None
        cfg = load_config(args.config, args.set) if (args.config or args.set) else recorded_config(Bag(args.bag))
    except AmbError as exc:
        raise BagError(str(exc)) from None
    t, e, ym = read_injection(args.bag, args.axis)
    m, notes = measured_sensitivity(t, e, ym, args.resolution, args.settle, band)
    limits = cfg.iso14839.sensitivity_zone_limits if cfg else (3.0, 4.0, 5.0)
    model = model_abs_at(cfg, args.axis, m.frequency_hz) if cfg else None
    report = sensitivity_report(m, notes, args.axis, limits, model)
    if cfg:
        add_fitted_model(report, m, cfg, args.axis)
    if args.out:
        from amb_dynamics.plots_sensitivity import measured_figure

        report["png"] = str(measured_figure(report, limits, f"{args.bag}: {args.axis}", args.out))
    if args.json:
        print(json.dumps(report, indent=1))
    else:
        print(format_report(report))
    return 0


def format_report(r: dict) -> str:
    p = r["peak"]
    lines = [
        f"{r['axis']}: {len(r['frequency_hz'])} frequencies, resolution {r['resolution_hz']:g} Hz, "
        f"{r['segments']} segments; {'; '.join(r['notes'])}",
    ]
    if p["peak_abs"] is None:
        lines.append(f"no peak: {p.get('reason')}")
    else:
        zone = p.get("zone") or "-"
        lines.append(
            f"peak |S| {p['peak_abs']:.4g} ({p['peak_db']:.2f} dB) at {p['peak_hz']:.4g} Hz, zone {zone}"
            + ("" if p["resolved"] else f" (unresolved: {p.get('reason')})")
        )
    if r.get("max_rel_error_where_coherent") is not None:
        lines.append(
            f"model of the digital loop: max |S| difference {100 * r['max_rel_error_where_coherent']:.2f} % over "
            f"{r['coherent_bins']} bins with coherence >= {r['min_coherence']:g} (at most "
            f"{r['max_difference_in_random_errors']:.2g} x the estimate's random error)"
        )
    return "\n".join(lines)
