"""Live-view cost: the lockstep loop's steps/s without and with ``--live`` (amb-live beside the rig), side by side.

Pairs of ``amb-rig run --json --no-monitor --duration RIG_DURATION`` without and with ``--live --live-port 0``
(no Foxglove client connected: the view's DDS readers and its conversion of every state block run, the
WebSocket sends nothing), the order swapped from one pair to the next, so that the machine's drift and any
after-effect of the previous run hit both alike; steps/s is the plant's loop rate from the summary (start-up
excluded).  The cost is the median over the pairs of 1 - with/without.
"""

from __future__ import annotations

import json
import statistics
import subprocess
import sys
from pathlib import Path

from report import record

BIN = Path(sys.executable).parent
PAPER = ["--config", str(Path(__file__).resolve().parents[1] / "config" / "seed_paper.yaml")]  # a fast plant
RIG_DURATION = 3.0  # simulated s: 15,000 steps at 5 kHz
PAIRS = 8  # run-to-run spread here is several % either way: the median needs many pairs


def steps_per_s(live: bool) -> float:
    from amb_ros.env import child_env

    cmd = [str(BIN / "amb-rig"), "run", "--json", "--no-monitor", "--duration", str(RIG_DURATION), *PAPER,
           "--set", "controller.current_limit=1e9"]  # fmt: skip
    if live:
        cmd += ["--live", "--live-port", "0"]
    out = subprocess.run(cmd, env=child_env(), capture_output=True, text=True, timeout=900)
    try:
        summary = json.loads(out.stdout)
    except json.JSONDecodeError:
        raise RuntimeError(f"amb-rig failed: {out.stderr.strip()[-500:]}") from None
    if not summary["ok"]:
        raise RuntimeError(f"amb-rig: {summary['errors']}")
    return float(summary["steps_per_s"])


def main(pairs: int = PAIRS) -> dict:
    rows = []
    for i in range(pairs):
        if i % 2:
            with_live, without = steps_per_s(True), steps_per_s(False)
        else:
            without, with_live = steps_per_s(False), steps_per_s(True)
        rows.append((without, with_live))
        print(f"  pair {i + 1}: {without:8,.0f} steps/s without, {with_live:8,.0f} with --live "
              f"({100 * (1 - with_live / without):+.1f} %)", flush=True)  # fmt: skip
    costs = [1 - w / wo for wo, w in rows]
    result = {"pairs": rows, "cost": statistics.median(costs), "cost_min": min(costs), "cost_max": max(costs),
              "steps_per_s_without": statistics.median(r[0] for r in rows),
              "steps_per_s_with_live": statistics.median(r[1] for r in rows)}  # fmt: skip
    print(f"  cost of --live: {100 * result['cost']:.1f} % of steps/s, median of {pairs} pairs "
          f"({100 * result['cost_min']:.1f} to {100 * result['cost_max']:.1f} %); goal < 5 %")  # fmt: skip
    record("live view: lockstep steps/s lost with --live (no client), back-to-back pairs", [100 * c for c in costs],
           "%", goal="< 5")  # fmt: skip
    record("lockstep steps/s without --live (the pairs above)", [r[0] for r in rows], "steps/s")
    record("lockstep steps/s with --live (the pairs above)", [r[1] for r in rows], "steps/s")
    return result


if __name__ == "__main__":
    from amb_ros.env import ensure_localhost_dds

    ensure_localhost_dds()
    main(int(sys.argv[1]) if len(sys.argv) > 1 else PAIRS)
