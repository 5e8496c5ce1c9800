"""Core speed: modes over 100 speeds, the 100x100 pitch chart, and its speed-up over a plain solve_ivp monodromy;
the unbalance response over 1000 speeds and the chart's cost per point on the full FE model (what the CLI runs).

Ratios are measured side by side in this run (machines here are noisy); run with `make bench`.
"""

from __future__ import annotations

import time

import numpy as np

from amb_dynamics.chart import stability_chart
from amb_dynamics.config import load_config, paper_config_path
from amb_dynamics.modes import campbell_data
from amb_dynamics.motion import BaseMotion
from amb_dynamics.structure import build_structure
from amb_dynamics.system import closed_loop, periodic_system
from amb_dynamics.unbalance import SynchronousResponse, Unbalance
from amb_dynamics.validation import rho_ivp

SAMPLE_POINTS = ((10, 80), (30, 90), (55, 99), (70, 65), (95, 40))  # (omega index, amplitude index)


def main() -> dict:
    cfg = load_config(paper_config_path())  # the paper rotor, 5000 rad/s modal model
    model = build_structure(cfg)
    loop = closed_loop(model, cfg)
    t0 = time.perf_counter()
    campbell_data(model, loop, np.linspace(0.0, 3000.0, 100))
    t_modes = time.perf_counter() - t0

    omegas, amps = np.linspace(1.0, 40.0, 100), np.linspace(0.0, 0.5, 100)
    chart = stability_chart(loop, "pitch", omegas, amps, cfg.spin_rad_s)
    per_point_chart = chart.seconds / chart.rho.size

    t_ivp, errs = [], []
    for i, j in SAMPLE_POINTS:
        ps = periodic_system(loop, BaseMotion.single("pitch", amps[j], omegas[i]), cfg.spin_rad_s)
        t0 = time.perf_counter()
        ref = rho_ivp(ps, rtol=1e-10, atol=1e-12)
        t_ivp.append(time.perf_counter() - t0)
        errs.append(abs(ref - chart.rho[i, j]))
    full_cfg = load_config(paper_config_path(), ["modal_cutoff=null", "disks.0.unbalance=1e-3"])
    full_model = build_structure(full_cfg)
    full_loop = closed_loop(full_model, full_cfg)
    t0 = time.perf_counter()
    SynchronousResponse(full_model, full_loop, Unbalance.from_config(full_cfg)).displacements(
        np.linspace(1, 3000, 1000)
    )
    t_unbalance = time.perf_counter() - t0
    full_chart = stability_chart(full_loop, "pitch", omegas[::10], amps[::10], cfg.spin_rad_s)
    res = {
        "unbalance_1000_speeds_s": t_unbalance,
        "chart_full_fe_per_point_s": full_chart.seconds / full_chart.rho.size,
        "modes_100_speeds_s": t_modes,
        "chart_100x100_s": chart.seconds,
        "chart_unstable_points": int((chart.rho > 1 + 1e-6).sum()),
        "solve_ivp_per_point_s": float(np.mean(t_ivp)),
        "chart_per_point_s": per_point_chart,
        "speedup_vs_solve_ivp": float(np.mean(t_ivp) / per_point_chart),
        "max_abs_rho_difference": float(max(errs)),
    }
    print("core (amb_dynamics), paper rotor (config/seed_paper.yaml), modal cutoff 5000 rad/s")
    print(f"  modes, 100 speeds                 {t_modes:8.3f} s      (goal: well under 1 s)")
    print(f"  pitch chart 100x100 (2 procs)     {chart.seconds:8.3f} s      (goal: < 10 s)")
    print(
        f"  solve_ivp DOP853 monodromy        {res['solve_ivp_per_point_s']:8.3f} s/point (rtol 1e-10, "
        f"{len(SAMPLE_POINTS)} grid points)"
    )
    print(f"  chart                             {per_point_chart * 1e3:8.3f} ms/point")
    print(f"  speed-up chart / solve_ivp        {res['speedup_vs_solve_ivp']:8.0f} x      (goal: >= 100 x)")
    print(f"  max |rho_chart - rho_ivp|         {res['max_abs_rho_difference']:8.1e}        (goal: <= 1e-6)")
    print(f"  chart on the full FE model (CLI)  {res['chart_full_fe_per_point_s'] * 1e3:8.3f} ms/point (10x10 grid)")
    print(f"  unbalance response, 1000 speeds   {t_unbalance:8.3f} s      (goal: < 1 s; full FE model)")
    return res


if __name__ == "__main__":
    main()
