"""`make demo`: the main job on the seed rotor, end to end, and where its outputs are.

1. the closed-loop modes at 0 and 1000 rpm and the Campbell diagram (core),
2. the pitch case of the paper (0.3 rad at 24.5 rad/s): Floquet multipliers of the continuous and the digital loop,
3. the ROS 2 node suite on that case: `amb-rig run` (lockstep over DDS, localhost only), recorded to an MCAP bag,
   with the stability monitor's verdict, then `amb-bag info` of the bag.
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
    step("Floquet multipliers, continuous PD", [dyn, "floquet", *CASE, "--top", "4"])
    step(
        "Floquet multipliers, digital PD at the configured rate (T = pi/24.5 s is not a whole number of samples)",
        [dyn, "floquet", *CASE, "--controller", "sampled", "--snap", "--top", "4"],
    )
    bag = OUT / "demo_bag"
    if bag.exists():
        shutil.rmtree(bag)
    step(
        "ROS 2 node suite: base_motion, amb_plant, amb_controller, stability_monitor, recorder (lockstep)",
        [str(BIN / "amb-rig"), "run", "--duration", "3", *CASE, "--initial-displacement", "1e-3", "--bag", str(bag)],
    )
    step("the recorded bag", [str(BIN / "amb-bag"), "info", str(bag)])
    step("plot of the recorded run", [str(BIN / "amb-bag"), "plot", str(bag), "--out", str(OUT / "demo_run.png")])
    print(f"\noutputs: {OUT}/campbell.png, {OUT}/demo_run.png, bag {bag}/ (rosbag2 layout, MCAP)")


if __name__ == "__main__":
    main()
