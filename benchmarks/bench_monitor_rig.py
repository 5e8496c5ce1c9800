"""The stability monitor on the real-rig default config (config/seed_rotor.yaml): speed changes (issue 16).

Offline: ``simulate_rig`` (the plant node's own stepping code and the controller) with every effect of the config
(G2.5 unbalance, runout, sensor and force noise, gravity, actuator and sensor dynamics, nonlinear bearing law,
touchdown bearings), then the monitor's pipeline fed as the node is: samples, and the tachometer (/amb/spin_speed,
every 25 steps, angle wrapped to [0, 2 pi) as the plant publishes it).  Scenarios:

* run-up 500 -> 1500 rpm in 20 s on a static base (the monitor's static-base window: period 0.1 s, 16 periods),
  full state and sensor-only: no flag may go up (the speed nears the 166 rad/s mode at the end);
* the tongue point pitch 0.6 rad at 21.8 rad/s (model max|mu| 1.0606 per T = pi/omega at 1000 rpm) while the speed
  rises slowly, 1000 -> 1060 rpm at 10 rpm/s: the flag must still go up; its time in base periods is printed.
"""

from __future__ import annotations

import math
import time

import numpy as np
from report import record

from amb_dynamics.config import load_config
from amb_dynamics.motion import BaseMotion
from amb_dynamics.rig_loop import simulate_rig
from amb_dynamics.structure import build_structure
from stability_monitor.pipeline import MonitorPipeline, MonitorSettings, synchronous_harmonics

SPIN_EVERY = 25


def simulate(overrides: list[str], motion_args, seconds: float):
    cfg = load_config(None, overrides)
    model = build_structure(cfg)
    motion = BaseMotion.single(*motion_args) if motion_args else BaseMotion.from_config(cfg.base_motion)
    steps = round(seconds * cfg.controller.rate_hz)
    t0 = time.perf_counter()
    run = simulate_rig(model, cfg, motion, steps)
    return cfg, model, run, time.perf_counter() - t0


def monitor(cfg, model, run, sensor_only: bool, period: float, forcing: str):
    """The pipeline over the run as the node sees it; returns (pipeline, estimates, seconds per sample)."""
    n = model.n
    S = run.y if sensor_only else run.x[:, : 2 * n]
    groups = None if sensor_only else tuple([0] * n + [1] * n)
    Ts = run.t[1] - run.t[0]
    angle = np.concatenate([[0.0], np.cumsum(0.5 * (run.spin[1:] + run.spin[:-1]) * Ts)])  # exact for a ramp
    settings = MonitorSettings(sensor_only=sensor_only, period=period, forcing=forcing,
                               synchronous=synchronous_harmonics(-1, cfg))  # fmt: skip
    pl = MonitorPipeline(settings, groups)
    ests = []
    t0 = time.perf_counter()
    for k in range(run.t.size):
        if k % SPIN_EVERY == 0:
            ests += pl.on_spin(run.t[k], math.fmod(angle[k], 2 * math.pi), run.spin[k])
        ests += pl.on_sample(run.t[k], S[k])
    return pl, ests, (time.perf_counter() - t0) / run.t.size


def main() -> dict:
    res = {}
    ramp = ["spin.profile=ramp", "spin.start_rpm=500", "spin.end_rpm=1500", "spin.rate_rpm_s=50",
            "spin_speed_rpm=500", "base_motion.kind=none"]  # fmt: skip
    cfg, model, run, sim_s = simulate(ramp, None, 20.0)
    for mode in ("full", "sensor"):
        pl, ests, cost = monitor(cfg, model, run, mode == "sensor", 0.1, "constant")
        excited = [e.fit.rho for e in ests if e.fit.excited]
        res[f"runup_{mode}"] = {"flag_time_s": pl.flag_time, "refits": len(ests), "excited": len(excited),
                                "max_rho": max(excited, default=None), "cost_us": cost * 1e6}  # fmt: skip
        print(f"run-up 500 -> 1500 rpm in 20 s, static base, {mode}: flag {pl.flag_time}, {len(excited)} of "
              f"{len(ests)} refits identified a map, largest rho {max(excited, default=float('nan')):.4f}, "
              f"{cost * 1e6:.1f} us per sample (simulation {sim_s:.0f} s)")  # fmt: skip
        record(f"false alarms, real rig run-up 500 -> 1500 rpm in 20 s, static base ({mode})",
               [int(pl.flag_time is not None)], "runs", goal="0")  # fmt: skip
    A, W = 0.6, 21.8
    slow = ["spin.profile=ramp", "spin.start_rpm=1000", "spin.end_rpm=1060", "spin.rate_rpm_s=10"]
    cfg, model, run, sim_s = simulate(slow, ("pitch", A, W), 6.0)
    base_period = 2 * math.pi / W
    for mode in ("full", "sensor"):
        pl, ests, cost = monitor(cfg, model, run, mode == "sensor", math.pi / W, "two_periods")
        flag = None if pl.flag_time is None else pl.flag_time / base_period
        res[f"tongue_ramp_{mode}"] = {"flag_base_periods": flag, "final_rho": ests[-1].fit.rho if ests else None}
        print(f"pitch {A} rad at {W} rad/s (model 1.0606 at 1000 rpm) while 1000 -> 1060 rpm at 10 rpm/s, {mode}: "
              f"flag after {flag if flag is None else round(flag, 2)} base periods")  # fmt: skip
        record(f"real rig tongue point (0.6 rad, 21.8 rad/s) during a 10 rpm/s ramp ({mode}): flag after",
               [flag if flag is not None else float("inf")], "base periods", goal="<= 16")  # fmt: skip
    return res


if __name__ == "__main__":
    main()
