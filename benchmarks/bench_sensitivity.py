"""Model sensitivity speed: S_jj of the four AMB axes at 2,000 frequencies with refined peaks (goal < 1 s), for the
continuous and the digital loop, and against a plain batched solve of (I - P K)^-1 at the same frequencies; and the
wall time of one measured axis (`amb-rig sensitivity`, lockstep, seed rotor at 5 kHz) for a stated resolution."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from report import record

from amb_dynamics.config import load_config
from amb_dynamics.sensitivity import find_peaks, loop_state_spaces, sensitivity_matrix
from amb_dynamics.structure import build_structure

REPEATS = 5


def _times(fn) -> list[float]:
    times = []
    for _ in range(REPEATS):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return times


def main() -> dict:
    cfg = load_config()
    model = build_structure(cfg)
    w = 2 * np.pi * np.geomspace(1.0, 500.0, 2000)
    out = {}
    for controller in ("continuous", "sampled"):
        plant, ctrl = loop_state_spaces(model, cfg, 1000.0, controller)

        def full(plant=plant, ctrl=ctrl):
            S = sensitivity_matrix(plant, ctrl, w)
            find_peaks(plant, ctrl, w, S, (w[0], w[-1]))

        def direct(plant=plant, ctrl=ctrl):
            P, K = plant.freqresp(w), ctrl.freqresp(w)
            np.linalg.inv(np.eye(4) - P @ K)

        full_s, direct_s = _times(full), _times(direct)
        t_full, t_direct = min(full_s), min(direct_s)
        out[controller] = {"seconds_2000_freqs_with_peaks": t_full, "seconds_direct_solve_no_peaks": t_direct}
        record(f"model sensitivity, 4 axes, 2,000 frequencies with refined peaks ({controller} loop, 1000 rpm)",
               full_s, "s", goal="< 1")  # fmt: skip
        record(f"  the same grid by a plain batched solve of (I - P K)^-1, no peaks ({controller})", direct_s, "s")
        print(
            f"sensitivity ({controller}): 2,000 frequencies + refined peaks {t_full:.3f} s (goal < 1 s); "
            f"plain batched solve of the same grid without peaks {t_direct:.3f} s"
        )
    out["measured_axis"] = measured_axis()
    return out


def measured_axis(resolution_hz: float = 0.5, periods: int = 6) -> dict:
    """Wall time of `amb-rig sensitivity` on amb1_y: a multisine of ``periods`` periods at ``resolution_hz``."""
    duration = periods / resolution_hz
    cmd = [str(Path(sys.executable).parent / "amb-rig"), "sensitivity", "--axis", "amb1_y", "--band", "5:50",
           "--duration", str(duration), "--resolution", str(resolution_hz), "--settle", str(1 / resolution_hz),
           "--json"]  # fmt: skip
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=1800)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        errors = [ln.strip() for ln in proc.stderr.splitlines() if "error" in ln.lower()]
        raise RuntimeError(f"amb-rig sensitivity failed: {errors[-3:] or proc.stderr.strip().splitlines()[-1:]}")
    r = json.loads(proc.stdout)
    record(f"measured sensitivity, one axis, {resolution_hz:g} Hz resolution ({duration:g} s simulated, lockstep, "
           f"5 kHz; {r['coherent_bins']} coherent lines), wall time with start-up", wall, "s")  # fmt: skip
    record("  its largest difference from the model where coherent", 100 * r["max_rel_error_where_coherent"], "%")
    record("  the same in units of each bin's random error (coherence, segments)", r["max_difference_in_random_errors"],
           "", goal="< 4 (noise)")  # fmt: skip
    res = {
        "resolution_hz": r["resolution_hz"],
        "simulated_s": duration,
        "wall_s": wall,
        "coherent_bins": r["coherent_bins"],
        "max_rel_error_where_coherent": r["max_rel_error_where_coherent"],
    }
    print(
        f"measured sensitivity, one axis (lockstep, 5 kHz, {resolution_hz:g} Hz resolution, {duration:g} s simulated): "
        f"{wall:.1f} s wall including start-up; {res['coherent_bins']} coherent lines, model difference "
        f"{100 * res['max_rel_error_where_coherent']:.2f} %"
    )
    return res


if __name__ == "__main__":
    main()
