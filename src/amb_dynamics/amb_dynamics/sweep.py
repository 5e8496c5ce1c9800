"""``amb-dynamics sweep``: stability over config keys x (omega, A), as a labelled N-d dataset (netCDF) + PNG slices.

Every combination of the ``--axis KEY=lo:hi:n`` values is one chart (continuous or digital loop); all their rows
go to one :class:`dask_exec.ChunkRunner` job (one cluster, one resumable cache).  With ``--refine`` every sign
change of max|mu| - 1 between neighbouring frequencies (per amplitude and combination) is bisected in omega to
``--tol`` rad/s with the same kernel, so narrow tongues are located, not left to grid luck.
Outputs (in ``--out-dir``): ``sweep.nc`` (xarray, netCDF3 via scipy), ``boundaries.json``, ``slice_*.png``; each
written to a temporary name and renamed, the dataset last: a dataset that exists is complete.
"""

from __future__ import annotations

import itertools
import json
import time
from pathlib import Path

import numpy as np

from . import plots
from .chart import CHART_STEPS, _Row
from .chart_cli import DEFAULT_CACHE, add_execution_args, check_execution
from .chart_jobs import SCHEMA_VERSION, ChartSpec, _built, analysed_config, chart_chunk
from .config import load_config, to_dict
from .dask_exec import ChunkRunner, cache_key
from .digital_chart import digital_row
from .errors import InputError
from .structure import build_structure

CACHE_VERSION = "sweep-3"


def parse_axis(text: str) -> tuple[str, np.ndarray]:
    """'key=lo:hi:n' or 'key=a,b,c' -> (key, values); one clear line on bad input."""
    key, sep, rng = text.partition("=")
    if not sep or not key:
        raise InputError(f"--axis '{text}': use KEY=lo:hi:n or KEY=a,b,c (e.g. controller.rate_hz=3000:6000:4)")
    try:
        if ":" in rng:
            lo, hi, n = rng.split(":")
            if int(n) < 1:
                raise InputError(f"--axis {key}: empty range '{rng}' (n must be >= 1)")
            vals = np.linspace(float(lo), float(hi), int(n))
        else:
            vals = np.array([float(v) for v in rng.split(",") if v.strip()])
    except ValueError:
        raise InputError(f"--axis {key}: '{rng}' is not a range lo:hi:n or a list a,b,c") from None
    if vals.size == 0:
        raise InputError(f"--axis {key}: empty range")
    return key, vals


def _fmt(v: float) -> str:
    return str(int(v)) if float(v).is_integer() else repr(float(v))


def add_sweep_parser(sub, common, grid) -> None:
    p = sub.add_parser("sweep", help="stability over config keys x (omega, A): netCDF dataset, PNG slices")
    common(p)
    p.add_argument("--motion", choices=("roll", "pitch", "yaw"), required=True)
    p.add_argument("--amplitude", type=grid, required=True, help="lo:hi:n (rad)")
    p.add_argument("--frequency", type=grid, required=True, help="lo:hi:n (rad/s)")
    p.add_argument("--axis", action="append", default=[], metavar="KEY=lo:hi:n", help="config key axis (repeatable)")
    p.add_argument("--controller", choices=("continuous", "sampled"), default="continuous")
    p.add_argument("--delay-samples", type=int, choices=(0, 1), default=None)
    p.add_argument("--refine", action="store_true", help="bisect every stability boundary in omega")
    p.add_argument("--tol", type=float, default=1e-4, help="boundary tolerance in omega (rad/s)")
    p.add_argument("--out-dir", type=Path, default=Path("out/sweep"))
    add_execution_args(p)


def rho_at(spec: ChartSpec, omega: float, amplitude: float) -> float:
    """max|mu| at one point with the chart's kernel (continuous Magnus-4 chart row or digital row)."""
    built = _built(spec)
    amps = np.array([amplitude])
    if spec.controller == "continuous":
        return float(_Row(built, spec.kind, spec.cfg.spin_rad_s, amps, CHART_STEPS).evaluate(omega)[0][0])
    return float(digital_row(built, spec.kind, omega, amps).rho[0])


def refine_edges(spec: ChartSpec, omegas: np.ndarray, amps: np.ndarray, rho: np.ndarray, tol: float) -> list[dict]:
    """Bisect every sign change of rho - 1 between omega neighbours (per amplitude) to ``tol`` rad/s."""
    edges = []
    for j, a in enumerate(amps):
        s = rho[:, j] > 1.0
        for i in np.flatnonzero(s[1:] != s[:-1]):
            lo, hi = float(omegas[i]), float(omegas[i + 1])
            s_lo = bool(s[i])
            while hi - lo > tol:
                mid = 0.5 * (lo + hi)
                if (rho_at(spec, mid, float(a)) > 1.0) == s_lo:
                    lo = mid
                else:
                    hi = mid
            edges.append(
                {
                    "amplitude_rad": float(a),
                    "omega_rad_s": 0.5 * (lo + hi),
                    "bracket_rad_s": [lo, hi],
                    "kind": "enters unstable" if not s_lo else "leaves unstable",
                }
            )
    return edges


def run_sweep(args, describe) -> tuple[dict, str]:
    check_execution(args)
    if (args.frequency <= 0).any() or (args.amplitude < 0).any():
        raise InputError("sweep frequencies must be > 0 rad/s and amplitudes >= 0 rad")
    if args.tol <= 0:
        raise InputError(f"--tol must be > 0 rad/s (got {args.tol})")
    axes = [parse_axis(a) for a in args.axis]
    if len({k for k, _ in axes}) != len(axes):
        raise InputError("--axis: each key at most once")
    base = list(args.overrides) + ([f"formulation={args.formulation}"] if getattr(args, "formulation", None) else [])
    combos = list(itertools.product(*[v for _, v in axes])) or [()]
    specs = []
    for combo in combos:  # every combination validated before anything runs
        sets = [f"{k}={_fmt(v)}" for (k, _), v in zip(axes, combo, strict=True)]
        cfg = load_config(args.config, base + sets)
        specs.append(ChartSpec(cfg, args.motion, args.controller, args.delay_samples))
    omegas, amps = args.frequency, args.amplitude
    key = cache_key(CACHE_VERSION, [to_dict(s.cfg) for s in specs], args.motion, args.controller,
                    args.delay_samples, omegas, amps)  # fmt: skip
    rpc = args.rows_per_chunk
    chunks = [(s, omegas[i : i + rpc], amps) for s in specs for i in range(0, omegas.size, rpc)]
    cache = None if args.no_cache else (args.cache_dir or DEFAULT_CACHE) / key
    t0 = time.perf_counter()
    runner = ChunkRunner(chart_chunk, chunks, f"sweep {len(specs)} charts", cache, args.workers, args.scheduler)
    parts = runner.run()
    per = -(-omegas.size // rpc)
    fields = ("rho", "critical", "bound")
    res = {f: np.stack([np.concatenate([p[f] for p in parts[c * per : (c + 1) * per]]) for c in range(len(specs))])
           for f in fields}  # fmt: skip
    shape = (*(v.size for _, v in axes), omegas.size, amps.size)
    res = {f: v.reshape(shape) for f, v in res.items()}
    edges = []
    if args.refine:
        for c, (spec, combo) in enumerate(zip(specs, combos, strict=True)):
            rho_c = res["rho"].reshape(len(specs), omegas.size, amps.size)[c]
            for e in refine_edges(spec, omegas, amps, rho_c, args.tol):
                edges.append({**{k: float(v) for (k, _), v in zip(axes, combo, strict=True)}, **e})
    seconds = time.perf_counter() - t0
    out = args.out_dir
    out.mkdir(parents=True, exist_ok=True)
    pngs = _slices(out, specs, combos, axes, omegas, amps, res["rho"].reshape(len(specs), omegas.size, amps.size))
    analysed = analysed_config(specs[0])  # every chart of a sweep has the same controller
    meta = {
        "schema_version": SCHEMA_VERSION,
        "model": describe(analysed, build_structure(analysed)),
        "motion": args.motion,
        "controller": args.controller,
        "axes": [k for k, _ in axes] + ["omega_rad_s", "amplitude_rad"],
        "method": specs[0].method(),
        "boundary_tolerance_rad_s": args.tol if args.refine else None,
        "wall_time_s": seconds,
        "cache": {"dir": str(cache) if cache else None, "chunks": len(chunks), "cached_chunks": runner.cached},
    }
    _write_text(out / "boundaries.json", json.dumps({**meta, "boundaries": edges}, indent=1))
    nc = _write_dataset(out / "sweep.nc", axes, omegas, amps, res, meta, args.controller)
    data = {**meta, "dataset": str(nc), "pngs": [str(p) for p in pngs], "boundaries": edges,
            "unstable_points": int((res["rho"] > 1 + 1e-6).sum()), "points": int(res["rho"].size)}  # fmt: skip
    text = (
        f"sweep of {len(specs)} charts x {omegas.size}x{amps.size} in {seconds:.1f} s: "
        f"{data['unstable_points']} of {data['points']} points unstable"
        + (f", {len(edges)} boundaries refined to {args.tol:g} rad/s" if args.refine else "")
        + f"\ndataset: {nc}\nslices: {len(pngs)} PNG in {out}"
    )
    return data, text


def _slices(out: Path, specs, combos, axes, omegas, amps, rho) -> list[Path]:
    pngs = []
    for c, combo in enumerate(combos):
        label = "_".join(f"{k}={_fmt(v)}" for (k, _), v in zip(axes, combo, strict=True)) or "base"
        title = f"{specs[c].kind}, {specs[c].controller}: " + (label.replace("_", ", ") if combo else "config")
        pngs.append(plots.chart_figure(omegas, amps, rho[c], title, out / f"slice_{label}.png"))
    return pngs


def _write_text(path: Path, text: str) -> None:
    tmp = path.with_name(path.name + ".part")
    tmp.write_text(text)
    tmp.replace(path)


def _write_dataset(path: Path, axes, omegas, amps, res: dict, meta: dict, controller: str) -> Path:
    import xarray as xr

    dims = [k for k, _ in axes] + ["omega_rad_s", "amplitude_rad"]
    coords = {k: v for k, v in axes} | {"omega_rad_s": omegas, "amplitude_rad": amps}
    variables = {
        "max_abs_multiplier": (dims, res["rho"], {"long_name": "max |mu| per base period", "units": "1"}),
        "critical_frequency_rad_s": (dims, res["critical"], {"units": "rad/s"}),
    }
    if controller == "sampled":
        variables["error_bound"] = (dims, res["bound"], {"long_name": "absolute bound on max |mu|", "units": "1"})
    attrs = {
        "schema_version": SCHEMA_VERSION,
        "motion": meta["motion"],
        "controller": controller,
        "method": json.dumps(meta["method"]),
        "model": str(meta["model"]),
    }
    ds = xr.Dataset(variables, coords=coords, attrs=attrs)
    tmp = path.with_name(path.name + ".part")
    ds.to_netcdf(tmp, engine="scipy", format="NETCDF3_64BIT")
    tmp.replace(path)
    return path
