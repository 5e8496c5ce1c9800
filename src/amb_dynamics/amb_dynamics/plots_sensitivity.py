"""Bode magnitude of the sensitivity per AMB axis with the ISO 14839-3 zone bands (takes results, computes nothing)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .plots import _save, plt

ZONE_COLORS = ("tab:green", "gold", "tab:orange", "tab:red")


def sensitivity_figure(speeds: list[dict], limits_abs, title: str, out: Path | str, measured: dict | None = None):
    """One panel per axis: 20 log10 |S_jj| vs frequency (Hz), one line per speed, zones A-D shaded, peaks marked.

    ``measured`` (optional): {"axis": name, "frequency_hz": [...], "abs": [...]} drawn as points on its axis.
    """
    axes_names = list(speeds[0]["axes"])
    n = len(axes_names)
    cols = 2 if n > 1 else 1
    rows = (n + cols - 1) // cols
    fig, axs = plt.subplots(rows, cols, figsize=(6 * cols, 3.6 * rows), squeeze=False, sharex=True)
    lim_db = [20 * np.log10(x) for x in limits_abs]
    for k, name in enumerate(axes_names):
        ax = axs[k // cols][k % cols]
        mags = [20 * np.log10(np.asarray(s["abs"][name])) for s in speeds]
        top = max(max(m.max() for m in mags), lim_db[-1]) + 6
        bottom = min(-20.0, min(m.min() for m in mags) - 3)
        edges = [bottom, *lim_db, top]
        for z, color in enumerate(ZONE_COLORS):
            ax.axhspan(edges[z], edges[z + 1], color=color, alpha=0.12, lw=0)
            y = (edges[z] + edges[z + 1]) / 2 if z else lim_db[0] - 3
            ax.text(0.995, y, "ABCD"[z], transform=ax.get_yaxis_transform(), ha="right", va="center", fontsize=8)
        for s in speeds:
            f = np.asarray(s["frequency_hz"])
            mag = 20 * np.log10(np.asarray(s["abs"][name]))
            (line,) = ax.semilogx(f, mag, lw=1.0, label=f"{s['speed_rpm']:g} rpm")
            p = s["axes"][name]
            ax.plot(p["peak_hz"], p["peak_db"], "o", ms=4, color=line.get_color())
        if measured and measured.get("axis") == name:
            ax.semilogx(measured["frequency_hz"], 20 * np.log10(measured["abs"]), "k.", ms=3, label="measured")
        ax.set_ylim(bottom, top)
        ax.set_title(name, fontsize=9)
        ax.set_ylabel("|S| (dB)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7, loc="lower right")
    for ax in axs[-1]:
        ax.set_xlabel("frequency (Hz)")
    for k in range(n, rows * cols):
        axs[k // cols][k % cols].axis("off")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return _save(fig, out)


def measured_figure(report: dict, limits_abs, title: str, out: Path | str):
    """Measured |S_jj| (points, coherence below) with the model beside it (line) and the zone bands."""
    f = np.asarray(report["frequency_hz"])
    mag = 20 * np.log10(np.asarray(report["abs"]))
    fig, (ax, axc) = plt.subplots(2, 1, figsize=(7, 6), sharex=True, gridspec_kw={"height_ratios": [3, 1]})
    lim_db = [20 * np.log10(x) for x in limits_abs]
    curves = [mag] + ([20 * np.log10(np.asarray(report["model_abs"]))] if "model_abs" in report else [])
    top = max(max(c.max() for c in curves), lim_db[-1]) + 6
    bottom = min(-20.0, min(c.min() for c in curves) - 3)
    for z, (a, b) in enumerate(zip([bottom, *lim_db], [*lim_db, top], strict=True)):
        ax.axhspan(a, b, color=ZONE_COLORS[z], alpha=0.12, lw=0)
    if "model_abs" in report:
        ax.semilogx(f, curves[1], "-", color="tab:blue", lw=1.0, label="model (digital loop)")
    ax.semilogx(f, mag, "k.", ms=3, label="measured (H1)")
    ax.set_ylim(bottom, top)
    ax.set_ylabel("|S| (dB)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    axc.semilogx(f, report["coherence"], "k.", ms=3)
    axc.axhline(report.get("min_coherence", 0.9), color="tab:red", lw=0.8)
    axc.set_ylim(0, 1.05)
    axc.set_ylabel("coherence")
    axc.set_xlabel("frequency (Hz)")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return _save(fig, out)
