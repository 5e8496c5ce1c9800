"""Per-step cost of the plant's stepping code (rig_plant.RigPlant via rig_loop.simulate_rig, controller included)
for the paper config and the real-rig default, base at rest and on the default pitching base, side by side; and
the cost of a step while the rotor is on its touchdown bearings (sub-stepped contact), at 5 and 2 kHz.

The lockstep loop is bound by its DDS hops (~400 us per step here); the plant's computation adds to that only
where it does not overlap the controller's (the step's matrices are prepared while the controller computes).
A realtime loop must step within its period: in contact too, or a rotor that drops cannot be caught again.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
from report import record, record_ratio

from amb_dynamics.config import load_config
from amb_dynamics.motion import BaseMotion
from amb_dynamics.rig_loop import levitated_state, simulate_rig
from amb_dynamics.rig_plant import RigPlant
from amb_dynamics.structure import build_structure

CONFIG = Path(__file__).resolve().parents[1] / "config"
PAPER = CONFIG / "seed_paper.yaml"
STEPS = 1000
REPEATS = 3
DROP_S = 0.08  # zero current from the levitated state: the rotor is on its backup bearings after this
CONTACT_STEPS = 200


def per_step(path, moving: bool) -> float:
    cfg = load_config(path)
    model = build_structure(cfg)
    motion = BaseMotion.from_config(cfg.base_motion) if moving else BaseMotion()
    simulate_rig(model, cfg, motion, 5)  # warm-up
    t0 = time.perf_counter()
    simulate_rig(model, cfg, motion, STEPS)
    return (time.perf_counter() - t0) / STEPS


def contact_step(path: Path) -> tuple[float, int]:
    """(s per step, sub-steps per step) of RigPlant.step with the rotor dropped onto its touchdown bearings."""
    cfg = load_config(path)
    model = build_structure(cfg)
    plant = RigPlant(model, cfg, 1.0 / cfg.controller.rate_hz)
    x, zero, off = levitated_state(plant, cfg), np.zeros(3), np.zeros(4)
    for _ in range(round(DROP_S * cfg.controller.rate_hz)):
        x = plant.step(x, off, zero, zero)
    if not plant.contact.events or not plant.forces.near(x, plant.Ts):
        raise RuntimeError(f"{path.name}: the dropped rotor is not on its touchdown bearings")
    t0 = time.perf_counter()
    for _ in range(CONTACT_STEPS):
        x = plant.step(x, off, zero, zero)
    return (time.perf_counter() - t0) / CONTACT_STEPS, plant.forces.substeps


def main() -> dict:
    out = {}
    for name, path in (("paper", PAPER), ("real_rig", None)):
        for moving in (False, True):
            key = f"{name}_{'pitching' if moving else 'at_rest'}_us_per_step"
            out[key] = [per_step(path, moving) * 1e6 for _ in range(REPEATS)]
            print(f"{key}: {np.median(out[key]):.0f}", flush=True)
    for base in ("at_rest", "pitching"):
        paper, rig = out[f"paper_{base}_us_per_step"], out[f"real_rig_{base}_us_per_step"]
        label = "base at rest" if base == "at_rest" else "default pitching base"
        record(f"offline plant + controller step, paper config, {label}", paper, "us")
        record(f"offline plant + controller step, real-rig default, {label}", rig, "us")
        record_ratio(f"  steps/s real rig / paper, {label}", paper, rig)
    for path in (CONFIG / "seed_rotor.yaml", CONFIG / "seed_rotor_2khz_lqg.yaml"):
        runs = [contact_step(path) for _ in range(REPEATS)]
        us = [1e6 * s for s, _ in runs]
        rate = load_config(path).controller.rate_hz
        out[f"contact_{path.stem}_us_per_step"] = us
        print(f"{path.stem}: {np.median(us):.0f} us per step in contact ({runs[0][1]} sub-steps)", flush=True)
        record(f"plant step on the touchdown bearings, {path.name} ({runs[0][1]} sub-steps)", us, "us",
               goal=f"< {1e6 / rate:.0f} (the period) for realtime")  # fmt: skip
    return out


if __name__ == "__main__":
    main()
