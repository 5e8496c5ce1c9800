"""The /diagnostics schema: every key that one part writes and another reads back, typed, in one place.

The nodes write their reports with these keys (``values[Plant.steps.text] = ...``); amb-rig's summary and verdict,
``amb-bag info`` and the tests read them back with ``Key.read`` (a typed value, or None when the key is absent
or not a number).  Values on the wire stay strings, as diagnostic_msgs/KeyValue requires; units are in the key,
in parentheses, as diagnostic_updater's are.  Keys a node writes only for display (compute-time percentiles,
scheduling, ...) are not listed: nothing reads them.  tests/test_diag_keys.py checks, on real runs, that every
key listed here as always written is in its node's final report.

Per-channel keys of the plant (peaks, ISO 14839-2 vibration zones) are templates: ``peak_values`` and
``vibration_values`` write them, ``read_peaks`` and ``read_vibration`` read them.
"""

from __future__ import annotations

from dataclasses import dataclass

LOCKSTEP, REALTIME = "lockstep", "realtime"
BOTH = (LOCKSTEP, REALTIME)


@dataclass(frozen=True)
class Key:
    """One /diagnostics key: its text, the Python type of its value, and the run modes whose final report
    always carries it (empty: written only in some states, such as the monitor's rho before it has a fit)."""

    text: str
    kind: type = float
    always: tuple[str, ...] = BOTH

    def read(self, values: dict):
        """The typed value in ``values`` (a report's key -> string), or None if absent or malformed."""
        raw = values.get(self.text)
        if raw is None:
            return None
        if self.kind is bool:
            return {"true": True, "false": False}.get(raw)
        if self.kind is str:
            return raw
        try:
            number = float(raw)
        except ValueError:
            return None
        return int(number) if self.kind is int and number.is_integer() else number


def keys_of(schema: type) -> list[Key]:
    """The keys of one node's schema class."""
    return [v for v in vars(schema).values() if isinstance(v, Key)]


class Common:
    """Every node's."""

    final = Key("final", bool)


class Plant:
    steps = Key("steps", int)
    simulated_time = Key("simulated time (s)")
    wall_time = Key("wall time (s)")
    steps_per_second = Key("steps per second")
    air_gap = Key("air gap (m)")
    saturated_steps = Key("saturated steps", int)
    touchdown_contacts = Key("touchdown contacts", int)
    duplicate_commands = Key("duplicate commands", int, (LOCKSTEP,))
    late_commands_held = Key("late commands held (samples)", int, (REALTIME,))
    zero_current = Key("zero current (samples)", int, (REALTIME,))
    command_losses = Key("command losses", int, (REALTIME,))
    command_deadline = Key("command deadline (us)", float, (REALTIME,))  # after its sample: (delay_samples + 1) Ts
    round_trip_p50 = Key("round trip p50 (us)", float, ())  # sample to its command back at the plant (realtime)
    round_trip_p99 = Key("round trip p99 (us)", float, ())
    round_trip_max = Key("round trip max (us)", float, ())


class Controller:
    samples_answered = Key("samples answered", int)
    samples_lost = Key("samples lost", int)
    samples_out_of_window = Key("samples out of window", int)
    saturated_samples = Key("saturated samples", int)
    max_current = Key("max current (A)")
    sensor_losses = Key("sensor losses", int)
    ticks = Key("ticks", int, (REALTIME,))
    missed_deadlines = Key("missed deadlines", int, (REALTIME,))
    skipped_ticks = Key("skipped ticks", int, (REALTIME,))


class Monitor:
    unstable = Key("unstable", bool)
    samples_lost = Key("samples lost", int)
    samples = Key("samples", int)
    verdict = Key("verdict", str, ())
    rho = Key("rho", float, ())
    rho_std = Key("rho std", float, ())
    rho_scatter = Key("rho scatter", float, ())
    periods_used = Key("periods used", int, ())
    period = Key("period (s)", float, ())
    flag_raised_at = Key("flag raised at (s)", float, ())
    model_rho = Key("model rho", float, ())
    model_mismatch = Key("model mismatch", bool, ())


def per_topic(what: str, topic: str) -> Key:
    """``<what> <topic>`` counts of the common accounting (published, received, rejected, foreign) and of the
    publisher matches (``publishers matched``, ``foreign publishers``; ``publishers seen`` is a str)."""
    return Key(f"{what} {topic}", str if what == "publishers seen" else int, ())


def topics_with(values: dict, what: str) -> list[str]:
    """The topics that have a ``<what> <topic>`` key in ``values``."""
    prefix = what + " "
    return [k[len(prefix) :] for k in values if k.startswith(prefix)]


# -- the plant's per-channel keys --------------------------------------------------------------------------
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
