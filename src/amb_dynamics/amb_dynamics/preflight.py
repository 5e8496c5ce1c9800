"""The digital loop's verdict before anything runs: is the sampled-data loop stable at rest at the config's rate?

With the base at rest the loop is time-invariant: one step map F (``SampledLoop.step_map``) and its spectral
radius rho per sample decide (rho < 1: stable).  A nonlinear bearing law is linearised where the rotor rests, at
the levitated operating point (gravity and bias offsets: :func:`amb_dynamics.rig_loop.levitated_bearing`), the
point the rig starts from and the sensitivity model and the monitor's model value use.  Used by ``modes`` and
``campbell`` (per spin speed) and by ``amb-rig run`` (refuses an unstable loop unless --force), which also gets a
stable rate from a quick search, and the loop's delay margin (:mod:`amb_dynamics.delay_margin`) when it is stable.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .config import RotorConfig
from .delay_margin import delay_margin, margin_text
from .rig_loop import levitated_bearing
from .sampled import SampledLoop
from .structure import StructuralModel, build_structure

RATE_FACTOR = 1.25  # geometric search upward from the config's rate
MAX_RATE_HZ = 1.0e6  # the config's upper limit of controller.rate_hz
BISECTIONS = 6
MARGIN = 1e-12  # rho per sample must be below 1 - MARGIN (rounding only: slow modes give rho = 1 - 2e-6)


def digital_at_rest(model: StructuralModel, cfg: RotorConfig, rate_hz: float | None = None) -> dict:
    """Spectral radius per sample of the digital loop with the base at rest, at ``rate_hz`` (default: the config's)
    and the config's delay and spin speed, about the levitated operating point; the slowest-decaying discrete pole
    as an equivalent growth rate (1/s)."""
    rate = cfg.controller.rate_hz if rate_hz is None else rate_hz
    Ts = 1.0 / rate
    loop = SampledLoop(model, cfg, Ts=Ts, forcing=False, bearing=levitated_bearing(model, cfg, Ts))
    mu = np.linalg.eigvals(loop.step_map(np.zeros(3), np.zeros(3)))
    k = int(np.argmax(np.abs(mu)))
    rho = float(abs(mu[k]))
    return {
        "rate_hz": rate,
        "delay_samples": loop.delay,
        "spin_speed_rpm": cfg.spin_speed_rpm,
        "spectral_radius_per_sample": rho,
        "margin": 1.0 - rho,
        "growth_rate_1_s": float(np.log(max(rho, 1e-300)) * rate),
        "frequency_rad_s": float(abs(np.angle(mu[k])) * rate),
        "stable": bool(rho < 1.0 - MARGIN),
    }


def digital_over_speeds(model: StructuralModel, cfg: RotorConfig, speeds_rpm) -> list[dict]:
    """:func:`digital_at_rest` at each spin speed (rpm)."""
    return [digital_at_rest(model, dataclasses.replace(cfg, spin_speed_rpm=float(v))) for v in speeds_rpm]


def stable_rate(model: StructuralModel, cfg: RotorConfig) -> float | None:
    """A controller rate (Hz) at which the loop at rest is stable: geometric steps up from the config's rate, then
    bisection toward the last unstable one; every reported rate is checked.  None if none up to 1 MHz."""
    lo, hi = cfg.controller.rate_hz, None
    rate = lo
    while rate <= MAX_RATE_HZ:
        if digital_at_rest(model, cfg, rate)["stable"]:
            hi = rate
            break
        lo, rate = rate, rate * RATE_FACTOR
    if hi is None:
        return None
    for _ in range(BISECTIONS):
        mid = 0.5 * (lo + hi)
        if digital_at_rest(model, cfg, mid)["stable"]:
            hi = mid
        else:
            lo = mid
    rounded = float(np.ceil(hi / 100.0) * 100.0)  # a round number when it is stable too
    return rounded if digital_at_rest(model, cfg, rounded)["stable"] else float(hi)


def rig_preflight(cfg: RotorConfig) -> tuple[bool, str]:
    """(stable, one line) for ``amb-rig run``: the digital loop at rest at the config's rate and delay, and when it
    is stable its delay margin (how much later than its own delay a command may act)."""
    model = build_structure(cfg)
    d = digital_at_rest(model, cfg)
    head = (
        f"the digital loop at {d['rate_hz']:g} Hz (delay {d['delay_samples']}) is "
        f"{'stable' if d['stable'] else 'UNSTABLE'} at rest: max|mu| per sample {d['spectral_radius_per_sample']:.6g}"
    )
    if d["stable"]:
        return True, f"{head}; {margin_text(delay_margin(model, cfg))}"
    rate = stable_rate(model, cfg)
    hint = (
        f"; stable at {rate:g} Hz (--set controller.rate_hz={rate:g})"
        if rate is not None
        else "; no stable rate up to 1 MHz: reduce the plant model (modal_cutoff) or change the gains"
    )
    return False, head + hint
