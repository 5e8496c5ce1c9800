"""CPU per lockstep step of every process of a run: `.venv/bin/python tools/rig_cpu.py [--bag] [--runs N] [--json]`.

Runs ``amb-rig run --no-monitor`` (optionally ``--bag``) and samples, every 50 ms, the CPU time of each thread of
each node process from /proc; prints the steps/s and, per process and per thread group (the Python main thread,
Fast DDS's shared-memory receive thread ``dds.shm``, its event thread ``dds.ev``), the CPU time per step in us.
Start-up (imports, model build, discovery) costs the same in a short and a long run, so each measurement is a
pair of runs, ``--duration`` and three times it, and the figure is the difference of their CPU times divided by
the difference of their steps: the CPU of a step, without start-up.  Used for the recording-cost figures in
docs/bags.md and by ``make bench`` (benchmarks/bench_lockstep.py) for the per-node CPU per step.
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from amb_ros.env import child_env

BIN = Path(sys.executable).parent
PROCESSES = ("amb-plant", "amb-controller", "amb-base-motion", "amb-bag")
TICK_S = 1.0 / os.sysconf("SC_CLK_TCK")


def _thread_cpu(pid: str) -> dict[tuple[str, str], float]:
    """{(tid, thread group): CPU seconds} of one process (groups: main, dds.shm, dds.ev, other)."""
    out = {}
    for tid in os.listdir(f"/proc/{pid}/task"):
        with open(f"/proc/{pid}/task/{tid}/comm") as f:
            comm = f.read().strip()
        with open(f"/proc/{pid}/task/{tid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
        group = "main" if tid == pid else next((g for g in ("dds.shm", "dds.ev") if comm.startswith(g)), "other")
        out[(tid, group)] = (int(fields[11]) + int(fields[12])) * TICK_S  # utime + stime
    return out


def one_run(bag: bool, duration: float, config: list[str]) -> tuple[int, float, dict[str, dict[str, float]]]:
    """(steps, steps/s, {process: {thread group: CPU seconds}}) of one run."""
    with tempfile.TemporaryDirectory() as tmp:
        record = ["--bag", str(Path(tmp) / "bag")] if bag else []
        cmd = [str(BIN / "amb-rig"), "run", "--json", "--no-monitor", "--duration", str(duration), *config,
               "--set", "controller.current_limit=1e9", *record]  # fmt: skip
        rig = subprocess.Popen(cmd, env=child_env(), stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        last: dict[tuple[str, str], dict] = collections.defaultdict(dict)  # threads that ended keep their last value
        while rig.poll() is None:
            for pid in filter(str.isdigit, os.listdir("/proc")):
                try:
                    with open(f"/proc/{pid}/cmdline") as f:
                        args = f.read().split("\0")
                    name = next((p for p in PROCESSES if any(a.endswith("/" + p) for a in args[:2])), None)
                    if name is not None:
                        last[(name, pid)].update(_thread_cpu(pid))
                except OSError:  # a process or thread that has just ended
                    continue
            time.sleep(0.05)
        summary = json.loads(rig.communicate()[0])
    cpu: dict[str, dict[str, float]] = collections.defaultdict(lambda: collections.defaultdict(float))
    for (name, _), threads in last.items():
        for (_, group), seconds in threads.items():
            cpu[name][group] += seconds
    return int(summary["steps"]), float(summary["steps_per_s"]), cpu


def per_step(bag: bool, duration: float, config: list[str]) -> tuple[float, dict[str, dict[str, float]]]:
    """(steps/s of the long run, {process: {thread group: us of CPU per step}}) from a short and a long run."""
    n1, _, cpu1 = one_run(bag, duration, config)
    n2, rate, cpu2 = one_run(bag, 3 * duration, config)
    if n2 <= n1:
        raise RuntimeError(f"the long run made {n2} steps, the short one {n1}")
    us = {name: {g: 1e6 * (cpu2[name].get(g, 0.0) - cpu1.get(name, {}).get(g, 0.0)) / (n2 - n1) for g in groups}
          for name, groups in cpu2.items()}  # fmt: skip
    return rate, us


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bag", action="store_true", help="record the run (amb-rig run --bag)")
    parser.add_argument("--runs", type=int, default=1, help="measurements (each a short and a long run)")
    parser.add_argument("--duration", type=float, default=1.0, help="simulated s of the short run (long: 3x)")
    parser.add_argument("--config", help="rotor config (default: the real-rig default)")
    parser.add_argument("--json", action="store_true", help="one JSON object per measurement")
    args = parser.parse_args()
    config = ["--config", args.config] if args.config else []
    for _ in range(args.runs):
        rate, us = per_step(args.bag, args.duration, config)
        if args.json:
            print(json.dumps({"steps_per_s": rate, "us_per_step": us}), flush=True)
            continue
        parts = [f"{name} {sum(g.values()):.0f} ({', '.join(f'{k} {v:.0f}' for k, v in sorted(g.items()))})"
                 for name, g in us.items()]  # fmt: skip
        print(f"{rate:,.0f} steps/s; us of CPU per step: " + "; ".join(parts), flush=True)


if __name__ == "__main__":
    main()
