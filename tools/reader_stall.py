"""A reader that stops taking holds the lockstep loop up: `.venv/bin/python tools/reader_stall.py 1.5`.

Runs ``amb-rig run --no-monitor`` (8 s simulated) beside benchmarks/bench_recording_cost.py's bare raw reader of
every rig topic, SIGSTOPs the reader for the given seconds in mid-run, SIGCONTs it, and prints whether the run
finished and the plant's longest command wait (docs/nodes.md, Faults: 1.5 s stopped gave 1.50 s in 1 of 4 runs
under Fast DDS's default profile, 6-22 ms in 8 of 8 runs with the rig's profile).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

import bench_recording_cost  # noqa: E402  (the bare reader and the gates that make the plant wait for it)

from amb_ros.env import child_env  # noqa: E402

STOP_AFTER_S = 9.0  # wall time after start: start-up (~5 s) plus part of the run (~17 s at ~2,400 steps/s)


def main(stop_s: float) -> None:
    env = child_env()
    rig_cmd = [str(bench_recording_cost.BIN / "amb-rig"), "run", "--json", "--no-monitor", "--duration", "8",
               "--set", "controller.current_limit=1e9", *bench_recording_cost.READER_GATES]  # fmt: skip
    reader_cmd = [sys.executable, str(ROOT / "benchmarks" / "bench_recording_cost.py"), "--reader"]
    reader = subprocess.Popen(reader_cmd, env=env, stdout=subprocess.PIPE, text=True)
    rig = subprocess.Popen(rig_cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    try:
        time.sleep(STOP_AFTER_S)
        os.kill(reader.pid, signal.SIGSTOP)
        time.sleep(stop_s)
        os.kill(reader.pid, signal.SIGCONT)
        out, _ = rig.communicate(timeout=600)
    finally:
        reader.send_signal(signal.SIGINT)
        reader.communicate(timeout=60)
    summary = json.loads(out)
    plant = summary["nodes"]["plant"]["values"]
    print(
        f"reader stopped {stop_s:g} s: run ok {summary['ok']} {summary['errors']}; plant command wait "
        f"p50 {plant['command wait p50 (us)']} us, max {float(plant['command wait max (us)']) / 1e6:.3f} s"
    )


if __name__ == "__main__":
    main(float(sys.argv[1]) if len(sys.argv) > 1 else 1.5)
