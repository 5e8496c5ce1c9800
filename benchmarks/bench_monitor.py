"""Stability monitor: Monte Carlo detection latency and false alarms, and the estimator's cost per update.

Offline Monte Carlo with the core's lockstep-equivalent loop (``estimate_sim.SnapshotSimulator``, 5 kHz, seed
rotor, modal cutoff 5000 rad/s).  Each run starts at a random phase of the base motion from a random
disturbance (random direction, AMB amplitude log-uniform between 0.1x and 10x the forced response), with
random excitation currents (0.05 A rms per axis and sample, the node suite's excitation injection) and 0.1 %
measurement noise (of each channel's RMS) on the AMB sensors; the monitor runs sensor-only (the real-rig mode)
with its default settings and estimates the noise level itself.

- detection: pitch 0.6 rad at omega = pi/(712 Ts) = 22.06 rad/s, rho = 1.0512 per period T = pi/omega;
  latency = first time the latched flag is up, from the start of the run, in periods T (goal: <= 8 in >= 99 %).
- false alarms: pitch 0.3 rad at omega = pi/(641 Ts) = 24.51 rad/s, rho = 0.99879 (closer to 1 than the
  issue's 0.99, hence stricter), 50 periods per run (goal: 0 alarms in 100 runs).
A shorter full-state Monte Carlo (state [q; q'] snapshots) is reported beside it.
"""

from __future__ import annotations

import time

import numpy as np

from amb_dynamics.config import load_config
from amb_dynamics.estimate import fit_period_map
from amb_dynamics.estimate_sim import SnapshotSimulator, add_measurement_noise
from amb_dynamics.estimate_stream import EstimatorConfig, StreamingEstimator
from amb_dynamics.floquet import sampled_floquet
from amb_dynamics.motion import BaseMotion, Harmonic
from amb_dynamics.sampled import SampledLoop
from amb_dynamics.structure import build_structure

DETECT = (0.6, 712)  # amplitude (rad), samples per period T
STABLE = (0.3, 641)
PHASES = (0.0, np.pi / 4, np.pi / 2, 3 * np.pi / 4)  # start phases of the base motion (rad)
EXCITATION_A = 0.05
NOISE = 1e-3
LOCKSTEP_GOAL_STEPS_S = 2000.0  # issue 5's lockstep goal: the monitor's per-sample cost is compared with it


class Case:
    """Simulators (one per start phase) and the model rho of one pitch case."""

    def __init__(self, model, loop, amplitude, N):
        self.model, self.loop, self.N = model, loop, N
        self.T = N * loop.Ts
        w = np.pi / self.T
        self.rho = sampled_floquet(loop, BaseMotion.single("pitch", amplitude, w), self.T).max_abs
        self.sims = [
            SnapshotSimulator(loop, BaseMotion((Harmonic("pitch", amplitude, w, ph),), "pitch")) for ph in PHASES
        ]
        orbit = self.sims[0].periodic_orbit()
        self.forced_amp = float(np.abs(model.Ba.T @ orbit[: model.n]).max())

    def run(self, rng, periods, mode):
        """One random run; returns (t, snapshots with noise, scale groups)."""
        sim = self.sims[rng.integers(len(self.sims))]
        n = self.model.n
        x0 = rng.standard_normal(2 * n)
        x0[n:] *= 2 * np.pi / self.T * 10  # velocities of a mixed-frequency disturbance
        x0 *= self.forced_amp * 10 ** rng.uniform(-1, 1) / np.abs(self.model.Ba.T @ x0[:n]).max()
        run, _ = sim.run(periods * self.N, sim.initial_state(x0), excitation_std=EXCITATION_A, rng=rng)
        S = run.y if mode == "sensor" else run.x
        groups = None if mode == "sensor" else tuple([0] * n + [1] * n)
        return run.t, add_measurement_noise(S, NOISE, rng), groups

    def monitor(self, t, S, groups, stop_on_flag):
        cfg = EstimatorConfig(self.T, self.loop.Ts, forcing="alternating", scale_groups=groups)
        est = StreamingEstimator(cfg, S.shape[1])
        first, rho_max = None, 0.0
        for k in range(t.size):
            e = est.push(t[k], S[k])
            if e is None:
                continue
            if e.fit.excited:
                rho_max = max(rho_max, e.rho)
            if e.unstable and first is None:
                first = e.time / self.T
                if stop_on_flag:
                    break
        return first, rho_max


def monte_carlo(case: Case, runs: int, periods: int, mode: str, seed: int, detect: bool) -> dict:
    rng = np.random.default_rng(seed)
    flags, rho_max = [], []
    for _ in range(runs):
        t, S, groups = case.run(rng, periods, mode)
        first, rmax = case.monitor(t, S, groups, stop_on_flag=detect)
        flags.append(np.inf if first is None else first)
        rho_max.append(rmax)
    flags = np.array(flags)
    out = {"runs": runs, "periods_per_run": periods, "model_rho": case.rho, "max_rho_hat": float(max(rho_max))}
    if detect:
        ok = flags <= 8.0
        out.update(
            detected_within_8_periods_fraction=float(ok.mean()),
            latency_periods_p50=float(np.median(flags)),
            latency_periods_p99=float(np.percentile(flags, 99)),
            latency_periods_max=float(flags.max()),
        )
    else:
        out["false_alarms"] = int(np.isfinite(flags).sum())
    return out


def cost_per_update(case: Case) -> dict:
    """Wall time of one refit (sensor-only and full state) and of one sample push, averaged."""
    rng = np.random.default_rng(7)
    out = {}
    for mode in ("sensor", "full"):
        t, S, groups = case.run(rng, 20, mode)
        cfg = EstimatorConfig(case.T, case.loop.Ts, forcing="alternating", scale_groups=groups)
        est = StreamingEstimator(cfg, S.shape[1])
        t0 = time.perf_counter()
        for k in range(t.size):
            est.push(t[k], S[k])
        per_sample = (time.perf_counter() - t0) / t.size
        Z, scale = est.window_matrix()
        noise = np.tile(est.noise_estimate() / scale, cfg.phases)
        reps = 50
        t0 = time.perf_counter()
        for _ in range(reps):
            fit_period_map(Z, cfg.forcing, noise, cfg.method, cfg.max_rank)
        out[mode] = {
            "refit_ms": (time.perf_counter() - t0) / reps * 1e3,
            "window_shape": list(Z.shape),
            "per_sample_us_incl_refits": per_sample * 1e6,
            "fraction_of_lockstep_step": per_sample * LOCKSTEP_GOAL_STEPS_S,
        }
    return out


def main() -> dict:
    cfg = load_config()
    model = build_structure(cfg)
    loop = SampledLoop(model, cfg)
    t0 = time.perf_counter()
    det, stab = Case(model, loop, *DETECT), Case(model, loop, *STABLE)
    res = {
        "detection_sensor": monte_carlo(det, 200, 12, "sensor", 1, True),
        "false_alarm_sensor": monte_carlo(stab, 100, 50, "sensor", 2, False),
        "detection_full_state": monte_carlo(det, 50, 12, "full", 3, True),
        "false_alarm_full_state": monte_carlo(stab, 20, 50, "full", 4, False),
        "cost": cost_per_update(det),
    }
    res["wall_s"] = time.perf_counter() - t0
    d, f = res["detection_sensor"], res["false_alarm_sensor"]
    print("stability monitor, seed rotor, 5 kHz, sensor-only, 0.1 % noise, 0.05 A excitation, random start")
    print(
        f"  detection rho = {d['model_rho']:.4f}: within 8 periods in"
        f" {100 * d['detected_within_8_periods_fraction']:.1f} %"
        f" of {d['runs']} runs (goal >= 99 %); latency p50 {d['latency_periods_p50']:.2f}, p99"
        f" {d['latency_periods_p99']:.2f}, max {d['latency_periods_max']:.2f} periods T = pi/omega"
    )
    print(
        f"  false alarms rho = {f['model_rho']:.5f}: {f['false_alarms']} in {f['runs']} runs of 50 periods"
        f" (goal 0); largest rho_hat {f['max_rho_hat']:.4f}"
    )
    d, f = res["detection_full_state"], res["false_alarm_full_state"]
    print(
        f"  full state: detection {100 * d['detected_within_8_periods_fraction']:.1f} % of {d['runs']} within 8"
        f" (p99 {d['latency_periods_p99']:.2f}); false alarms {f['false_alarms']} in {f['runs']} runs"
    )
    for mode, c in res["cost"].items():
        print(
            f"  cost {mode:6s}: refit {c['refit_ms']:.2f} ms on a {c['window_shape'][0]}x{c['window_shape'][1]} window;"
            f" {c['per_sample_us_incl_refits']:.1f} us per sample incl. refits ="
            f" {100 * c['fraction_of_lockstep_step']:.1f} % of a lockstep step at {LOCKSTEP_GOAL_STEPS_S:.0f} steps/s"
        )
    print(f"  wall time {res['wall_s']:.0f} s")
    return res


if __name__ == "__main__":
    main()
