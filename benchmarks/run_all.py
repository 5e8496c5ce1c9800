"""`make bench`: every benchmark of the project; writes docs/performance.md (benchmarks/report.py).

.venv/bin/python benchmarks/run_all.py                      all benchmarks -> docs/performance.md
.venv/bin/python benchmarks/run_all.py bench_dynamics       one module     -> out/performance.md
.venv/bin/python benchmarks/run_all.py --out FILE [MODULE ...]
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import sys
import time
from pathlib import Path

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"  # DDS stays on this machine
os.environ.pop("ROS_STATIC_PEERS", None)
sys.path.insert(0, str(Path(__file__).parent))

from report import PAGE, record, set_source, write_page

from amb_dynamics.threads import single_thread_env  # imports no numpy
from amb_ros.env import ensure_localhost_dds

os.environ.update(single_thread_env())  # one BLAS thread for every benchmark and its children

BENCHMARKS = (
    "bench_dynamics",
    "bench_charts",
    "bench_lockstep",
    "bench_bag",
    "bench_recording_cost",
    "bench_monitor",
    "bench_live_cost",
    "bench_sensitivity",
    "bench_rig_plant",
    "bench_monitor_rig",
)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("modules", nargs="*", metavar="MODULE", help=", ".join(BENCHMARKS))
    ap.add_argument("--out", type=Path, default=None, help="page to write (default: see above)")
    args = ap.parse_args()
    unknown = [m for m in args.modules if m not in BENCHMARKS]
    if unknown:
        ap.error(f"unknown benchmark {unknown[0]!r} (one of {', '.join(BENCHMARKS)})")
    ensure_localhost_dds()
    results, failed = {}, []
    only = args.modules or list(BENCHMARKS)
    minutes = {}
    for name in only:
        print(f"\n=== {name} ===", flush=True)
        set_source(name)
        t0 = time.monotonic()
        try:
            results[name] = importlib.import_module(name).main()
        except Exception as exc:  # a failing benchmark must not hide the others; reported and exit non-zero
            failed.append(name)
            print(f"{name} FAILED: {type(exc).__name__}: {exc}", file=sys.stderr)
        minutes[name] = (time.monotonic() - t0) / 60.0
    set_source("")
    for name, m in minutes.items():
        record(f"wall time of {name}", [m], "min", command=f".venv/bin/python benchmarks/run_all.py {name}")
    if not args.modules:
        record("wall time of every benchmark (make bench, without its install)", [sum(minutes.values())], "min",
               goal="< 30", command="make bench")  # fmt: skip
    out = Path("out/bench.json")
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps(results, indent=1, default=float))
    page = args.out or (PAGE if not args.modules else Path("out/performance.md"))
    ran = [n for n in only if n not in failed]
    skipped = [n for n in BENCHMARKS if n not in only] + [f"{n} (failed)" for n in failed]
    write_page(page, ran, skipped)
    print(f"\nresults: {out}\npage: {page}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
