"""Monte Carlo of the stability monitor on a rig's own disturbances (ROS-free; benchmarks/bench_monitor_rig.py).

One run: the rig loop offline (``rig_loop.simulate_rig``, the plant node's stepping code and the controller) with
every effect of the config, its noise seed and the disk's unbalance phase drawn per run; then the monitor's
pipeline over the run fed as the node is fed (the samples, and the tachometer /amb/spin_speed every
``SPIN_EVERY`` steps with the angle wrapped to [0, 2 pi) as the plant publishes it), with the full state and with
the four AMB displacements (sensor-only) on the same signals.  ``mc_run`` is a module-level function of plain
arguments returning arrays, so that ``dask_exec.ChunkRunner`` can run it on Dask workers.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np

from amb_dynamics.config import load_config
from amb_dynamics.motion import BaseMotion
from amb_dynamics.rig_loop import simulate_rig
from amb_dynamics.structure import build_structure

from .pipeline import MonitorPipeline, MonitorSettings, synchronous_harmonics

SPIN_EVERY = 25  # the plant's tachometer: one /amb/spin_speed message per 25 samples
MODES = ("full", "sensor")


def simulate(overrides: list[str], motion_args, seconds: float):
    """(cfg, model, run, seconds of CPU) of the rig loop over ``seconds`` (motion: the config's, or ``motion_args``
    (kind, amplitude, frequency))."""
    cfg = load_config(None, overrides)
    model = build_structure(cfg)
    motion = BaseMotion.single(*motion_args) if motion_args else BaseMotion.from_config(cfg.base_motion)
    steps = round(seconds * cfg.controller.rate_hz)
    t0 = time.perf_counter()
    run = simulate_rig(model, cfg, motion, steps)
    return cfg, model, run, time.perf_counter() - t0


def monitor(cfg, model, run, sensor_only: bool, period: float, forcing: str, static_base: bool = False):
    """The pipeline over the run as the node sees it; returns (pipeline, estimates, seconds per sample).

    The period is given, not found from base rates (none are fed): ``static_base`` takes the window the node
    uses when the base rates show a static base (``static_window``), else that of a moving base."""
    n = model.n
    S = run.y if sensor_only else run.x[:, : 2 * n]
    groups = None if sensor_only else tuple([0] * n + [1] * n)
    Ts = run.t[1] - run.t[0]
    angle = np.concatenate([[0.0], np.cumsum(0.5 * (run.spin[1:] + run.spin[:-1]) * Ts)])  # exact for a ramp
    settings = MonitorSettings(sensor_only=sensor_only, period=period, forcing=forcing,
                               synchronous=synchronous_harmonics(-1, cfg))  # fmt: skip
    if static_base:
        settings = replace(settings, window=settings.static_window)
    pl = MonitorPipeline(settings, groups)
    ests = []
    t0 = time.perf_counter()
    for k in range(run.t.size):
        if k % SPIN_EVERY == 0:
            ests += pl.on_spin(run.t[k], math.fmod(angle[k], 2 * math.pi), run.spin[k])
        ests += pl.on_sample(run.t[k], S[k])
    return pl, ests, (time.perf_counter() - t0) / run.t.size


def mc_run(overrides: tuple[str, ...], seconds: float, period: float, forcing: str, seed: int) -> dict:
    """One Monte Carlo run: noise seed ``seed``, unbalance phase uniform in [0, 360) deg from the same seed.

    Returns arrays: ``sim_s``; per mode (full, sensor) ``<mode>_flag_s`` (NaN: never raised), ``<mode>_cost_s``
    (per sample), ``<mode>_t`` and ``<mode>_rho`` (the excited estimates, in order)."""
    phase = float(np.random.default_rng(seed).uniform(0.0, 360.0))
    sets = [*overrides, f"disturbances.seed={seed}", f"disks.0.unbalance_phase_deg={phase!r}"]
    cfg, model, run, sim_s = simulate(sets, None, seconds)
    out = {"sim_s": np.array(sim_s), "unbalance_phase_deg": np.array(phase)}
    for mode in MODES:
        pl, ests, cost = monitor(cfg, model, run, mode == "sensor", period, forcing)
        out[f"{mode}_flag_s"] = np.array(np.nan if pl.flag_time is None else pl.flag_time)
        out[f"{mode}_cost_s"] = np.array(cost)
        out[f"{mode}_t"] = np.array([e.time for e in ests if e.fit.excited])
        out[f"{mode}_rho"] = np.array([e.fit.rho for e in ests if e.fit.excited])
    return out
