"""Figures (matplotlib, Agg): Campbell diagram, stability chart, time response.  Takes results, computes nothing."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from .modes import ModalResult

WHIRL_STYLE = {"forward": ("tab:red", "^", "forward whirl"), "backward": ("tab:blue", "v", "backward whirl")}


def _save(fig, out: Path | str) -> Path:
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.stem + ".part" + out.suffix)
    fig.savefig(tmp, dpi=120)
    plt.close(fig)
    tmp.replace(out)  # nothing half-written is left behind
    return out


def campbell_figure(results: list[ModalResult], title: str, out: Path | str, max_frequency: float | None = None):
    """Damped frequencies and damping ratios vs spin speed, forward/backward whirl marked."""
    fig, (ax_f, ax_d) = plt.subplots(2, 1, figsize=(8, 8), sharex=True, gridspec_kw={"height_ratios": [3, 2]})
    speeds = np.array([r.speed_rpm for r in results])
    for whirl, (color, marker, label) in WHIRL_STYLE.items():
        xs, fs, ds = [], [], []
        for r in results:
            for m in r.modes:
                if m.whirl == whirl and (max_frequency is None or m.frequency_rad_s <= max_frequency):
                    xs.append(r.speed_rpm)
                    fs.append(m.frequency_rad_s)
                    ds.append(m.damping_ratio)
        ax_f.scatter(xs, fs, s=10, c=color, marker=marker, label=label)
        ax_d.scatter(xs, ds, s=10, c=color, marker=marker, label=label)
    spin = speeds * np.pi / 30
    ax_f.plot(speeds, spin, "k--", lw=1, label="1x spin")
    ax_f.set_ylabel("damped frequency (rad/s)")
    if max_frequency:
        ax_f.set_ylim(0, max_frequency)
    ax_f.legend(loc="upper left")
    ax_f.grid(alpha=0.3)
    ax_d.set_xlabel("spin speed (rpm)")
    ax_d.set_ylabel("damping ratio (-)")
    ax_d.set_yscale("symlog", linthresh=1e-4)
    ax_d.grid(alpha=0.3)
    fig.suptitle(title)
    fig.tight_layout()
    return _save(fig, out)


def chart_figure(omegas: np.ndarray, amplitudes: np.ndarray, rho: np.ndarray, title: str, out: Path | str):
    """Colour map of log10(max|mu|) over (omega, A) with the |mu| = 1 contour."""
    fig, ax = plt.subplots(figsize=(8, 6))
    with np.errstate(divide="ignore"):
        z = np.log10(np.maximum(rho, 1e-300))
    lim = max(float(np.nanmax(np.abs(z))), 1e-6)
    mesh = ax.pcolormesh(omegas, amplitudes, z.T, shading="nearest", cmap="RdBu_r", vmin=-lim, vmax=lim)
    fig.colorbar(mesh, ax=ax, label="log10 max|mu|  (>0: unstable)")
    if (rho > 1).any() and (rho < 1).any():
        ax.contour(omegas, amplitudes, rho.T, levels=[1.0], colors="k", linewidths=1.2)
    ax.set_xlabel("base-motion frequency omega (rad/s)")
    ax.set_ylabel("base-motion amplitude A (rad)")
    ax.set_title(title)
    fig.tight_layout()
    return _save(fig, out)


def response_figure(
    t: np.ndarray, disp: np.ndarray, labels: list[str], strobe: tuple, fit: tuple | None, title: str, out: Path | str
):
    """Disk displacement (m) vs time, and the state norm at t = kT with its fitted exponential (t0, slope, c)."""
    fig, (ax, ax_log) = plt.subplots(2, 1, figsize=(9, 7), sharex=True)
    for j, lab in enumerate(labels):
        ax.plot(t, disp[:, j] * 1e3, lw=0.8, label=lab)
    ax.set_ylabel("displacement (mm)")
    ax.legend(loc="upper right")
    ax.grid(alpha=0.3)
    ts, norms = strobe
    ax_log.semilogy(ts, np.maximum(norms, 1e-300), ".", ms=3, label="||x(kT)|| (state norm, once per period)")
    if fit is not None:
        tt, slope, c0 = fit
        ax_log.semilogy(tt, np.exp(c0 + slope * tt), "k--", lw=1.2, label=f"least-squares fit: sigma = {slope:.4g} 1/s")
    ax_log.set_xlabel("time (s)")
    ax_log.set_ylabel("state norm")
    ax_log.legend(loc="best")
    ax_log.grid(alpha=0.3, which="both")
    fig.suptitle(title)
    fig.tight_layout()
    return _save(fig, out)
