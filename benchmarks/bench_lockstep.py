"""Lockstep steps/s of the node suite vs a bare rclpy ping-pong, and realtime 1 kHz period error.

    .venv/bin/python benchmarks/bench_lockstep.py [--duration 2] [--round-trips 5000]

1. Bare rclpy inter-process ping-pong (benchmarks/pingpong.py), the physical limit of one lockstep step (one
   round trip per step): two processes echo a 4-channel JointState with the nodes' own transport settings
   (reliable, transient local, raw CDR, one reused wait set, synchronous Fast DDS publication).  Measured before
   and after the lockstep runs; their mean is the baseline.
2. Lockstep: ``amb-rig run --no-monitor`` with base_motion, plant and controller as separate processes (the
   paper config, 5 kHz, pitch 0.3 rad at 24.5 rad/s, current limit lifted so the linear run stays defined), with
   normal scheduling and with ``--rt-priority 20`` (SCHED_FIFO), and ``amb-rig run`` with its default stability
   monitor beside the loop (goal >= 0.8 x the ping-pong), alternating, ``repeats`` runs each (medians); steps/s
   is the plant's own loop rate (start-up excluded).  Printed: steps/s and the ratio to the ping-pong.
3. Realtime 1 kHz for 5 s (modal_cutoff 800 rad/s, stable at 1 and 2 kHz, SCHED_FIFO 20 as amb-rig's default):
   the period error p50/p99/max of the wall-clock timers (the plant's sample clock, and the controller with
   ``trigger:=timer``) and missed deadlines; then the default sample-triggered controller, whose update period
   follows the samples' arrival (sample clock + DDS latency jitter) and its sample-to-command latency; then the
   timers at 2 kHz on the paper loop; then the full FE real rig (no modal cutoff) with its 2 kHz controller
   (one sample of delay) and its 1 kHz controller (none), REAL_RIG_RUNS times each: how many runs kept the rotor
   off its touchdown bearings, and their p99s.
   Goals: >= 2,000 lockstep steps/s; realtime p99 period error < 100 us.
4. Executor trial: the same ping-pong driven by subscription callbacks of rclpy's EventsExecutor
   (rclpy.experimental) and of the standard SingleThreadedExecutor, against the nodes' own wait-set path,
   alternating; printed as round trips/s and ratios (the nodes keep the wait-set path unless these say otherwise).
5. Lockstep with the real-rig default config (every effect on, the default pitching base), alternating with the
   paper config's normal runs: goal >= 0.9 x its steps/s.
6. CPU per lockstep step of each node process, real-rig default config (tools/rig_cpu.py: the difference of a
   short and a long run, so start-up is excluded), all threads and the Python main thread: goal <= 40 us for the
   plant and the controller.

``main()`` prints a small table and returns a dict (benchmarks/run_all.py calls it).
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
from pathlib import Path

from pingpong import bench_env, pingpong, pingpong_detail
from report import record, record_ratio

BIN = Path(sys.executable).parent
# the paper's loop: its plant is fast, so these figures measure DDS and the nodes (the goals were set for it)
PAPER = ["--config", str(Path(__file__).resolve().parents[1] / "config" / "seed_paper.yaml")]
# the real rig's realtime loops, the full FE plant: 2 kHz with one sample of computation delay, 1 kHz without
REAL_RIG = {2000: Path(__file__).resolve().parents[1] / "config" / "seed_rotor_2khz_lqg.yaml",
            1000: Path(__file__).resolve().parents[1] / "config" / "seed_rotor_1khz_lqg.yaml"}  # fmt: skip
REAL_RIG_RUNS = 4  # realtime runs of the real rig per rate (each 5 s): how many keep the rotor up
GOAL_STEPS_PER_S = 2000.0
GOAL_P99_US = 100.0
GOAL_PINGPONG_RATIO = 0.8  # lockstep steps/s over the same run's ping-pong round trips/s, monitor on
GOAL_REAL_RIG_RATIO = 0.9  # the real-rig default's lockstep steps/s over the paper config's, same run
CPU_TOOL = Path(__file__).resolve().parents[1] / "tools" / "rig_cpu.py"
CPU_RUNS = 2  # measurements of tools/rig_cpu.py (each a short and a long run)
CPU_NODES = {"amb-plant": "<= 40", "amb-controller": "<= 40", "amb-base-motion": None}


# -- amb-rig runs -------------------------------------------------------------------------------------
def rig(args: list[str], timeout: float = 600.0, require_ok: bool = True, config: list[str] = PAPER) -> dict:
    out = subprocess.run([str(BIN / "amb-rig"), "run", "--json", *config, *args], env=bench_env(), capture_output=True,
                         text=True, timeout=timeout)  # fmt: skip
    try:
        summary = json.loads(out.stdout)
    except json.JSONDecodeError:
        raise RuntimeError(f"amb-rig {' '.join(args)} failed: {out.stderr.strip()[-500:]}") from None
    if require_ok and not summary["ok"]:
        raise RuntimeError(f"amb-rig {' '.join(args)}: {summary['errors']}")
    return summary


def lockstep(duration: float, rt_priority: int, real_rig: bool = False, monitor: bool = False) -> dict:
    watch = [] if monitor else ["--no-monitor"]  # amb-rig's default runs the stability monitor beside the loop
    if real_rig:  # the default config: its own current limit (below the bias), every effect on
        s = rig(["--duration", str(duration), *watch, "--rt-priority", str(rt_priority)], config=[])
    else:
        s = rig(["--duration", str(duration), *watch, "--rt-priority", str(rt_priority),
                 "--set", "controller.current_limit=1e9"])  # fmt: skip
    return {"steps": s["steps"], "steps_per_s": s["steps_per_s"], "wall_s": s["wall_s"],
            "scheduling": s["nodes"]["plant"]["values"]["scheduling"]}  # fmt: skip


def realtime(trigger: str, rate_hz: int = 1000, duration: float = 5.0, real_rig: bool = False) -> dict:
    # static base, centred rotor: the linear state stays zero whatever the timing (see tests/test_rig_realtime.py);
    # the paper loop with modal_cutoff 800 rad/s is stable at 1 and 2 kHz (amb-dynamics modes says so); real_rig:
    # the full FE real rig with its controller for rate_hz (REAL_RIG), every effect on
    args = ["--mode", "realtime", "--duration", str(duration), "--motion", "none", "--param",
            f"controller:trigger={trigger}"]  # fmt: skip
    if real_rig:
        s = rig(args, require_ok=False, config=["--config", str(REAL_RIG[rate_hz])])
    else:
        s = rig([*args, "--set", f"controller.rate_hz={rate_hz}", "--set", "modal_cutoff=800"], require_ok=False)
    c, p = s["nodes"]["controller"]["values"], s["nodes"]["plant"]["values"]
    out = {
        "samples_lost": c.get("samples lost", "?"),
        "trigger": trigger,
        "scheduling": c["scheduling"],
        "ticks": int(c["ticks"]),
        "p50_us": float(c["period error p50 (us)"]),
        "p99_us": float(c["period error p99 (us)"]),
        "max_us": float(c["period error max (us)"]),
        "missed_deadlines": int(c["missed deadlines"]),
        "plant_p50_us": float(p["period error p50 (us)"]),
        "plant_p99_us": float(p["period error p99 (us)"]),
        "plant_max_us": float(p["period error max (us)"]),
        "plant_missed_deadlines": int(p["missed deadlines"]),
        "errors": s["errors"],
        "touchdown": p.get("first touchdown", ""),  # "t = ... s at node n": the rotor dropped
    }
    if trigger == "sample":
        out["latency_p99_us"] = float(c["sample-to-command latency p99 (us)"])
    return out


def record_real_rig(rate: int, runs: list[dict]) -> tuple[str, str, str]:
    """The figures of the real rig's realtime runs at ``rate`` (Hz): runs that kept the rotor up, the p99s; the
    table row of the median run."""
    name, khz = REAL_RIG[rate].name, f"{rate / 1000:g} kHz"
    median = sorted(runs, key=lambda r: r["p99_us"])[len(runs) // 2]
    up = sum(not r["touchdown"] for r in runs)
    record(f"realtime {khz} real rig ({name}): runs that kept the rotor off its touchdown bearings", up,
           f"of {len(runs)}", goal=f"{len(runs)}",
           note="; ".join(f"run {i + 1}: {r['touchdown']}" for i, r in enumerate(runs) if r["touchdown"]))  # fmt: skip
    record(f"realtime {khz} period error p99, controller, real rig ({name})", [r["p99_us"] for r in runs], "us",
           goal="< 100", note=f"median run: {median['missed_deadlines']} missed deadlines, "
           f"{median['samples_lost']} samples lost")  # fmt: skip
    record(f"realtime {khz} period error p99, plant, real rig ({name})", [r["plant_p99_us"] for r in runs], "us",
           goal="< 100", note=f"median run: {median['plant_missed_deadlines']} missed deadlines")  # fmt: skip
    return (f"realtime {khz}, real rig ({name}), median run: controller, plant",
            f"{median['p50_us']:.0f}/{median['p99_us']:.0f}/{median['max_us']:.0f}",
            f"plant {median['plant_p50_us']:.0f}/{median['plant_p99_us']:.0f}/{median['plant_max_us']:.0f}; "
            f"{median['missed_deadlines']} + {median['plant_missed_deadlines']} missed deadlines; "
            f"{median['samples_lost']} samples lost; {'; '.join(median['errors']) or 'run OK'}")  # fmt: skip


def cpu_per_step(runs: int = CPU_RUNS) -> list[dict]:
    """tools/rig_cpu.py's measurements: [{"steps_per_s", "us_per_step": {process: {thread group: us}}}, ...]."""
    out = subprocess.run([sys.executable, str(CPU_TOOL), "--json", "--runs", str(runs), "--duration", "0.5"],
                         env=bench_env(), capture_output=True, text=True, timeout=900)  # fmt: skip
    if out.returncode != 0:
        raise RuntimeError(f"tools/rig_cpu.py failed: {out.stderr.strip()[-500:]}")
    return [json.loads(line) for line in out.stdout.splitlines() if line.startswith("{")]


def main(duration: float = 2.0, round_trips: int = 5000, repeats: int = 3) -> dict:
    d1 = pingpong_detail(round_trips)
    pp1 = d1["round_trips_per_s"]
    runs = {0: [], 20: [], "real": [], "monitor": []}
    for _ in range(repeats):  # alternating: this machine's load drifts
        for prio in runs:
            if prio == "real":
                runs[prio].append(lockstep(duration, 0, real_rig=True))
            elif prio == "monitor":
                runs[prio].append(lockstep(duration, 0, monitor=True))
            else:
                runs[prio].append(lockstep(duration, prio))
    d2 = pingpong_detail(round_trips)
    pp2 = d2["round_trips_per_s"]
    paths = {"waitset": [], "events": [], "single": []}
    for _ in range(repeats):  # the executors' callback paths against the nodes' wait-set path, alternating
        for path in paths:
            paths[path].append(pingpong(round_trips, path))
    timer, sample, timer2 = realtime("timer"), realtime("sample"), realtime("timer", 2000)
    # the LQGs' delay is exact only when each sample is answered; several runs: a stall may drop the rotor
    rigs = {rate: [realtime("sample", rate, real_rig=True) for _ in range(REAL_RIG_RUNS)] for rate in REAL_RIG}
    cpu = cpu_per_step()
    base = 0.5 * (pp1 + pp2)
    normal = statistics.median(r["steps_per_s"] for r in runs[0])
    fifo = statistics.median(r["steps_per_s"] for r in runs[20])
    real = statistics.median(r["steps_per_s"] for r in runs["real"])
    watched = statistics.median(r["steps_per_s"] for r in runs["monitor"])
    timers_p99 = max(timer["p99_us"], timer["plant_p99_us"])
    result = {
        "pingpong_round_trips_per_s": base,
        "pingpong_before_after": [pp1, pp2],
        "lockstep_steps_per_s": normal,
        "lockstep_runs": [r["steps_per_s"] for r in runs[0]],
        "lockstep_to_pingpong_ratio": normal / base,
        "lockstep_monitor_steps_per_s": watched,
        "lockstep_monitor_runs": [r["steps_per_s"] for r in runs["monitor"]],
        "lockstep_monitor_to_pingpong_ratio": watched / base,
        "lockstep_monitor_goal_met": watched >= GOAL_PINGPONG_RATIO * base,
        "lockstep_fifo_steps_per_s": fifo,
        "lockstep_fifo_runs": [r["steps_per_s"] for r in runs[20]],
        "lockstep_fifo_scheduling": runs[20][-1]["scheduling"],
        "lockstep_fifo_to_pingpong_ratio": fifo / base,
        "lockstep_goal_met": {"normal": normal >= GOAL_STEPS_PER_S, "sched_fifo": fifo >= GOAL_STEPS_PER_S},
        "lockstep_real_rig_steps_per_s": real,
        "lockstep_real_rig_runs": [r["steps_per_s"] for r in runs["real"]],
        "lockstep_real_rig_to_paper_ratio": real / normal,
        "lockstep_real_rig_goal_met": real >= GOAL_REAL_RIG_RATIO * normal,
        "executor_trial_round_trips_per_s": paths,
        "realtime_1khz_timer": timer,
        "realtime_1khz_sample": sample,
        "realtime_2khz_timer": timer2,
        "realtime_2khz_real_rig": rigs[2000],
        "realtime_1khz_real_rig": rigs[1000],
        "realtime_goal_met": timers_p99 < GOAL_P99_US,
        "cpu_us_per_step": [c["us_per_step"] for c in cpu],
        "pingpong_cpu_us_per_round_trip": {side: [d[f"{side}_cpu_us"] for d in (d1, d2) if f"{side}_cpu_us" in d]
                                           for side in ("ping", "echo")},
    }  # fmt: skip
    steps = runs[0][-1]["steps"]
    rows = [
        ("bare rclpy ping-pong (round trips/s)", f"{base:,.0f}", f"before {pp1:,.0f}, after {pp2:,.0f}"),
        ("lockstep, 3 processes, normal scheduling", f"{normal:,.0f}",
         f"steps/s, {normal / base:.2f} x ping-pong; runs {', '.join(f'{r:,.0f}' for r in result['lockstep_runs'])}"
         f" ({steps} steps each)"),
        ("lockstep with the monitor (amb-rig's default)", f"{watched:,.0f}",
         f"steps/s, {watched / base:.2f} x ping-pong (goal >= {GOAL_PINGPONG_RATIO:g}: "
         f"{'met' if result['lockstep_monitor_goal_met'] else 'MISSED'}); runs "
         f"{', '.join(f'{r:,.0f}' for r in result['lockstep_monitor_runs'])}"),
        ("lockstep, 3 processes, --rt-priority 20", f"{fifo:,.0f}",
         f"steps/s, {fifo / base:.2f} x ping-pong; runs {', '.join(f'{r:,.0f}' for r in result['lockstep_fifo_runs'])}"
         f"; {result['lockstep_fifo_scheduling']}"),
        ("lockstep, real-rig default config (every effect on)", f"{real:,.0f}",
         f"steps/s, {real / normal:.2f} x the paper config's normal runs (goal >= {GOAL_REAL_RIG_RATIO:g}: "
         f"{'met' if result['lockstep_real_rig_goal_met'] else 'MISSED'}); runs "
         f"{', '.join(f'{r:,.0f}' for r in result['lockstep_real_rig_runs'])}"),
        ("executor trial: ping-pong round trips/s", "", "wait-set " + ", ".join(f"{r:,.0f}" for r in paths["waitset"])
         + "; EventsExecutor " + ", ".join(f"{r:,.0f}" for r in paths["events"]) + "; SingleThreadedExecutor "
         + ", ".join(f"{r:,.0f}" for r in paths["single"])),
        ("lockstep goal >= 2,000 steps/s", "", f"normal {'met' if normal >= GOAL_STEPS_PER_S else 'MISSED'}, "
         f"SCHED_FIFO {'met' if fifo >= GOAL_STEPS_PER_S else 'MISSED'}"),
        ("realtime 1 kHz timer p50/p99/max (us): controller", f"{timer['p50_us']:.0f}/{timer['p99_us']:.0f}/"
         f"{timer['max_us']:.0f}", f"{timer['missed_deadlines']} missed deadlines in {timer['ticks']} ticks; "
         f"{timer['scheduling']}"),
        ("realtime 1 kHz timer p50/p99/max (us): plant", f"{timer['plant_p50_us']:.0f}/{timer['plant_p99_us']:.0f}/"
         f"{timer['plant_max_us']:.0f}", f"{timer['plant_missed_deadlines']} missed deadlines; goal p99 < "
         f"{GOAL_P99_US:.0f}: {'met' if result['realtime_goal_met'] else 'MISSED'}"),
        ("realtime 1 kHz sample-triggered controller", f"{sample['p50_us']:.0f}/{sample['p99_us']:.0f}/"
         f"{sample['max_us']:.0f}", f"update-period error p50/p99/max (us; sample clock + DDS jitter); latency p99 "
         f"{sample['latency_p99_us']:.0f} us; {sample['missed_deadlines']} missed deadlines"),
    ]  # fmt: skip
    record("lockstep, 3 node processes, normal scheduling", result["lockstep_runs"], "steps/s", goal=">= 2,000")
    record("lockstep, 3 node processes, --rt-priority 20", result["lockstep_fifo_runs"], "steps/s", goal=">= 2,000")
    record("lockstep, real-rig default config, normal scheduling", result["lockstep_real_rig_runs"], "steps/s")
    record_ratio("lockstep real rig / paper config (normal)", result["lockstep_real_rig_runs"], result["lockstep_runs"],
                 goal=f">= {GOAL_REAL_RIG_RATIO:g}")  # fmt: skip
    record("bare rclpy ping-pong, before and after", [pp1, pp2], "round trips/s")
    record("ping-pong, nodes' wait-set path (executor trial)", paths["waitset"], "round trips/s")
    record_ratio("ping-pong, EventsExecutor callbacks / wait-set path", paths["events"], paths["waitset"])
    record_ratio("ping-pong, SingleThreadedExecutor callbacks / wait-set path", paths["single"], paths["waitset"])
    record_ratio("lockstep (normal, --no-monitor) / ping-pong", result["lockstep_runs"],
                 [base] * len(result["lockstep_runs"]))  # fmt: skip
    record("lockstep with the monitor (amb-rig's default), normal scheduling", result["lockstep_monitor_runs"],
           "steps/s")  # fmt: skip
    record_ratio("lockstep with the monitor / ping-pong", result["lockstep_monitor_runs"],
                 [base] * len(result["lockstep_monitor_runs"]), goal=f">= {GOAL_PINGPONG_RATIO:g}x")  # fmt: skip
    record("realtime 1 kHz timer period error p99, controller", timer["p99_us"], "us", goal="< 100")
    record("realtime 1 kHz timer period error p99, plant", timer["plant_p99_us"], "us", goal="< 100")
    record("realtime 1 kHz sample-triggered controller, update-period error p99", sample["p99_us"], "us")
    record("realtime 2 kHz timer period error p99, controller", timer2["p99_us"], "us", goal="< 100",
           note=f"{timer2['missed_deadlines']} missed deadlines in {timer2['ticks']} ticks")  # fmt: skip
    record("realtime 2 kHz timer period error p99, plant", timer2["plant_p99_us"], "us", goal="< 100",
           note=f"{timer2['plant_missed_deadlines']} missed deadlines")  # fmt: skip
    rows.append(("realtime 2 kHz timer p50/p99/max (us): controller, plant",
                 f"{timer2['p50_us']:.0f}/{timer2['p99_us']:.0f}/{timer2['max_us']:.0f}",
                 f"plant {timer2['plant_p50_us']:.0f}/{timer2['plant_p99_us']:.0f}/{timer2['plant_max_us']:.0f}; "
                 f"{timer2['missed_deadlines']} + {timer2['plant_missed_deadlines']} missed deadlines"))  # fmt: skip
    for rate, runs_at in rigs.items():
        rows.append(record_real_rig(rate, runs_at))
    for proc, goal in CPU_NODES.items():
        total = [sum(c["us_per_step"][proc].values()) for c in cpu]
        main_thread = [c["us_per_step"][proc]["main"] for c in cpu]
        record(f"CPU per lockstep step, {proc}, all threads (real-rig default config)", total, "us", goal=goal,
               note=f"main thread {statistics.median(main_thread):.0f} us")  # fmt: skip
        rows.append((f"CPU per step, {proc} (us)", f"{statistics.median(total):.0f}",
                     f"all threads; main thread {statistics.median(main_thread):.0f}; goal {goal or '-'}"))  # fmt: skip
    for side, like in (("ping", "amb-plant"), ("echo", "amb-controller")):
        cpu_rt = result["pingpong_cpu_us_per_round_trip"][side]
        if cpu_rt:  # the floor under the nodes' CPU per step: rclpy's own cost of one step's traffic
            record(f"CPU per round trip, bare rclpy ping-pong, {side} process, all threads (the floor of {like})",
                   cpu_rt, "us")  # fmt: skip
            rows.append((f"CPU per round trip, ping-pong {side} (us)", f"{statistics.median(cpu_rt):.0f}",
                         f"all threads, no computation: the rclpy floor under {like}'s CPU per step"))  # fmt: skip
    width = max(len(r[0]) for r in rows)
    print("bench_lockstep")
    for name, value, note in rows:
        print(f"  {name:<{width}}  {value:>14}  {note}")
    return result


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=2.0, help="simulated seconds of the lockstep run")
    ap.add_argument("--round-trips", type=int, default=5000)
    ns = ap.parse_args()
    main(ns.duration, ns.round_trips)
