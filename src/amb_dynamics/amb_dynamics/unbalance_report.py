"""``amb-dynamics unbalance``: steady-state unbalance response of the linear closed loop, JSON and Bode plot.

The continuous closed loop on the full FE model (as every continuous analysis), base at rest, constant spin.
Channels are named by node as the AMB channels are: amb<node>_y/z at the AMBs, disk<node>_y/z at the disks.
Amplitudes are 0-peak (m); the phase is that of y(t) = A cos(phi(t) + phase) against the spin angle phi, whose
zero puts the heavy spot of a disk with unbalance_phase_deg 0 on +Y.
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import numpy as np

from .config import load_config
from .errors import InputError
from .structure import build_structure
from .system import closed_loop
from .unbalance import SynchronousResponse, Unbalance, channels

SCHEMA_VERSION = 1
SWEEP_POINTS = 1000


def add_parser(sub, common) -> None:
    """The ``unbalance`` subcommand (``common`` adds --config, --set, --json)."""
    from .cli import grid

    p = sub.add_parser("unbalance", help="steady-state unbalance response (amplitude, phase) at spin speeds")
    common(p)
    p.add_argument("--speed-rpm", type=float, nargs="+", default=None, help="speeds (default: the config's spin)")
    p.add_argument("--speeds", type=grid, default=None, help="plot sweep lo:hi:n rpm (default 0:max speed:1000)")
    p.add_argument("--out", type=Path, default=None, help="write a Bode plot (PNG) of the sweep with critical speeds")


def run_unbalance(args: argparse.Namespace):
    cfg = load_config(args.config, list(args.overrides))
    model = build_structure(dataclasses.replace(cfg, modal_cutoff=None))  # continuous: the full FE model
    resp = SynchronousResponse(model, closed_loop(model, cfg), Unbalance.from_config(cfg))
    speeds = np.array(args.speed_rpm if args.speed_rpm is not None else [cfg.spin_speed_rpm], dtype=float)
    if not np.all(np.isfinite(speeds)):
        raise InputError("--speed-rpm values must be finite numbers")
    chans = channels(cfg)
    y = resp.displacements(speeds)[:, [i for _, i in chans]]
    data = {
        "schema_version": SCHEMA_VERSION,
        "speeds": [
            {
                "speed_rpm": float(s),
                "amplitude_m": {name: float(abs(v)) for (name, _), v in zip(chans, row, strict=True)},
                "phase_deg": {name: float(np.degrees(np.angle(v))) for (name, _), v in zip(chans, row, strict=True)},
            }
            for s, row in zip(speeds, y, strict=True)
        ],
    }
    lines = ["speed (rpm)  " + "  ".join(f"{name:>20s}" for name, _ in chans) + "   (0-peak m @ phase deg)"]
    for s, row in zip(speeds, y, strict=True):
        lines.append(f"{s:11.1f}  " + "  ".join(f"{abs(v):11.4e} @{np.degrees(np.angle(v)):7.1f}" for v in row))
    if args.out is not None:
        top = cfg.max_speed_rpm or 3000.0
        sweep = args.speeds if args.speeds is not None else np.linspace(top / SWEEP_POINTS, top, SWEEP_POINTS)
        crit = resp.critical_speeds_rpm(float(sweep.min()), float(sweep.max()))
        ys = resp.displacements(sweep)[:, [i for _, i in chans]]
        png = bode_figure(
            sweep, ys, [n for n, _ in chans], crit, f"Unbalance response: {Path(cfg.source).name}", args.out
        )
        lines.append(f"critical speeds (rpm): {', '.join(f'{c:.1f}' for c in crit) or 'none in range'}")
        lines.append(f"PNG: {png}")
    return data, "\n".join(lines)


def bode_figure(speeds, y, names, critical, title, out):
    """Amplitude (log) and phase of each channel against speed, critical speeds as dashed lines."""
    from .plots import _save, plt

    fig, (ax_a, ax_p) = plt.subplots(2, 1, figsize=(8, 7), sharex=True, gridspec_kw={"height_ratios": [3, 2]})
    amp = np.abs(y)
    nodes = list(dict.fromkeys(n.rsplit("_", 1)[0] for n in names))
    for j, name in enumerate(names):
        color = f"C{nodes.index(name.rsplit('_', 1)[0])}"
        style = "-" if name.endswith("_y") else ":"
        ax_a.semilogy(speeds, amp[:, j], style, color=color, lw=1.2, label=name)
        if name.endswith("_y"):  # z lags y by 90 degrees in a forward circular orbit
            ax_p.plot(speeds, np.degrees(np.angle(y[:, j])), color=color, lw=1.0, label=name)
    ax_a.set_ylim(max(amp[amp > 0].min(initial=amp.max()), 1e-4 * amp.max()), 2 * amp.max())
    for c in critical:
        for ax in (ax_a, ax_p):
            ax.axvline(c, color="k", ls="--", lw=0.8)
        ax_a.annotate(f"{c:.0f} rpm", (c, 1.0), xycoords=("data", "axes fraction"), va="top", ha="left", fontsize=8)
    ax_a.set_ylabel("amplitude, 0-peak (m)")
    ax_a.legend(ncol=3, fontsize=8)
    ax_a.grid(alpha=0.3, which="both")
    ax_p.set_ylabel("phase of y (deg)")
    ax_p.set_xlabel("spin speed (rpm)")
    ax_p.set_yticks(range(-180, 181, 90))
    ax_p.grid(alpha=0.3)
    fig.suptitle(title)
    fig.tight_layout()
    return _save(fig, out)
