"""`make bench`: every benchmark of the project, each printing ratios measured side by side in this run."""

from __future__ import annotations

import importlib
import json
import os
import sys
from pathlib import Path

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"  # DDS stays on this machine
sys.path.insert(0, str(Path(__file__).parent))

from amb_ros.env import ensure_localhost_dds

BENCHMARKS = (
    "bench_dynamics",
    "bench_lockstep",
    "bench_bag",
    "bench_recording_cost",
    "bench_monitor",
    "bench_rig_plant",
)


def main() -> int:
    ensure_localhost_dds()
    results, failed = {}, []
    only = sys.argv[1:] or BENCHMARKS
    for name in only:
        print(f"\n=== {name} ===", flush=True)
        try:
            results[name] = importlib.import_module(name).main()
        except Exception as exc:  # a failing benchmark must not hide the others; reported and exit non-zero
            failed.append(name)
            print(f"{name} FAILED: {type(exc).__name__}: {exc}", file=sys.stderr)
    out = Path("out/bench.json")
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps(results, indent=1, default=float))
    print(f"\nresults: {out}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
