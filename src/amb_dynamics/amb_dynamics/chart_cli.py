"""``amb-dynamics chart``: continuous or digital-loop chart, serial or on Dask, resumable (docs/charts.md)."""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from . import plots
from .chart_jobs import ChartSpec, chart_document, run_chart_job
from .errors import InputError

DEFAULT_CACHE = Path("out/cache")
SERIAL_BELOW_ROWS = 40  # a continuous chart with fewer rows runs in this process unless --workers says otherwise


def add_execution_args(p: argparse.ArgumentParser) -> None:
    """--workers / --scheduler / --cache-dir / --no-cache / --rows-per-chunk (chart and sweep)."""
    p.add_argument("--workers", type=int, default=None, help="local worker processes (1: serial; default: cores)")
    p.add_argument("--scheduler", default=None, metavar="tcp://HOST:PORT", help="run on an existing Dask cluster")
    p.add_argument("--cache-dir", type=Path, default=DEFAULT_CACHE, help="finished chunks (resume after a kill)")
    p.add_argument("--no-cache", action="store_true", help="do not read or write finished chunks")
    p.add_argument("--rows-per-chunk", type=int, default=1, help="grid rows per Dask task")


def add_chart_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--controller", choices=("continuous", "sampled"), default="continuous")
    p.add_argument("--delay-samples", type=int, choices=(0, 1), default=None, help="sampled: override the config's")
    add_execution_args(p)


def check_execution(args) -> None:
    if args.workers is not None and args.workers < 1:
        raise InputError(f"--workers must be >= 1 (got {args.workers})")
    if args.rows_per_chunk < 1:
        raise InputError(f"--rows-per-chunk must be >= 1 (got {args.rows_per_chunk})")
    if args.scheduler is not None and not args.scheduler.startswith(("tcp://", "tls://", "inproc://", "ucx://")):
        raise InputError(f"--scheduler '{args.scheduler}' is not an address like tcp://127.0.0.1:8786")


def run_chart(args, s, describe) -> tuple[dict, str]:
    """``s``: analysis.Setup; ``describe``: analysis.describe (passed in to avoid an import cycle)."""
    if (args.frequency <= 0).any() or (args.amplitude < 0).any():
        raise InputError("chart frequencies must be > 0 rad/s and amplitudes >= 0 rad")
    check_execution(args)
    spec = ChartSpec(s.cfg, args.motion, args.controller, args.delay_samples)
    t0 = time.perf_counter()
    cache = None if args.no_cache else args.cache_dir
    if args.workers is None and args.scheduler is None and args.controller == "continuous":
        # a continuous row on the full FE model is ~60 ms of one core; under SERIAL_BELOW_ROWS rows, starting a
        # local cluster (~1 s) would cost more than it saves
        args.workers = 1 if args.frequency.size < SERIAL_BELOW_ROWS else None
    res = run_chart_job(spec, args.frequency, args.amplitude, cache, args.workers, args.scheduler, args.rows_per_chunk)
    seconds = time.perf_counter() - t0
    doc = chart_document(spec, args.frequency, args.amplitude, res, seconds)
    loop_text = (
        "continuous controller"
        if args.controller == "continuous"
        else (f"digital loop {doc['controller_rate_hz']:g} Hz, delay {doc['delay_samples']}")
    )
    title = (
        f"{describe(s.cfg, s.model)}\n{args.motion}, spin {s.cfg.spin_speed_rpm:g} rpm, {loop_text}: max|mu| per period"
    )
    png = plots.chart_figure(args.frequency, args.amplitude, res["rho"], title, args.out)
    doc.update(model=describe(s.cfg, s.model), png=str(png))
    if args.json_out:
        write_json(args.json_out, doc)
    extra = ""
    if args.controller == "sampled":
        extra = f", max error bound {doc['max_error_bound']:.2g}, {doc['undecided_points']} points within it of 1"
    text = (
        f"chart {res['rho'].shape[0]}x{res['rho'].shape[1]} ({loop_text}) in {seconds:.2f} s: "
        f"{doc['unstable_points']} unstable points, max|mu| = {res['rho'].max():.6f}{extra}\nPNG: {png}"
        + (f"\nJSON: {args.json_out}" if args.json_out else "")
    )
    summary = {
        k: v
        for k, v in doc.items()
        if k not in ("max_abs_multiplier", "critical_frequency_rad_s", "error_bound", "method_per_point")
    }
    return summary, text


def write_json(path: Path, data: dict) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".part")
    tmp.write_text(json.dumps(data))
    tmp.replace(path)
