"""What the plant reports about the rotor's motion: displacement peaks, the ISO 14839-2 grade of the end of the
run, and the touchdown contacts (diagnostics values and /amb_plant/touchdown events)."""

from __future__ import annotations

import json

import numpy as np

from amb_dynamics.iso14839 import TrailingPeaks, clearance_of
from amb_ros.diag_keys import Plant, peak_values, vibration_values


class DisplacementReport:
    """Peak |y| per channel over the whole run, and the trailing second's vibration against C_min."""

    def __init__(self, channels: tuple[str, ...], cfg, Ts: float):
        self.channels, self.Ts = channels, Ts
        self.air_gap = cfg.bearings.air_gap
        self.peak = np.zeros(len(channels))
        self.trailing = TrailingPeaks(len(channels), Ts)  # the end of the run, without its start
        self.c_min = clearance_of(cfg)
        self.iso = cfg.iso14839

    def add(self, y: np.ndarray) -> None:
        np.maximum(self.peak, np.abs(y), out=self.peak)
        self.trailing.add(y)

    def values(self) -> dict[str, str]:
        iso = self.iso
        zones = self.trailing.zones(self.channels, self.c_min, iso.vibration_zone_limits, iso.vibration_measure)
        out = peak_values(self.channels, self.peak, self.air_gap)
        out.update(vibration_values(self.trailing.covered * self.Ts, zones))
        return out


def contact_json(ev) -> str:
    """A touchdown event as one JSON object (t_s, node, penetration_m, peak_force_n; end_s once it ended)."""
    t0, node, pen, force, t1 = ev
    return json.dumps({"t_s": t0, "node": node, "penetration_m": pen, "peak_force_n": force, "end_s": t1})


def contact_summary(events) -> dict[str, str]:
    """Diagnostics values of the touchdown contacts (shown in the run summary)."""
    if not events:
        return {Plant.touchdown_contacts.text: "0"}
    first = events[0]
    worst = max(events, key=lambda ev: ev[2])
    return {
        Plant.touchdown_contacts.text: str(len(events)),
        "first touchdown": f"t = {first[0]:.6g} s at node {first[1]}",
        "max penetration (m)": f"{worst[2]:.6g} (node {worst[1]}, t = {worst[0]:.6g} s)",
        "peak contact force (N)": f"{max(ev[3] for ev in events):.6g}",
    }
