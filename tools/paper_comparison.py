"""Reproduce docs/paper-comparison.md's figures and numbers: `.venv/bin/python tools/paper_comparison.py`.

The seed paper's three claims (PHYSICS.md 9) against this software's `seed` and `derived` formulations.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from amb_dynamics import plots
from amb_dynamics.chart import stability_chart
from amb_dynamics.config import load_config, paper_config_path
from amb_dynamics.floquet import floquet
from amb_dynamics.motion import BaseMotion
from amb_dynamics.structure import build_structure
from amb_dynamics.system import closed_loop, periodic_system

DOCS = Path(__file__).resolve().parents[1] / "docs"
OMEGAS = np.linspace(1.0, 40.0, 157)
AMPS = np.linspace(0.0, 0.5, 101)
POINTS = {
    "fig5_pitch_15_0.4": ("pitch", 0.4, 15.0),
    "fig8_pitch_24.5_0.3": ("pitch", 0.3, 24.5),
    "fig6_roll_3_0.25": ("roll", 0.25, 3.0),
}


def main() -> dict:
    out: dict = {"charts": {}, "points": {}}
    for form in ("derived", "seed"):
        cfg = load_config(paper_config_path(), [f"formulation={form}", "modal_cutoff=null"])  # continuous: full FE
        model = build_structure(cfg)
        loop = closed_loop(model, cfg)
        for kind in ("pitch", "roll"):
            steps = 32 if kind == "pitch" else 64
            res = stability_chart(loop, kind, OMEGAS, AMPS, cfg.spin_rad_s, steps=steps, progress=True)
            png = plots.chart_figure(
                OMEGAS,
                AMPS,
                res.rho,
                f"seed rotor, {form} formulation, {kind}: max|mu|",
                DOCS / f"chart_{kind}_{form}.png",
            )
            unstable = res.rho > 1 + 1e-6
            first = [float(OMEGAS[i]) for i in range(OMEGAS.size) if unstable[i].any()]
            out["charts"][f"{kind}_{form}"] = {
                "png": png.name,
                "max_abs_multiplier": float(res.rho.max()),
                "unstable_points": int(unstable.sum()),
                "points": int(res.rho.size),
                "lowest_unstable_omega_rad_s": min(first) if first else None,
                "lowest_unstable_amplitude_rad": float(AMPS[np.argmax(unstable.any(axis=0))]) if first else None,
            }
        for name, (kind, A, w) in POINTS.items():
            ps = periodic_system(loop, BaseMotion.single(kind, A, w), cfg.spin_rad_s)
            r = floquet(ps)
            out["points"][f"{name}_{form}"] = {
                "max_abs_multiplier": r.max_abs,
                "verdict": r.verdict,
                "growth_rate_1_s": float(np.log(r.max_abs) / ps.period),
            }
    (DOCS / "paper-comparison.json").write_text(json.dumps(out, indent=1))
    print(json.dumps(out, indent=1))
    return out


if __name__ == "__main__":
    main()
