"""`make demo`: the main job on the seed rotor, end to end, and where its outputs are.

1. the closed-loop modes at 0 and 1000 rpm and the Campbell diagram (core),
2. the pitch case of the paper (0.3 rad at 24.5 rad/s): Floquet multipliers of the continuous and the digital loop,
3. the ROS 2 node suite on that case: `amb-rig run` (lockstep over DDS, localhost only), recorded to an MCAP bag,
   with the stability monitor's verdict, then `amb-bag info` of the bag,
4. the real rig (config/seed_rotor.yaml: unbalance, gravity, noise, amplifier and sensor dynamics, nonlinear
   bearing force, touchdown bearings) on the plant node's stepping code (`amb-dynamics simulate --sampled`):
   the orbits at 1000 rpm (unbalance and noise) inside the clearance circles, a run-up through the first critical
   speeds, and a drop onto the touchdown bearings after a controller failure; the same failure over DDS with
   `--param controller:fail_at_s=`.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
OUT = REPO / "out"
BIN = Path(sys.executable).parent
CASE = ["--motion", "pitch", "--amplitude", "0.3", "--frequency", "24.5"]
PAPER = ["--config", str(REPO / "config" / "seed_paper.yaml")]  # the paper's idealised rotor
# through the first critical speeds (202 and 233 rpm: `amb-dynamics unbalance --out`)
RAMP = ["--set", "spin.profile=ramp", "--set", "spin.start_rpm=100", "--set", "spin.end_rpm=400",
        "--set", "spin.rate_rpm_s=100"]  # fmt: skip


def step(title: str, cmd: list[str]) -> None:
    print(f"\n### {title}\n$ {' '.join(cmd)}", flush=True)
    rc = subprocess.run(cmd, cwd=REPO).returncode
    if rc != 0:
        sys.exit(f"demo: '{cmd[0]} {cmd[1]}' failed with exit code {rc}")


def main() -> None:
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"  # DDS stays on this machine
    os.environ.pop("ROS_STATIC_PEERS", None)
    OUT.mkdir(exist_ok=True)
    dyn = str(BIN / "amb-dynamics")
    step(
        "closed-loop modes of the seed rotor (below 600 rad/s)",
        [dyn, "modes", "--speed-rpm", "0", "1000", "--max-frequency", "600"],
    )
    step("Campbell diagram", [dyn, "campbell", "--out", str(OUT / "campbell.png")])
    step("Floquet multipliers, continuous PD (paper model)", [dyn, "floquet", *PAPER, *CASE, "--top", "4"])
    step(
        "Floquet multipliers, digital PD at the configured rate (T = pi/24.5 s is not a whole number of samples)",
        [dyn, "floquet", *PAPER, *CASE, "--controller", "sampled", "--snap", "--top", "4"],
    )
    bag = OUT / "demo_bag"
    if bag.exists():
        shutil.rmtree(bag)
    step(
        "ROS 2 node suite: base_motion, amb_plant, amb_controller, stability_monitor, recorder (lockstep)",
        [
            str(BIN / "amb-rig"),
            "run",
            "--duration",
            "3",
            *PAPER,
            *CASE,
            "--initial-displacement",
            "1e-3",
            "--bag",
            str(bag),
        ],
    )
    step("the recorded bag", [str(BIN / "amb-bag"), "info", str(bag)])
    step("plot of the recorded run", [str(BIN / "amb-bag"), "plot", str(bag), "--out", str(OUT / "demo_run.png")])
    real_rig(dyn)
    print(f"\noutputs: {OUT}/campbell.png, {OUT}/demo_run.png, bag {bag}/ (rosbag2 layout, MCAP), "
          f"{OUT}/rig_orbits.png, {OUT}/rig_runup.png, {OUT}/rig_drop.png")  # fmt: skip


def real_rig(dyn: str) -> None:
    """The real-rig default on the plant node's stepping code (base at rest, every effect of the config)."""
    sim = [dyn, "simulate", "--sampled", "--motion", "none"]
    step("real rig: orbits at both AMBs at 1000 rpm (G2.5 unbalance, force and sensor noise), inside the clearances",
         [*sim, "--duration", "0.5", "--out", str(OUT / "rig_orbits.png")])  # fmt: skip
    step("real rig: run-up 100 -> 400 rpm at 100 rpm/s through the first critical speeds",
         [*sim, *RAMP, "--duration", "3.2", "--out", str(OUT / "rig_runup.png")])  # fmt: skip
    step("real rig: controller failure at 0.2 s, the rotor drops onto its touchdown bearings",
         [*sim, "--fail-at-s", "0.2", "--duration", "0.5", "--out", str(OUT / "rig_drop.png")])  # fmt: skip
    step("the same drop over DDS: amb-rig with --param controller:fail_at_s (lockstep, base at rest)",
         [str(BIN / "amb-rig"), "run", "--duration", "0.4", "--motion", "none", "--no-monitor",
          "--param", "controller:fail_at_s=0.2"])  # fmt: skip


if __name__ == "__main__":
    main()
