"""rho(t) of an analysed run against the model value (matplotlib, written to a PNG)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from amb_dynamics.errors import InputError


def plot_rho(analysis, out: Path, margin: float, z: float) -> Path:
    """Estimated rho with its +-z standard-error band, the flag threshold, the model rho and the flag time."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    est = [e for e in analysis.estimates if e.fit.excited]
    if not est:
        raise InputError("no estimate identified the map (insufficient excitation everywhere): nothing to plot")
    t = np.array([e.time for e in est])
    rho = np.array([e.rho for e in est])
    sd = np.array([e.fit.rho_std for e in est])
    fig, ax = plt.subplots(figsize=(8, 4.5))
    ax.plot(t, rho, ".-", lw=1, ms=3, label=r"estimated $\rho$")
    ok = np.isfinite(sd)
    ax.fill_between(t[ok], (rho - z * sd)[ok], (rho + z * sd)[ok], alpha=0.25, label=rf"$\pm{z:g}$ std")
    ax.axhline(1.0, color="k", lw=0.8)
    ax.axhline(1.0 + margin, color="r", lw=0.8, ls=":", label=f"flag threshold 1 + {margin:g}")
    model = analysis.model or {}
    if "rho" in model:
        ax.axhline(model["rho"], color="g", ls="--", label=rf"model $\rho$ = {model['rho']:.5f}")
    if analysis.pipeline.flag_time is not None:
        ax.axvline(analysis.pipeline.flag_time, color="r", lw=1, label="unstable flag raised")
    pe = analysis.pipeline.period_estimate
    period = f", T = {pe.period:.6g} s" if pe else ""
    ax.set(xlabel="time (s)", ylabel=r"$\rho = \max|\mu|$ per period", title=f"{Path(analysis.bag).name}{period}")
    lo, hi = np.nanmin(rho), np.nanmax(rho)
    ax.set_ylim(min(lo, 0.95) - 0.01, max(hi, 1.0 + margin) + 0.02)
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    plt.close(fig)
    return out
