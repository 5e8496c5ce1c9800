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
from amb_dynamics.rig_loop import RigStepper, simulate_rig
from amb_dynamics.structure import build_structure

from .pipeline import MonitorPipeline, MonitorSettings, synchronous_harmonics

SPIN_EVERY = 25  # the plant's tachometer: one /amb/spin_speed message per 25 samples
MODES = ("full", "sensor")


CHUNK_S = 0.25  # a Monte Carlo run that stops once flagged checks its monitors this often (simulated s)


def _setup(overrides, motion_args, seconds: float):
    cfg = load_config(None, overrides)
    model = build_structure(cfg)
    motion = BaseMotion.single(*motion_args) if motion_args else BaseMotion.from_config(cfg.base_motion)
    return cfg, model, motion, round(seconds * cfg.controller.rate_hz)


def simulate(overrides: list[str], motion_args, seconds: float):
    """(cfg, model, run, seconds of CPU) of the rig loop over ``seconds`` (motion: the config's, or ``motion_args``
    (kind, amplitude, frequency))."""
    cfg, model, motion, steps = _setup(overrides, motion_args, seconds)
    t0 = time.perf_counter()
    run = simulate_rig(model, cfg, motion, steps)
    return cfg, model, run, time.perf_counter() - t0


class MonitorFeed:
    """The pipeline fed a run's samples as the node is fed them, a chunk at a time (``feed(run, k_end)``).

    The period is given, not found from base rates (none are fed): ``static_base`` takes the window the node
    uses when the base rates show a static base (``static_window``), else that of a moving base."""

    def __init__(self, cfg, n: int, sensor_only: bool, period: float, forcing: str, static_base: bool = False):
        settings = MonitorSettings(sensor_only=sensor_only, period=period, forcing=forcing,
                                   synchronous=synchronous_harmonics(-1, cfg))  # fmt: skip
        if static_base:
            settings = replace(settings, window=settings.static_window)
        self.n, self.sensor_only = n, sensor_only
        self.pl = MonitorPipeline(settings, None if sensor_only else tuple([0] * n + [1] * n))
        self.ests: list = []
        self.k = 0  # samples fed
        self.angle = 0.0  # spin angle at the last sample fed (trapezoidal: exact for a ramp)
        self.seconds = 0.0  # time spent in the pipeline

    def feed(self, run, k_end: int) -> None:
        """Samples self.k .. k_end - 1 of ``run`` (a RigRun, or a RigStepper's arrays)."""
        k0 = self.k
        if k_end <= k0:
            return
        S = run.y if self.sensor_only else run.x[:, : 2 * self.n]
        Ts = run.t[1] - run.t[0]
        lo = max(k0 - 1, 0)  # cumsum from the last angle: the sums of the whole run, in the same order
        steps = 0.5 * (run.spin[lo + 1 : k_end] + run.spin[lo : k_end - 1]) * Ts
        angle = np.cumsum(np.concatenate([[self.angle], steps]))[-(k_end - k0) :]
        t0 = time.perf_counter()
        pl, ests = self.pl, self.ests
        for k in range(k0, k_end):
            if k % SPIN_EVERY == 0:
                ests += pl.on_spin(run.t[k], math.fmod(angle[k - k0], 2 * math.pi), run.spin[k])
            ests += pl.on_sample(run.t[k], S[k])
        self.seconds += time.perf_counter() - t0
        self.k, self.angle = k_end, float(angle[-1])

    @property
    def cost(self) -> float:
        """Seconds per sample in the pipeline."""
        return self.seconds / max(self.k, 1)


def monitor(cfg, model, run, sensor_only: bool, period: float, forcing: str, static_base: bool = False):
    """The pipeline over the whole run as the node sees it; returns (pipeline, estimates, seconds per sample)."""
    feed = MonitorFeed(cfg, model.n, sensor_only, period, forcing, static_base)
    feed.feed(run, run.t.size)
    return feed.pl, feed.ests, feed.cost


def mc_run(overrides: tuple[str, ...], seconds: float, period: float, forcing: str, seed: int,
           stop_on_flags: bool = False) -> dict:  # fmt: skip
    """One Monte Carlo run: noise seed ``seed``, unbalance phase uniform in [0, 360) deg from the same seed.

    With ``stop_on_flags`` the run ends at the first CHUNK_S boundary after every mode has flagged (the flag times
    are those of the whole run: each is its first flag's).  Returns arrays: ``sim_s`` (CPU), ``simulated_s``; per mode
    (full, sensor) ``<mode>_flag_s`` (NaN: never raised), ``<mode>_cost_s`` (per sample), ``<mode>_t`` and
    ``<mode>_rho`` (the excited estimates, in order)."""
    phase = float(np.random.default_rng(seed).uniform(0.0, 360.0))
    sets = [*overrides, f"disturbances.seed={seed}", f"disks.0.unbalance_phase_deg={phase!r}"]
    cfg, model, motion, steps = _setup(sets, None, seconds)
    stepper = RigStepper(model, cfg, motion, steps)
    feeds = {mode: MonitorFeed(cfg, model.n, mode == "sensor", period, forcing) for mode in MODES}
    chunk = max(1, round(CHUNK_S * cfg.controller.rate_hz))
    sim_s = 0.0
    while not stepper.closed:
        t0 = time.perf_counter()
        stepper.advance(stepper.k + chunk)
        sim_s += time.perf_counter() - t0
        for feed in feeds.values():
            feed.feed(stepper, stepper.measured)
        if stop_on_flags and all(f.pl.flag_time is not None for f in feeds.values()):
            break
    out = {"sim_s": np.array(sim_s), "simulated_s": np.array(stepper.t[stepper.measured - 1]),
           "unbalance_phase_deg": np.array(phase)}  # fmt: skip
    for mode, feed in feeds.items():
        out[f"{mode}_flag_s"] = np.array(np.nan if feed.pl.flag_time is None else feed.pl.flag_time)
        out[f"{mode}_cost_s"] = np.array(feed.cost)
        out[f"{mode}_t"] = np.array([e.time for e in feed.ests if e.fit.excited])
        out[f"{mode}_rho"] = np.array([e.fit.rho for e in feed.ests if e.fit.excited])
    return out
