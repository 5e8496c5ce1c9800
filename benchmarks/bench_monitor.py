"""Stability monitor: Monte Carlo detection latency and false alarms, and the estimator's cost per update.

Offline Monte Carlo with the core's lockstep-equivalent loop (``estimator.sim.SnapshotSimulator``, 5 kHz, seed
rotor, modal cutoff 5000 rad/s).  Every run starts at a random phase of the base motion from a random knock (a
displaced rotor at rest), with random excitation currents (0.005 A rms per axis and sample, the node suite's
excitation injection) and 0.1 % measurement noise (of each channel's RMS); the monitor runs with its default
settings (sensor-only unless said otherwise) and estimates the noise level itself.

- detection: pitch 0.6 rad at omega = pi/(712 Ts) = 22.06 rad/s, rho = 1.0512 per period T = pi/omega;
  latency = first time the latched flag is up, from the start of the run, in periods T.  The issue's goal is
  <= 8 base-motion periods (2 pi/omega = 2 T, so 16 T) in >= 99 % of runs; within 8 T is printed too.
- false alarms: pitch 0.3 rad at omega = pi/(641 Ts) = 24.51 rad/s, rho = 0.99879 (closer to 1 than the
  issue's 0.99, hence stricter), 50 periods per run (goal: 0 alarms in 100 runs).

Scenarios: (A) ``base_forcing=true``: the base motion starts with its inertial load (forced response 50-70 mm
at the AMBs in this linear model; its RMS sets the 0.1 % noise) plus a knock at the disk of 0.1-10x that
amplitude; the forcing model is 'alternating'.  (B) the seed config (no base forcing, forcing model 'none'), a
knock at the disk of 0.1-1 mm in a random direction: every mode is excited, the excitation's fast response is
noise on every period's snapshots, and a weak knock leaves the growing mode under a decaying one of the same
angle; the plateau floor and the variable-projection refinement ('opt') are what make (B) meet the goal.
Then the estimator's cost per update (scenario A's window, and the mean over scenario-B runs, where the
refinement runs) and the lockstep loop's steps/s of amb-rig with its own monitor and with ``--no-monitor``
(alternating runs).
"""

from __future__ import annotations

import json
import multiprocessing
import os
import re
import subprocess
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from amb_dynamics.threads import single_thread_env

os.environ.update(single_thread_env())  # one BLAS thread, set before numpy loads (amb_dynamics/threads.py)
import numpy as np
from report import record

from amb_dynamics.config import load_config, paper_config_path
from amb_dynamics.estimator.fit import fit_period_map
from amb_dynamics.estimator.sim import SnapshotSimulator, add_measurement_noise
from amb_dynamics.estimator.stream import EstimatorConfig, StreamingEstimator
from amb_dynamics.fe import dof_index
from amb_dynamics.floquet import sampled_floquet
from amb_dynamics.motion import BaseMotion, Harmonic
from amb_dynamics.sampled import SampledLoop
from amb_dynamics.structure import build_structure
from amb_ros.env import child_env

DETECT = (0.6, 712)  # amplitude (rad), samples per period T
STABLE = (0.3, 641)
PHASES = (0.0, np.pi / 4, np.pi / 2, 3 * np.pi / 4)  # start phases of the base motion (rad)
EXCITATION_A = 0.005  # A rms per axis and sample: ~0.2 um rms at the AMBs
DISK = 7  # node of the seed rotor's disk
NOISE = 1e-3
LOCKSTEP_GOAL_STEPS_S = 2000.0  # issue 5's lockstep goal: the monitor's per-sample cost is compared with it


class Case:
    """Simulators (one per start phase) and the model rho of one pitch case."""

    def __init__(self, amplitude, N, base_forcing=False, excitation=EXCITATION_A):
        cfg = load_config(paper_config_path(), [f"base_forcing={str(base_forcing).lower()}"])  # the paper's loop
        self.model = model = build_structure(cfg)
        self.loop = loop = SampledLoop(model, cfg)
        self.N, self.T, self.excitation = N, N * loop.Ts, excitation
        self.forcing = "alternating" if base_forcing else "none"
        w = np.pi / self.T
        self.rho = sampled_floquet(loop, BaseMotion.single("pitch", amplitude, w), self.T).max_abs
        self.sims = [
            SnapshotSimulator(loop, BaseMotion((Harmonic("pitch", amplitude, w, ph),), "pitch")) for ph in PHASES
        ]
        if base_forcing:  # disturbances relative to the forced response
            orbit = self.sims[0].periodic_orbit()
            forced = float(np.abs(model.Ba.T @ orbit[: model.n]).max())
            self.ic_range = (0.1 * forced, 10.0 * forced)
        else:
            self.ic_range = (1e-4, 1e-3)  # m, disk displacement (the paper starts from 1 mm)

    def disturbance(self, rng) -> np.ndarray:
        """A knock: the disk displaced in a random direction by a log-uniform amount in ``ic_range``, at rest
        (the paper starts from 1 mm at the disk)."""
        n = self.model.n
        q_fe = np.zeros(self.model.fe.n)
        v, w = rng.standard_normal(2)
        lo, hi = np.log10(self.ic_range)
        amp = 10 ** rng.uniform(lo, hi) / np.hypot(v, w)
        q_fe[[dof_index(DISK, 0), dof_index(DISK, 1)]] = amp * v, amp * w
        return np.concatenate([self.model.from_fe(q_fe), np.zeros(n)])

    def run(self, rng, periods, mode):
        """One random run; returns (t, snapshots with noise, scale groups)."""
        sim = self.sims[rng.integers(len(self.sims))]
        X0 = sim.initial_state(self.disturbance(rng))
        run, _ = sim.run(periods * self.N, X0, excitation_std=self.excitation, rng=rng)
        n = self.model.n
        S = run.y if mode == "sensor" else run.x
        groups = None if mode == "sensor" else tuple([0] * n + [1] * n)
        return run.t, add_measurement_noise(S, NOISE, rng), groups

    def monitor(self, t, S, groups, stop_on_flag):
        cfg = EstimatorConfig(self.T, self.loop.Ts, forcing=self.forcing, scale_groups=groups)
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
            # the issue counts base-motion periods: 2 pi/omega = 2 T for pitch
            detected_within_8_base_periods_fraction=float((flags <= 16.0).mean()),
            latency_periods_p50=float(np.percentile(flags, 50, method="higher")),
            latency_periods_p99=float(np.percentile(flags, 99, method="higher")),
            latency_periods_max=float(flags.max()),
        )
    else:
        out["false_alarms"] = int(np.isfinite(flags).sum())
    return out


def cost_per_update(case: Case, modes=("sensor", "full"), runs: int = 1, periods: int = 20) -> dict:
    """Wall time of one refit (on the last window) and of one sample push incl. refits, averaged over runs."""
    rng = np.random.default_rng(7)
    out = {}
    for mode in modes:
        elapsed, samples = 0.0, 0
        for _ in range(runs):
            t, S, groups = case.run(rng, periods, mode)
            cfg = EstimatorConfig(case.T, case.loop.Ts, forcing=case.forcing, scale_groups=groups)
            est = StreamingEstimator(cfg, S.shape[1])
            t0 = time.perf_counter()
            for k in range(t.size):
                est.push(t[k], S[k])
            elapsed += time.perf_counter() - t0
            samples += t.size
        per_sample = elapsed / samples
        Z, scale = est.window_matrix()
        noise = np.tile(est.noise_estimate() / scale, cfg.phases)
        batches = []  # best of 5 batches: the machine is shared, the minimum is the estimator's own cost
        for _ in range(5):
            t0 = time.perf_counter()
            for _ in range(10):
                fit_period_map(Z, cfg.forcing, noise, cfg.method, cfg.max_rank)
            batches.append((time.perf_counter() - t0) / 10)
        out[mode] = {
            "refit_ms": min(batches) * 1e3,
            "refit_ms_median": float(np.median(batches)) * 1e3,
            "window_shape": list(Z.shape),
            "per_sample_us_incl_refits": per_sample * 1e6,
            "fraction_of_lockstep_step": per_sample * LOCKSTEP_GOAL_STEPS_S,
        }
    return out


def all_costs() -> dict:
    """Scenario A (sensor-only and full state, one run) and scenario B (sensor-only, mean over 6 runs)."""
    a = cost_per_update(Case(*DETECT, base_forcing=True))
    b = cost_per_update(Case(*DETECT), ("sensor",), runs=6, periods=18)
    return {"A sensor": a["sensor"], "A full": a["full"], "B sensor": b["sensor"]}


BIN = Path(sys.executable).parent
RIG_T = STABLE[1] * 2e-4  # the stable case's period at 5 kHz: the monitor gets it as a parameter (no waiting)
RIG_ARGS = ["--config", str(paper_config_path()), "--duration", "2.0", "--motion", "pitch", "--amplitude", "0.3",
            "--frequency", repr(np.pi / RIG_T),
            "--set", "controller.current_limit=1e9", "--param", "plant:max_displacement_ratio=1e9",
            "--param", "plant:initial_displacement=1e-3"]  # fmt: skip


def rig_steps_per_s(with_monitor: bool) -> tuple[float, str]:
    """One lockstep amb-rig run (2 s simulated): with amb-rig's own monitor (given the period, so it does not
    wait for /base/imu), or with ``--no-monitor``; returns steps/s and the monitor's closing line."""
    mon = ["--param", f"monitor:period_s={RIG_T!r}"]
    mon = mon if with_monitor else ["--no-monitor"]
    out = subprocess.run([str(BIN / "amb-rig"), "run", "--json", *RIG_ARGS, *mon], env=child_env(),
                         capture_output=True, text=True, timeout=600)  # fmt: skip
    summary = json.loads(out.stdout)
    if not summary["ok"]:
        raise RuntimeError(f"amb-rig failed: {summary['errors']}")
    line = ""
    if with_monitor:
        node = summary["nodes"]["monitor"]
        v = node["values"]
        line = (f"stability_monitor: {v.get('samples', '0')} samples ({v.get('samples lost', '?')} lost), "
                f"{v.get('refits', '0')} refits; {node['message']}")  # fmt: skip
    return summary["steps_per_s"], line


def lockstep_side_by_side(repeats: int = 4) -> dict:
    """Lockstep steps/s without and with the monitor, alternating runs (this machine's load drifts); the cost is
    the median over the back-to-back pairs of 1 - with / without."""
    without, with_, lines = [], [], []
    for _ in range(repeats):
        without.append(rig_steps_per_s(False)[0])
        rate, line = rig_steps_per_s(True)
        with_.append(rate)
        lines.append(line)
    lost = [int(m.group(1)) for x in lines if (m := re.search(r"\((\d+) lost\)", x))]
    return {
        "steps_per_s_without_monitor": float(np.median(without)),
        "steps_per_s_with_monitor": float(np.median(with_)),
        "ratio_with_to_without": float(np.median(with_) / np.median(without)),
        "pair_costs": [1.0 - b / a for a, b in zip(without, with_, strict=True)],
        "monitor_samples_lost": lost,
        "monitor_summary": lines[-1],
    }


def report(title: str, det: dict, fa: dict) -> None:
    print(f"  {title}")
    print(f"    detection rho = {det['model_rho']:.4f}: within 8 base-motion periods (16 T) in"
          f" {100 * det['detected_within_8_base_periods_fraction']:.1f} % of {det['runs']} runs (goal >= 99 %);"
          f" within 8 T in {100 * det['detected_within_8_periods_fraction']:.1f} %;"
          f" latency p50 {det['latency_periods_p50']:.2f}, p99 {det['latency_periods_p99']:.2f},"
          f" max {det['latency_periods_max']:.2f} periods T")  # fmt: skip
    print(f"    false alarms rho = {fa['model_rho']:.5f}: {fa['false_alarms']} in {fa['runs']} runs of"
          f" {fa['periods_per_run']} periods (goal 0); largest rho_hat {fa['max_rho_hat']:.4f}")  # fmt: skip


def cost_in_node_setting() -> dict:
    """``cost_per_update`` in a fresh interpreter with one BLAS thread, as the monitor node runs (this process may
    have loaded numpy with several threads, which oversubscribes the 2 cores)."""
    env = dict(child_env(), OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", MKL_NUM_THREADS="1")
    out = subprocess.run([sys.executable, __file__, "--cost"], env=env, capture_output=True, text=True, timeout=600)
    if out.returncode:
        raise RuntimeError(f"cost measurement failed: {out.stderr.strip()[-300:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> dict:
    t0 = time.perf_counter()
    det_a, stab_a = Case(*DETECT, base_forcing=True), Case(*STABLE, base_forcing=True)
    det_b, stab_b, det_b0 = Case(*DETECT), Case(*STABLE), Case(*DETECT, excitation=0.0)
    jobs = {("A_sensor", "detection"): (det_a, 200, 12, "sensor", 1, True),
            ("A_sensor", "false_alarms"): (stab_a, 100, 50, "sensor", 2, False),
            ("A_full_state", "detection"): (det_a, 50, 12, "full", 3, True),
            ("A_full_state", "false_alarms"): (stab_a, 20, 50, "full", 4, False),
            ("B_sensor", "detection"): (det_b, 100, 18, "sensor", 5, True),
            ("B_sensor", "false_alarms"): (stab_b, 100, 50, "sensor", 6, False),
            ("B_sensor_no_excitation", "detection"): (det_b0, 100, 18, "sensor", 7, True)}  # fmt: skip
    # the Monte Carlo sets are independent and seeded: two processes (one per core) give the same numbers in half
    # the time; the timed parts (cost, lockstep pairs) run afterwards, alone
    res: dict = {}
    with ProcessPoolExecutor(2, mp_context=multiprocessing.get_context("fork")) as pool:
        futures = {key: pool.submit(monte_carlo, *args) for key, args in jobs.items()}
        for (group, what), fut in futures.items():
            res.setdefault(group, {})[what] = fut.result()
    res["cost"] = cost_in_node_setting()
    res["lockstep"] = lockstep_side_by_side()
    res["wall_s"] = time.perf_counter() - t0
    print("stability monitor, seed rotor, 5 kHz, 0.1 % noise, 0.005 A excitation, random start phase and knock")
    report("(A) base forcing on, sensor-only", res["A_sensor"]["detection"], res["A_sensor"]["false_alarms"])
    report("(A) base forcing on, full state [q; q']", res["A_full_state"]["detection"],
           res["A_full_state"]["false_alarms"])  # fmt: skip
    report("(B) seed config (no base forcing), knock at the disk, sensor-only", res["B_sensor"]["detection"],
           res["B_sensor"]["false_alarms"])  # fmt: skip
    d = res["B_sensor_no_excitation"]["detection"]
    print(f"    without excitation: within 8 base-motion periods in "
          f"{100 * d['detected_within_8_base_periods_fraction']:.1f} %, within 8 T in "
          f"{100 * d['detected_within_8_periods_fraction']:.1f} % of"
          f" {d['runs']} runs; latency p50 {d['latency_periods_p50']:.2f}, p99 {d['latency_periods_p99']:.2f},"
          f" max {d['latency_periods_max']:.2f} periods T")  # fmt: skip
    for mode, c in res["cost"].items():
        rows, cols = c["window_shape"]
        print(f"  cost {mode:8s}: refit {c['refit_ms']:.2f} ms on a {rows}x{cols} window;"
              f" {c['per_sample_us_incl_refits']:.1f} us per sample incl. refits ="
              f" {100 * c['fraction_of_lockstep_step']:.1f} % of a lockstep step at"
              f" {LOCKSTEP_GOAL_STEPS_S:.0f} steps/s")  # fmt: skip
    ls = res["lockstep"]
    costs = ", ".join(f"{100 * c:.1f} %" for c in ls["pair_costs"])
    print(f"  lockstep amb-rig: {ls['steps_per_s_without_monitor']:.0f} steps/s without, "
          f"{ls['steps_per_s_with_monitor']:.0f} with the monitor (ratio {ls['ratio_with_to_without']:.2f}); "
          f"cost {100 * float(np.median(ls['pair_costs'])):.1f} %, median of the pairs ({costs}); "
          f"monitor samples lost {ls['monitor_samples_lost']}")  # fmt: skip
    print(f"  wall time {res['wall_s']:.0f} s")
    for key, label in (("A_sensor", "A, base forcing, sensor-only"), ("B_sensor", "B, knock, sensor-only")):
        d, f = res[key]["detection"], res[key]["false_alarms"]
        record(f"monitor detects rho = {d['model_rho']:.4g} within 8 base periods ({label})",
               100 * d["detected_within_8_base_periods_fraction"], "% of runs", goal=">= 99",
               note=f"{d['runs']} runs, latency p99 {d['latency_periods_p99']:.1f} periods T")  # fmt: skip
        record(f"monitor false alarms at rho = {f['model_rho']:.5g}, 50 periods ({label})", f["false_alarms"],
               f"of {f['runs']} runs", goal="0")  # fmt: skip
    for mode, c in res["cost"].items():
        record(f"monitor cost per sample incl. refits ({mode})", c["per_sample_us_incl_refits"], "us")
    record("lockstep steps/s lost with the monitor beside the loop, back-to-back pairs",
           [100 * c for c in ls["pair_costs"]], "%", note=f"samples lost {ls['monitor_samples_lost']}")  # fmt: skip
    return res


if __name__ == "__main__":
    if sys.argv[1:] == ["--cost"]:
        print(json.dumps(all_costs()))
    else:
        main()
