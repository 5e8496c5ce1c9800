"""``amb-dynamics simulate --sampled``: the digital loop offline on the rig plant (rig_loop.simulate_rig), the same
stepping code as the plant node, with every effect of the config; a PNG of the AMB orbits, displacements and
spin speed, and a JSON summary (peaks against the touchdown clearance and the air gap, contacts)."""

from __future__ import annotations

import numpy as np

from .errors import InputError
from .iso14839 import clearance_of, vibration_zones
from .rig_loop import simulate_rig


def run_sampled(s, motion, args, describe) -> tuple[dict, str]:
    """Setup ``s`` (cfg, model), base ``motion``: the offline rig run of args.duration seconds."""
    cfg, model = s.cfg, s.model
    Ts = 1.0 / cfg.controller.rate_hz
    steps = round(args.duration / Ts)
    if steps < 1:
        raise InputError("--duration must cover at least one sample")
    fail = args.fail_at_s
    run = simulate_rig(model, cfg, motion, steps, fail_at_s=fail)
    peak = np.abs(run.displacement).max(axis=0)
    clearance = cfg.touchdown.clearance
    data = {
        "model": describe(cfg, model),
        "mode": "sampled (rig plant)",
        "duration_s": float(run.t[-1]),
        "steps": steps,
        "rate_hz": cfg.controller.rate_hz,
        "peak_displacement_m": {c: float(p) for c, p in zip(model.channels, peak, strict=True)},
        "peak_over_air_gap": float(peak.max() / cfg.bearings.air_gap),
        "touchdown_clearance_m": clearance,
        "spin_rpm": [float(run.spin[0] * 30 / np.pi), float(run.spin[-1] * 30 / np.pi)],
        "contacts": [
            {"t_s": ev[0], "node": ev[1], "penetration_m": ev[2], "peak_force_n": ev[3], "end_s": ev[4]}
            for ev in run.contacts
        ],
    }
    # ISO 14839-2 grade of the run's last second (its end, not its start-up transient)
    tail = run.displacement[-min(len(run.t), max(1, round(1.0 / Ts))) :]
    iso = cfg.iso14839
    zones = vibration_zones({c: tail[:, j] for j, c in enumerate(model.channels)}, clearance_of(cfg),
                            iso.vibration_zone_limits, iso.vibration_measure)  # fmt: skip
    data["vibration_last_s"] = {c: z.to_dict() for c, z in zones.items()}
    if args.out:
        data["png"] = str(plot_rig_run(run, model.channels, clearance, cfg.bearings.air_gap, args.out))
    lines = [data["model"], f"sampled-data rig loop, {steps} steps at {cfg.controller.rate_hz:g} Hz"]
    lines += [f"  peak {c}: {p * 1e6:.2f} um" for c, p in data["peak_displacement_m"].items()]
    lines.append(f"  touchdown contacts: {len(run.contacts)}")
    window = f"last {(len(tail) - 1) * Ts:.3g} s" if len(tail) < round(1.0 / Ts) else "last second"  # a short run
    lines += [f"  {window} {c}: {z.displacement_m * 1e6:.2f} um {z.measure}, ISO 14839-2 zone {z.zone or '-'}"
              for c, z in zones.items()]  # fmt: skip
    return data, "\n".join(lines)


def plot_rig_run(run, channels, clearance, air_gap, out):
    """Orbits at both AMBs inside their clearance circles, displacement vs time, spin speed (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 4, figsize=(18, 4.2))
    circle = np.linspace(0, 2 * np.pi, 200)
    for j in range(2):
        a = ax[j]
        a.plot(run.displacement[:, 2 * j + 1] * 1e6, run.displacement[:, 2 * j] * 1e6, lw=0.6)
        for r, style, label in ((clearance, "r--", "touchdown clearance"), (air_gap, "k:", "air gap")):
            if r:
                a.plot(r * 1e6 * np.cos(circle), r * 1e6 * np.sin(circle), style, lw=1, label=label)
        a.set_aspect("equal")
        a.set_xlabel("z (um)")
        a.set_ylabel("y (um)")
        a.set_title(f"orbit at {channels[2 * j][:-2]}")
        a.legend(loc="upper right", fontsize=7)
        # the orbit itself is microns inside millimetre clearances: an inset at its own scale
        inset = a.inset_axes((0.06, 0.06, 0.34, 0.34))
        inset.plot(run.displacement[:, 2 * j + 1] * 1e6, run.displacement[:, 2 * j] * 1e6, lw=0.4)
        inset.set_aspect("equal", adjustable="datalim")
        inset.tick_params(labelsize=6)
        inset.set_title("zoom (um)", fontsize=6)
    for c in range(4):
        ax[2].plot(run.t, run.displacement[:, c] * 1e6, lw=0.6, label=channels[c])
    ax[2].set_xlabel("t (s)")
    ax[2].set_ylabel("displacement (um)")
    ax[2].legend(fontsize=7)
    ax[3].plot(run.t, run.spin * 30 / np.pi)
    ax[3].set_xlabel("t (s)")
    ax[3].set_ylabel("spin speed (rpm)")
    for ev in run.contacts[:50]:
        ax[2].axvline(ev[0], color="r", lw=0.3)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out
