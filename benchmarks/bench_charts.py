"""Charts on the paper model (config/seed_paper.yaml): the 100x100 digital-loop pitch chart (default 5 kHz loop),
serially and on 2 local Dask workers (the 1 -> 2 workers speed-up, with its control: the same rows in one plain
process against two side by side, no Dask), its per-point speed against the straightforward product of one-expm
step maps, and the continuous 100x100 chart on the full FE model.  Ratios are measured side by side in this run.

    .venv/bin/python benchmarks/run_all.py bench_charts
"""

from __future__ import annotations

import multiprocessing as mp
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
from report import record, record_ratio

from amb_dynamics.chart_jobs import ChartSpec, chart_chunk
from amb_dynamics.config import load_config
from amb_dynamics.dask_exec import ChunkRunner, local_cluster
from amb_dynamics.digital_chart import digital_row
from amb_dynamics.digital_floquet import plan_ratio
from amb_dynamics.floquet import sampled_floquet
from amb_dynamics.motion import BaseMotion
from amb_dynamics.sampled import SampledLoop
from amb_dynamics.structure import build_structure

PAPER = Path(__file__).resolve().parents[1] / "config" / "seed_paper.yaml"
OMEGAS, AMPS = np.linspace(1.0, 40.0, 100), np.linspace(0.0, 0.5, 100)
PER_POINT_OMEGAS = (5.0, 20.0, 35.0)
SCALING_REPEATS = 3
CONTINUOUS_REPEATS = 3


def _chart(spec, omegas, amps, workers, scheduler=None):
    runner = ChunkRunner(chart_chunk, [(spec, omegas[i : i + 1], amps) for i in range(omegas.size)], "bench",
                         None, workers, scheduler, progress=False)  # fmt: skip
    t0 = time.perf_counter()
    parts = runner.run()
    total = time.perf_counter() - t0
    return np.concatenate([p["rho"] for p in parts]), total, runner.compute_seconds or total


def on_cluster(spec, omegas, amps, n_workers):
    """(rho, compute seconds) on a local cluster of ``n_workers`` started before the clock runs."""
    cluster = local_cluster(n_workers)
    try:
        rho, _, compute = _chart(spec, omegas, amps, None, cluster.scheduler_address)
    finally:
        cluster.close()
    return rho, compute


def _rows(spec, omegas, amps) -> float:
    """Seconds for ``chart_chunk`` on these rows in a fresh process (its own model build included, as a worker's)."""
    t0 = time.perf_counter()
    chart_chunk(spec, omegas, amps)
    return time.perf_counter() - t0


def side_by_side(spec, omegas, amps) -> tuple[float, float]:
    """The machine's own ceiling for 1 -> 2 workers, without Dask: (seconds for all rows in one fresh process,
    seconds until two fresh processes side by side have done half the rows each: equal shares of work).  The rows
    cost less as omega grows, so they are dealt in snake order (0, 3, 4, 7, ... and 1, 2, 5, 6, ...)."""
    ctx = mp.get_context("spawn")  # fresh processes: no model memoised from this one
    with ProcessPoolExecutor(1, mp_context=ctx) as pool:
        pool.submit(time.sleep, 0).result()  # started and imported before the clock runs
        one = pool.submit(_rows, spec, omegas, amps).result()
    snake = (np.arange(omegas.size) + 1) // 2 % 2  # 0 1 1 0 0 1 1 0 ...
    with ProcessPoolExecutor(2, mp_context=ctx) as pool:
        for f in [pool.submit(time.sleep, 0.2) for _ in range(2)]:
            f.result()
        t0 = time.perf_counter()
        futures = [pool.submit(_rows, spec, omegas[snake == k], amps) for k in (0, 1)]
        for f in futures:
            f.result()
        two = time.perf_counter() - t0
    return one, two


def per_point(cfg, model, loop) -> tuple[float, float, float]:
    """(chart s/point, straightforward s/point, max |rho difference| at the compared points)."""
    t_chart = t_plain = 0.0
    diff = 0.0
    for w in PER_POINT_OMEGAS:
        T = np.pi / w
        t0 = time.perf_counter()
        row = digital_row(loop, "pitch", w, AMPS)
        t_chart += (time.perf_counter() - t0) / AMPS.size
        plan = plan_ratio(T / loop.Ts, 4)
        t0 = time.perf_counter()
        rhos = []
        for p, r in plan.ratios:  # the same exact products, one scipy expm per step, per point
            sub = SampledLoop(model, cfg, Ts=r * T / p, forcing=False)
            rhos.append(sampled_floquet(sub, BaseMotion.single("pitch", AMPS[60], w), T).max_abs)
        t_plain += time.perf_counter() - t0
        diff = max(diff, abs(plan.combine(rhos)[0] - row.rho[60]))
    n = len(PER_POINT_OMEGAS)
    return t_chart / n, t_plain / n, diff


def main() -> dict:
    cfg = load_config(PAPER)
    model = build_structure(cfg)
    loop = SampledLoop(model, cfg, forcing=False)
    workers = 2  # the machine: two cores; the 1 -> 2 speed-up is measured on the whole chart
    t_pt_chart, t_pt_plain, diff = per_point(cfg, model, loop)

    spec = ChartSpec(cfg, "pitch", "sampled", None)
    rho, t_digital, t_digital_compute = _chart(spec, OMEGAS, AMPS, workers)  # as `amb-dynamics chart` runs it
    c1, c2, same = [], [], True
    for _ in range(SCALING_REPEATS):  # 1 and 2 local workers, each cluster started before the clock runs
        for n, times in ((1, c1), (2, c2)):
            rho_n, t = on_cluster(spec, OMEGAS, AMPS, n)
            times.append(t)
            same = same and np.array_equal(rho_n, rho)
    one, two = side_by_side(spec, OMEGAS, AMPS)

    cont = ChartSpec(cfg, "pitch", "continuous", None)
    serial, pooled, pooled_compute = [], [], []
    for _ in range(CONTINUOUS_REPEATS):  # alternating: this machine's load drifts
        serial.append(_chart(cont, OMEGAS, AMPS, 1)[1])
        _, t, c = _chart(cont, OMEGAS, AMPS, workers)
        pooled.append(t)
        pooled_compute.append(c)
    t_cont, t_cont_w, t_cont_w_compute = (float(np.median(v)) for v in (serial, pooled, pooled_compute))
    res = {
        "digital_chart_100x100_s": t_digital,
        "digital_chart_100x100_compute_s": t_digital_compute,
        "digital_chart_workers": workers,
        "digital_chart_unstable_points": int((rho > 1 + 1e-6).sum()),
        "digital_chart_equal_on_1_and_2_workers": bool(same),
        "digital_per_point_chart_s": t_pt_chart,
        "digital_per_point_plain_expm_s": t_pt_plain,
        "digital_per_point_speedup": t_pt_plain / t_pt_chart,
        "digital_per_point_rho_difference": diff,
        "workers_1_s": c1,
        "workers_2_s": c2,
        "speedup_1_to_2_workers": float(np.median(np.array(c1) / np.array(c2))),
        "side_by_side_1_s": one,
        "side_by_side_2_s": two,
        "speedup_1_to_2_processes_without_dask": one / two,
        "continuous_chart_100x100_s": t_cont,
        "continuous_chart_100x100_workers_s": t_cont_w,
        "continuous_chart_100x100_workers_compute_s": t_cont_w_compute,
    }
    print("charts, config/seed_paper.yaml (5 kHz digital loop, 5000 rad/s modal model)")
    print(f"  digital pitch chart 100x100, {workers} local workers  {t_digital:8.1f} s "
          f"(compute {t_digital_compute:.1f} s; goal < 60 s)")  # fmt: skip
    print(f"  per point: chart {t_pt_chart * 1e3:8.2f} ms, plain expm products {t_pt_plain * 1e3:8.1f} ms: "
          f"{res['digital_per_point_speedup']:.0f}x (|rho difference| {diff:.1e})")  # fmt: skip
    print(f"  the same chart on 1 and 2 local workers: {np.median(c1):.2f} s and {np.median(c2):.2f} s compute: "
          f"{res['speedup_1_to_2_workers']:.2f}x (goal >= 1.8x); identical numbers: {same}")  # fmt: skip
    print(f"  the same rows in plain processes, no Dask: one {one:.2f} s, two side by side {two:.2f} s: "
          f"{one / two:.2f}x (the machine's own ceiling for 2 workers)")  # fmt: skip
    print(f"  continuous pitch chart 100x100 (serial)     {t_cont:8.2f} s (median of {CONTINUOUS_REPEATS})")
    print(f"  continuous pitch chart 100x100, {workers} local workers {t_cont_w:8.2f} s "
          f"(compute {t_cont_w_compute:.2f} s; goal < 5 s)")  # fmt: skip
    record(f"digital-loop pitch chart 100 x 100, paper config, {workers} local Dask workers", t_digital, "s",
           goal="< 60 s", note=f"compute {t_digital_compute:.1f} s")  # fmt: skip
    record_ratio("digital chart per point vs a product of one-expm step maps", [t_pt_plain], [t_pt_chart])
    record("  max |rho difference| at those points", diff, "")
    record_ratio("100 x 100 digital chart, 1 -> 2 local workers (compute)", c1, c2, goal=">= 1.8x",
                 note=f"median of {SCALING_REPEATS} each")  # fmt: skip
    record_ratio("  control: the same rows in plain processes, one vs two side by side (no Dask)", [one], [two])
    record("continuous pitch chart 100 x 100 through the chunk runner, full FE model, serial", serial, "s")
    record(f"continuous pitch chart 100 x 100, full FE model, {workers} local Dask workers", pooled, "s",
           goal="< 5 s", note=f"compute {t_cont_w_compute:.1f} s, cluster start-up included")  # fmt: skip
    return res


if __name__ == "__main__":
    main()
