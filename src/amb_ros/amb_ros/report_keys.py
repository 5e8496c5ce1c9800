"""The plant's displacement report on /diagnostics: its key strings, written and read in one place.

The plant (amb_plant/report.py) writes them; amb-rig's summary and `amb-bag info` read them back.  Keys per AMB
channel c: ``peak c (m)``, ``peak c / air gap`` (the whole run), ``vibration c (m)`` and ``vibration zone c``
(ISO 14839-2 grade of the run's last second against C_min), and ``vibration window (s)``.
"""

from __future__ import annotations

VIBRATION_WINDOW = "vibration window (s)"


def peak_values(channels, peaks, air_gap: float) -> dict[str, str]:
    out = {}
    for name, peak in zip(channels, peaks, strict=True):
        out[f"peak {name} (m)"] = f"{peak:.6g}"
        out[f"peak {name} / air gap"] = f"{peak / air_gap:.6g}"
    return out


def vibration_values(window_s: float, zones: dict) -> dict[str, str]:
    """``zones``: channel -> object with ``displacement_m`` and ``zone`` (None: no zone)."""
    out = {VIBRATION_WINDOW: f"{window_s:.6g}"}
    for name, z in zones.items():
        out[f"vibration {name} (m)"] = f"{z.displacement_m:.6g}"
        out[f"vibration zone {name}"] = z.zone or "-"
    return out


def _num(values: dict, key: str):
    try:
        return float(values[key])
    except (KeyError, ValueError):
        return None


def _channels(values: dict, prefix: str, suffix: str) -> list[str]:
    return [k[len(prefix) : -len(suffix)] for k in values if k.startswith(prefix) and k.endswith(suffix)]


def read_peaks(values: dict) -> dict[str, dict]:
    """channel -> {"m", "air_gap_ratio"} from a plant report's values."""
    return {c: {"m": _num(values, f"peak {c} (m)"), "air_gap_ratio": _num(values, f"peak {c} / air gap")}
            for c in _channels(values, "peak ", " (m)")}  # fmt: skip


def read_vibration(values: dict) -> dict | None:
    """{"window_s", "axes": channel -> {"m", "zone"}} from a plant report's values; None if it has none."""
    if VIBRATION_WINDOW not in values:
        return None
    axes = {c: {"m": _num(values, f"vibration {c} (m)"), "zone": values.get(f"vibration zone {c}", "-")}
            for c in _channels(values, "vibration ", " (m)")}  # fmt: skip
    return {"window_s": _num(values, VIBRATION_WINDOW), "axes": axes}
