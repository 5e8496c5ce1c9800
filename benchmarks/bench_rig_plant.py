"""Per-step cost of the plant's stepping code (rig_plant.RigPlant via rig_loop.simulate_rig, controller included)
for the paper config and the real-rig default, base at rest and on the default pitching base, side by side.

The lockstep loop is bound by its DDS hops (~400 us per step here); the plant's computation adds to that only
where it does not overlap the controller's (the step's matrices are prepared while the controller computes).
"""

from __future__ import annotations

import time
from pathlib import Path

from amb_dynamics.config import load_config
from amb_dynamics.motion import BaseMotion
from amb_dynamics.rig_loop import simulate_rig
from amb_dynamics.structure import build_structure

PAPER = Path(__file__).resolve().parents[1] / "config" / "seed_paper.yaml"
STEPS = 1000


def per_step(path, moving: bool) -> float:
    cfg = load_config(path)
    model = build_structure(cfg)
    motion = BaseMotion.from_config(cfg.base_motion) if moving else BaseMotion()
    simulate_rig(model, cfg, motion, 5)  # warm-up
    t0 = time.perf_counter()
    simulate_rig(model, cfg, motion, STEPS)
    return (time.perf_counter() - t0) / STEPS


def main() -> dict:
    out = {}
    for name, path in (("paper", PAPER), ("real_rig", None)):
        for moving in (False, True):
            key = f"{name}_{'pitching' if moving else 'at_rest'}_us_per_step"
            out[key] = per_step(path, moving) * 1e6
            print(f"{key}: {out[key]:.0f}", flush=True)
    for base in ("at_rest", "pitching"):
        ratio = out[f"paper_{base}_us_per_step"] / out[f"real_rig_{base}_us_per_step"]
        out[f"real_rig_over_paper_speed_{base}"] = ratio
        print(f"real rig / paper, steps per second of the offline loop, base {base}: {ratio:.3f}")
    return out


if __name__ == "__main__":
    main()
