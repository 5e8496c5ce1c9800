"""How the default controller rate and plant model were chosen: `.venv/bin/python tools/rate_choice.py`.

Sampled-data Floquet analysis of the digital PD loop at rest (PHYSICS.md 3.3) for several plant models
(modal cutoffs) and rates: max|mu| per sample, and the largest multiplier among the 'digital' modes
(|arg mu|/Ts > 2000 rad/s, the mesh modes that sampling folds near Nyquist).
"""

from __future__ import annotations

import numpy as np

from amb_dynamics.config import load_config, paper_config_path
from amb_dynamics.floquet import sampled_floquet
from amb_dynamics.motion import BaseMotion
from amb_dynamics.sampled import SampledLoop
from amb_dynamics.structure import build_structure

RATES = (1000, 2000, 3000, 4000, 5000, 10000, 20000, 50000)
CUTOFFS = (None, 10000.0, 5000.0, 2000.0)


def at_rest(model, cfg, rate):
    sl = SampledLoop(model, cfg, Ts=1.0 / rate, forcing=False)
    mu = sampled_floquet(sl, BaseMotion(), None).multipliers
    fast = np.abs(mu[np.abs(np.angle(mu)) * rate > 2000.0])
    slow = np.log(np.abs(mu[0])) * rate
    return float(np.abs(mu[0])), float(fast.max()) if fast.size else 0.0, slow


def min_stable_rate(model, cfg, lo=500.0, hi=50000.0):
    if at_rest(model, cfg, hi)[0] >= 1:
        return None
    for _ in range(30):
        mid = np.sqrt(lo * hi)
        lo, hi = (lo, mid) if at_rest(model, cfg, mid)[0] < 1 else (mid, hi)
    return hi


def main():
    print("max|mu| per sample at rest (digital-mode max in brackets); '*' = unstable")
    print("cutoff (rad/s)  n   " + "".join(f"{r:>18d}" for r in RATES) + "   min stable rate")
    for cut in CUTOFFS:
        cfg = load_config(paper_config_path(), [f"modal_cutoff={'null' if cut is None else cut}"])
        model = build_structure(cfg)
        cells = []
        for r in RATES:
            rho, fast, _ = at_rest(model, cfg, r)
            cells.append(f"{rho:.6f}{'*' if rho >= 1 else ' '}({fast:.3f})")
        mr = min_stable_rate(model, cfg)
        print(
            f"{cut or 'full':>14}  {model.n:2d}  " + "".join(f"{c:>18}" for c in cells) + f"   {mr:.0f} Hz"
            if mr
            else "   none below 50 kHz"
        )
    cfg = load_config(paper_config_path())
    model = build_structure(cfg)
    rho, fast, slow = at_rest(model, cfg, cfg.controller.rate_hz)
    print(
        f"\ndefault: {cfg.controller.rate_hz:g} Hz, modal_cutoff {cfg.modal_cutoff:g} rad/s: max|mu| = {rho:.7f} per "
        f"sample (slowest mode decays at {slow:.4f} 1/s), digital modes <= {fast:.3f} per sample, "
        f"stable from {min_stable_rate(model, cfg):.0f} Hz"
    )


if __name__ == "__main__":
    main()
