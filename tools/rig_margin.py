"""Stability margin of the digital loop at rest on the model the plant runs: `.venv/bin/python tools/rig_margin.py`.

Sampled-data Floquet analysis (docs/physics.md#sampled) of the config's loop with its amplifier, sensor filter and shaft
damping (amb_dynamics.plant_dynamics), the base at rest, at the config's spin speed: max|mu| per sample, the
largest multiplier among the 'digital' modes (|arg mu|/Ts > 2000 rad/s, near Nyquist) and the lowest stable rate
(bisection).  Options: --config FILE, --set key=value (repeatable), as amb-dynamics.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from amb_dynamics.config import load_config
from amb_dynamics.errors import AmbError
from amb_dynamics.floquet import sampled_floquet
from amb_dynamics.motion import BaseMotion
from amb_dynamics.sampled import SampledLoop
from amb_dynamics.structure import build_structure

FAST_RAD_S = 2000.0


def at_rest(model, cfg, rate: float) -> tuple[float, float, float]:
    """(max|mu| per sample, digital-mode max|mu|, slowest decay rate 1/s) at ``rate`` Hz."""
    sl = SampledLoop(model, cfg, Ts=1.0 / rate, forcing=False)
    mu = sampled_floquet(sl, BaseMotion(), None).multipliers
    fast = np.abs(mu[np.abs(np.angle(mu)) * rate > FAST_RAD_S])
    return float(np.abs(mu[0])), float(fast.max()) if fast.size else 0.0, float(np.log(np.abs(mu[0])) * rate)


def lowest_stable_rate(model, cfg, lo: float = 200.0, hi: float | None = None, iters: int = 20) -> float | None:
    """Bisection (geometric) on the rate between lo and hi for the stability boundary; None if hi is unstable."""
    hi = hi or cfg.controller.rate_hz
    if at_rest(model, cfg, hi)[0] >= 1.0:
        return None
    for _ in range(iters):
        mid = np.sqrt(lo * hi)
        lo, hi = (lo, mid) if at_rest(model, cfg, mid)[0] < 1.0 else (mid, hi)
    return hi


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", default=None)
    ap.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    args = ap.parse_args(argv)
    try:
        cfg = load_config(args.config, args.overrides)
    except AmbError as exc:
        print(f"rig_margin: error: {exc}", file=sys.stderr)
        return 2
    model = build_structure(cfg)
    rate = cfg.controller.rate_hz
    rho, fast, slow = at_rest(model, cfg, rate)
    low = lowest_stable_rate(model, cfg)
    plant = "full FE model" if cfg.modal_cutoff is None else f"modal cutoff {cfg.modal_cutoff:g} rad/s"
    where = f"stable from {low:.0f} Hz ({rate / low:.2f}x rate margin)" if low else "UNSTABLE at this rate"
    print(
        f"{cfg.source}: {plant} ({model.n} coordinates), {rate:g} Hz, at rest, {cfg.spin_speed_rpm:g} rpm: "
        f"max|mu| = {rho:.7f} per sample (slowest mode {slow:.4f} 1/s), digital modes <= {fast:.4f} per sample, "
        f"{where}"
    )
    return 0 if rho < 1.0 else 1


if __name__ == "__main__":
    sys.exit(main())
