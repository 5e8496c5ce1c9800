"""A tour of the amb_dynamics Python API: build a rotor from YAML, then modes, Floquet, a chart and time runs.

Run:  .venv/bin/python examples/rotor_tour.py [--config config/seed_rotor.yaml] [--json]

Prints what it computes (or, with --json, one JSON document; tests/test_examples.py checks it).  Each step is one
or two calls; docs/api.md lists the API and docs/physics.md the model.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import amb_dynamics as amb

REPO = Path(__file__).resolve().parents[1]


def tour(config: Path) -> dict:
    # 1. the rotor: YAML -> validated config (overrides as with --set) -> FE model -> continuous closed loop
    cfg = amb.load_config(config, ["spin_speed_rpm=1000"])
    model = amb.build_structure(cfg)
    loop = amb.closed_loop(model, cfg)

    # 2. closed-loop modes at rest and at 1000 rpm (base at rest)
    modes = {rpm: amb.modes_at_speed(model, loop, rpm) for rpm in (0.0, 1000.0)}
    lowest = modes[1000.0].modes[0]

    # 3. Floquet multipliers of the paper's pitch case: 0.3 rad at 24.5 rad/s, continuous controller
    pitch = amb.BaseMotion.single("pitch", 0.3, 24.5)
    ps = amb.periodic_system(loop, pitch, cfg.spin_rad_s)
    fl = amb.floquet_multipliers(ps)

    # 4. the digital controller the node suite runs (5 kHz, zero-order hold); T/Ts is not a ratio of small
    #    integers here, so Ts is snapped to T/round(T/Ts) (the result says so in its notes)
    digital = amb.sampled_floquet(amb.SampledLoop(model, cfg, forcing=False), pitch, ps.period, snap=True)

    # 5. a small stability chart around that point (one process: workers=1)
    chart = amb.stability_chart(loop, "pitch", [23.5, 24.5, 25.5], [0.0, 0.15, 0.3], cfg.spin_rad_s, workers=1)

    # 6. Newmark time response from the paper's 1 mm disk displacement, 8 base periods of A(t)
    disk_node = cfg.disks[0].node
    x0 = amb.disk_initial_state(model, loop.N, disk_node)
    steps_per_period = 200
    run = amb.newmark_response(ps, model.M, x0, ps.period / steps_per_period, 8 * steps_per_period)
    norms = [float(abs(x).max()) for x in run.x[::steps_per_period]]

    # 7. the sampled-data loop simulated offline, exactly as the nodes run it in lockstep (0.1 s)
    sim = amb.SampledLoop(model, cfg, forcing=False).simulate(pitch, 500, x0[: 2 * model.n])

    return {
        "model": f"{cfg.shaft.elements} elements, {model.n} coordinates, formulation {cfg.formulation}",
        "lowest_mode_1000rpm": {
            "frequency_rad_s": lowest.frequency_rad_s,
            "damping_ratio": lowest.damping_ratio,
            "whirl": lowest.whirl,
        },
        "modes_at_rest": len(modes[0.0].modes),
        "max_real_part_1000rpm": max([m.eigenvalue.real for m in modes[1000.0].modes] + list(modes[1000.0].real_roots)),
        "floquet": {"period_s": fl.period, "max_abs_multiplier": fl.max_abs, "verdict": fl.verdict},
        "floquet_digital": {"max_abs_multiplier": digital.max_abs, "verdict": digital.verdict},
        "chart": {
            "omega_rad_s": chart.omegas.tolist(),
            "amplitude_rad": chart.amplitudes.tolist(),
            "max_abs_multiplier": chart.rho.tolist(),
        },
        "newmark_peak_state_at_periods": norms,
        "sampled_peak_displacement_m": float(abs(sim.y).max()),
    }


def main() -> int:
    amb.limit_blas_threads()  # before numpy is first used in earnest (this script imports it only via amb)
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", type=Path, default=REPO / "config" / "seed_rotor.yaml")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    out = tour(args.config)
    if args.json:
        json.dump(out, sys.stdout, indent=1)
        print()
        return 0
    print(out["model"])
    m = out["lowest_mode_1000rpm"]
    print(f"lowest mode at 1000 rpm: {m['frequency_rad_s']:.3f} rad/s, zeta {m['damping_ratio']:.5f}, {m['whirl']}")
    fl = out["floquet"]
    print(f"pitch 0.3 rad at 24.5 rad/s: max|mu| = {fl['max_abs_multiplier']:.6f} ({fl['verdict']})")
    print(f"  digital 5 kHz loop: max|mu| = {out['floquet_digital']['max_abs_multiplier']:.6f}")
    print("chart max|mu| (rows: omega 23.5, 24.5, 25.5 rad/s; columns: A 0, 0.15, 0.3 rad):")
    for row in out["chart"]["max_abs_multiplier"]:
        print("  " + "  ".join(f"{r:.6f}" for r in row))
    print(
        "Newmark max |x_i| at each period (state, modal coordinates):",
        " ".join(f"{v:.3g}" for v in out["newmark_peak_state_at_periods"]),
    )
    print(f"sampled loop, 0.1 s: peak bearing displacement {out['sampled_peak_displacement_m']:.3g} m")
    return 0


if __name__ == "__main__":
    sys.exit(main())
