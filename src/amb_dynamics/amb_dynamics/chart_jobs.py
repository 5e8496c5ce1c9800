"""Stability charts as chunks of rows for :class:`dask_exec.ChunkRunner`: continuous or digital (sampled) loop.

A chunk is a few rows (omega values) of one chart; its function is module-level and rebuilds the model from the
config on the worker (memoised per process), so the same chunk gives the same bits wherever it runs.
"""

from __future__ import annotations

import dataclasses
import pickle
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .chart import A_NODES, AMP_TOL, CHART_STEPS, _Row, continuous_method
from .config import RotorConfig, to_dict
from .dask_exec import ChunkRunner, cache_key
from .digital_chart import CHART_MAX_R, digital_row
from .digital_floquet import BOUND_FLOOR, BOUND_SAFETY
from .rate_family import U_NODES
from .sampled import SampledLoop
from .structure import build_structure
from .system import closed_loop

SCHEMA_VERSION = 1
CACHE_VERSION = "chart-6"  # bump when the numbers a chunk produces change
_MEMO: dict[bytes, object] = {}


@dataclass(frozen=True)
class ChartSpec:
    """Everything a chart's numbers depend on (picklable, hashed for the cache)."""

    cfg: RotorConfig
    kind: str  # roll | pitch | yaw
    controller: str  # continuous | sampled
    delay_samples: int | None  # sampled: None = the config's

    def method(self) -> dict:
        if self.controller == "continuous":
            return continuous_method()
        return {
            "loop": "sampled-data (ZOH, discrete PID, base rates held per sample)",
            "exact": f"product of the step maps over the hybrid period when T/Ts = p/r, r <= {CHART_MAX_R}",
            "estimate": "rho interpolated (quadratic) in T/Ts from exact products at the three nearest integer "
            f"ratios; bound {BOUND_SAFETY:g} |quadratic - linear| + {BOUND_FLOOR:g} + amplitude-interpolation check",
            "step_map_chebyshev_nodes": U_NODES,
            "amplitude_chebyshev_nodes": A_NODES,
            "amplitude_check_tolerance": AMP_TOL,
            "eigenvalues": continuous_method()["eigenvalues"],
            "method_codes": {"0": "exact", "1": "ratio-interpolation"},
        }

    def key(self, omegas: np.ndarray, amps: np.ndarray) -> str:
        return cache_key(CACHE_VERSION, to_dict(self.cfg), self.kind, self.controller, self.delay_samples, omegas, amps)


def analysed_config(spec: ChartSpec) -> RotorConfig:
    """The config whose structure the chart analyses: ``modal_cutoff`` serves the digital loop only, the
    continuous analyses run on the full FE model."""
    return spec.cfg if spec.controller == "sampled" else dataclasses.replace(spec.cfg, modal_cutoff=None)


def _built(spec: ChartSpec):
    k = pickle.dumps(spec)
    hit = _MEMO.get(k)
    if hit is None:
        cfg = analysed_config(spec)
        if spec.controller == "sampled":
            hit = SampledLoop(build_structure(cfg), cfg, delay_samples=spec.delay_samples, forcing=False)
        else:
            hit = closed_loop(build_structure(cfg), cfg)
        _MEMO.clear()
        _MEMO[k] = hit
    return hit


def chart_chunk(spec: ChartSpec, omegas: np.ndarray, amps: np.ndarray) -> dict:
    """rho, critical frequency, error bound and method code for the rows ``omegas`` (one chunk)."""
    built = _built(spec)
    n_w, n_a = len(omegas), len(amps)
    out = {k: np.empty((n_w, n_a)) for k in ("rho", "critical", "bound")}
    out["method"] = np.zeros(n_w, dtype=np.int8)
    out["steps"] = np.zeros(n_w, dtype=np.int64)
    if spec.controller == "continuous":
        row = _Row(built, spec.kind, spec.cfg.spin_rad_s, amps, CHART_STEPS)
        for i, w in enumerate(omegas):
            out["rho"][i], out["critical"][i] = row.evaluate(float(w))
        out["bound"][:] = np.nan  # validated separately (tests: < 1e-6 against single-point Magnus)
        out["steps"][:] = CHART_STEPS
        return out
    for i, w in enumerate(omegas):
        r = digital_row(built, spec.kind, float(w), amps)
        out["rho"][i], out["critical"][i], out["bound"][i] = r.rho, r.critical, r.bound
        out["method"][i], out["steps"][i] = r.method, r.steps
    return out


def run_chart_job(
    spec: ChartSpec,
    omegas: np.ndarray,
    amps: np.ndarray,
    cache_root: Path | None,
    workers: int | None,
    scheduler: str | None,
    rows_per_chunk: int = 1,
    progress: bool = True,
) -> dict:
    """The whole chart through the chunk runner; returns arrays (n_w, n_A) and the cache folder used."""
    omegas = np.asarray(omegas, dtype=float)
    amps = np.asarray(amps, dtype=float)
    key = spec.key(omegas, amps)
    chunks = [(spec, omegas[i : i + rows_per_chunk], amps) for i in range(0, omegas.size, rows_per_chunk)]
    cache = cache_root / key if cache_root else None
    runner = ChunkRunner(chart_chunk, chunks, f"chart {spec.controller}", cache, workers, scheduler, progress)
    parts = runner.run()
    res = {k: np.concatenate([p[k] for p in parts]) for k in ("rho", "critical", "bound", "method", "steps")}
    res.update(cache_dir=str(cache) if cache else None, cached_chunks=runner.cached, chunks=len(chunks), key=key)
    return res


def chart_document(spec: ChartSpec, omegas, amps, res: dict, seconds: float) -> dict:
    """The chart JSON (schema_version 1): grids, max|mu|, and per point the method code and error bound."""
    rho = res["rho"]
    doc = {
        "schema_version": SCHEMA_VERSION,
        "motion": spec.kind,
        "controller": spec.controller,
        "omega_rad_s": np.asarray(omegas).tolist(),
        "amplitude_rad": np.asarray(amps).tolist(),
        "max_abs_multiplier": rho.tolist(),
        "critical_frequency_rad_s": res["critical"].tolist(),
        "unstable_points": int((rho > 1 + 1e-6).sum()),
        "points": int(rho.size),
        "method": spec.method(),
        "wall_time_s": seconds,
        "cache": {"dir": res["cache_dir"], "chunks": res["chunks"], "cached_chunks": res["cached_chunks"]},
    }
    if spec.controller == "sampled":
        loop = _built(spec)
        doc["controller_rate_hz"] = 1.0 / loop.Ts
        doc["delay_samples"] = loop.delay
        doc["error_bound"] = res["bound"].tolist()
        doc["method_per_point"] = np.repeat(res["method"][:, None], rho.shape[1], axis=1).tolist()
        doc["max_error_bound"] = float(np.nanmax(res["bound"]))
        doc["undecided_points"] = int(((rho - res["bound"] <= 1 + 1e-6) & (rho + res["bound"] >= 1 - 1e-6)).sum())
    return doc
