"""Recording cost: the lockstep loop's steps/s without and with recording, measured side by side in this run.

Lockstep steps/s of ``amb-rig run --duration RIG_DURATION --no-monitor`` without and with ``--bag`` (the recorder
started by amb-rig, every reader matched before step 0), alternating runs in this invocation (the machine's load
drifts); steps/s is the plant's loop rate from ``amb-rig run --json`` (``steps_per_s``, start-up excluded).
Cost = median over the back-to-back pairs of 1 - with / without (robust to load drifting between pairs); goal
< 20 %.  Two controls in the same pairs:

- beside a bare raw reader of the rig's topics that takes every message and writes nothing (scheduled and batched
  like amb-rig's lockstep recorder: normal priority, 50 ms): the cost of one more DDS reader alone, which no
  recorder can go below;
- beside a busy loop that takes BURN_DUTY of one core and no DDS at all, to compare with the recorder's own CPU
  share (its CPU time while recording / the loop's wall time, from its final diagnostics): on this 2-core machine
  any process of that size costs the loop about as much.
"""

from __future__ import annotations

import argparse
import json
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench_bag import BIN, EVERY
from bench_lockstep import PAPER
from report import record

RIG_DURATION = 2.0  # simulated s per lockstep run (10,000 steps at 5 kHz)
RIG_PAIRS = 4  # alternating runs without / with --bag (and beside each control)
GOAL_COST = 0.20
BURN_DUTY = 0.2  # the busy-loop control: a fifth of one core, about the recorder's share (measured)
BURN_PERIOD_S = 0.01
STALL_S = 0.5  # a plant command wait longer than this is a stall (the loop's round trip is ~0.4 ms)


RIG_TOPICS = tuple(EVERY)  # the lockstep mix's topics (bench_bag)
GATES = (
    "plant:min_subscribers=2",
    "plant:min_state_subscribers=1",
    "base_motion:min_rates_subscribers=2",
    "base_motion:min_imu_subscribers=1",
    "base_motion:min_acceleration_subscribers=1",
)  # every sample reaches the bare reader too
READER_GATES = [a for g in GATES for a in ("--param", g)]


def bare_reader() -> None:
    """Raw subscriptions to the rig's topics (lockstep QoS); take everything every 50 ms until SIGINT."""
    import signal

    import rclpy
    from geometry_msgs.msg import Vector3Stamped
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import Imu, JointState
    from trajectory_msgs.msg import JointTrajectory

    from amb_bringup.processes import consumer_priority as rig_priority
    from amb_ros.qos import lockstep_qos
    from amb_ros.scheduling import consumer_priority

    types = {
        "/clock": Clock,
        "/base/rates": JointTrajectory,
        "/base/imu": Imu,
        "/base/angular_acceleration": Vector3Stamped,
        "/amb_plant/state": JointTrajectory,
    }
    from amb_ros.fastdds import init_rclpy

    init_rclpy()  # as the nodes start DDS (like with like)
    node = rclpy.create_node("bench_bare_reader")
    subs = [node.create_subscription(types.get(t, JointState), t, lambda _: None, lockstep_qos(), raw=True)
            for t in RIG_TOPICS]  # fmt: skip
    consumer_priority(rig_priority("lockstep"))
    stop = []
    signal.signal(signal.SIGINT, lambda *_: stop.append(1))
    taken = 0
    while not stop:
        time.sleep(0.05)
        for sub in subs:
            while sub.handle.take_message(sub.msg_type, True) is not None:
                taken += 1
    print(json.dumps({"taken": taken}), flush=True)


def busy_loop(duty: float) -> None:
    """Burn ``duty`` of one core (busy ``duty`` of every BURN_PERIOD_S, asleep the rest) until killed."""
    while True:
        t0 = time.perf_counter()
        while time.perf_counter() - t0 < duty * BURN_PERIOD_S:
            pass
        time.sleep(BURN_PERIOD_S * (1.0 - duty))


def rig_steps_per_s(bag: Path | None, reader: bool = False, burn: float = 0.0) -> dict:
    """One lockstep ``amb-rig run`` without the monitor, optionally recorded into ``bag``, beside a bare reader
    or beside a busy loop taking ``burn`` of a core: plant steps/s (and the recorder's CPU share)."""
    import signal

    from amb_ros.env import child_env

    cmd = [str(BIN / "amb-rig"), "run", "--json", "--no-monitor", "--duration", str(RIG_DURATION), *PAPER,
           "--set", "controller.current_limit=1e9"]  # fmt: skip
    if bag is not None:
        cmd += ["--bag", str(bag)]
    proc = None
    if reader:
        cmd += READER_GATES
        proc = subprocess.Popen([sys.executable, __file__, "--reader"], env=child_env(), stdout=subprocess.PIPE,
                                text=True)  # fmt: skip
    burner = subprocess.Popen([sys.executable, __file__, "--burn", str(burn)]) if burn else None
    t0 = time.monotonic()
    try:
        out = subprocess.run(cmd, env=child_env(), capture_output=True, text=True, timeout=600)
        command_s = time.monotonic() - t0
    finally:
        if proc is not None:
            proc.send_signal(signal.SIGINT)
            proc.communicate(timeout=30)
        if burner is not None:
            burner.kill()
            burner.wait()
    try:
        summary = json.loads(out.stdout)
    except json.JSONDecodeError:
        raise RuntimeError(f"amb-rig failed: {out.stderr.strip()[-500:]}") from None
    if not summary["ok"]:
        raise RuntimeError(f"amb-rig: {summary['errors']}")
    plant = summary["nodes"]["plant"]["values"]
    row = {"steps": summary["steps"], "steps_per_s": summary["steps_per_s"],
           "wait_max_s": float(plant.get("command wait max (us)", "nan")) * 1e-6,
           "connect_s": float(plant.get("connect time (s)", "nan")), "command_s": command_s}  # fmt: skip
    if bag is not None:
        rec = summary["nodes"]["recorder"]["values"]
        loop_wall = float(plant["wall time (s)"])
        row.update(messages=int(rec["messages written"]), lost=int(rec["lost total"]),
                   recorder_cpu_share=float(rec["cpu time (s)"]) / loop_wall)  # fmt: skip
    return row


def bench_recording_cost(tmp: Path, pairs: int = RIG_PAIRS) -> dict:
    """Lockstep steps/s without and with recording (and beside a bare reader), alternating runs in this invocation.

    A run that fails is reported (``failed_runs``) and its pair left out of the medians, not hidden by a retry.
    """
    without, with_bag, with_reader, with_burner, failed = [], [], [], [], []

    def attempt(label: str, **kwargs) -> dict | None:
        try:
            return rig_steps_per_s(**kwargs)
        except RuntimeError as exc:
            failed.append(f"{label}: {exc}")
            return None

    for i in range(pairs):
        base = attempt(f"pair {i + 1} without --bag", bag=None)
        rec = attempt(f"pair {i + 1} with --bag", bag=tmp / f"rig{i}")
        shutil.rmtree(tmp / f"rig{i}", ignore_errors=True)
        bare = attempt(f"pair {i + 1} beside the bare reader", bag=None, reader=True)
        burner = attempt(f"pair {i + 1} beside the busy loop", bag=None, burn=BURN_DUTY)
        if base is not None:
            without.append(base)
            with_bag.append(rec)
            with_reader.append(bare)
            with_burner.append(burner)
    pairs_bag = [(a, b) for a, b in zip(without, with_bag, strict=True) if b is not None]
    pairs_reader = [(a, b) for a, b in zip(without, with_reader, strict=True) if b is not None]
    pairs_burner = [(a, b) for a, b in zip(without, with_burner, strict=True) if b is not None]
    if not pairs_bag or not pairs_reader or not pairs_burner:
        raise RuntimeError(f"no complete pair of lockstep runs: {failed}")
    pair_costs = [1.0 - b["steps_per_s"] / a["steps_per_s"] for a, b in pairs_bag]
    reader_costs = [1.0 - b["steps_per_s"] / a["steps_per_s"] for a, b in pairs_reader]
    burner_costs = [1.0 - b["steps_per_s"] / a["steps_per_s"] for a, b in pairs_burner]
    cost = statistics.median(pair_costs)
    return {
        "steps_per_s_without_bag": statistics.median(a["steps_per_s"] for a, _ in pairs_bag),
        "steps_per_s_with_bag": statistics.median(b["steps_per_s"] for _, b in pairs_bag),
        "cost": cost,
        "pair_costs": pair_costs,
        "runs_without": [a["steps_per_s"] for a, _ in pairs_bag],
        "runs_with": [b["steps_per_s"] for _, b in pairs_bag],
        "runs_with_bare_reader": [b["steps_per_s"] for _, b in pairs_reader],
        "bare_reader_cost": statistics.median(reader_costs),
        "bare_reader_costs": reader_costs,
        "busy_loop_cost": statistics.median(burner_costs),
        "busy_loop_costs": burner_costs,
        "recorder_cpu_share": statistics.median(b["recorder_cpu_share"] for _, b in pairs_bag),
        "wait_max_without": [a["wait_max_s"] for a, _ in pairs_bag],
        "wait_max_with": [b["wait_max_s"] for _, b in pairs_bag],
        "connect_s_without": [a["connect_s"] for a in without],
        "command_s_without": [a["command_s"] for a in without],
        "messages_per_run": pairs_bag[0][1]["messages"],
        "lost": sum(b["lost"] for _, b in pairs_bag),
        "failed_runs": failed,
        "goal_met": cost < GOAL_COST,
    }


def main() -> dict:
    tmp = Path(tempfile.mkdtemp(prefix="bench_recording_cost_"))
    try:
        cost = bench_recording_cost(tmp)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    print(f"recording cost, lockstep amb-rig run --duration {RIG_DURATION:g} --no-monitor, {RIG_PAIRS} pairs of "
          f"back-to-back runs without / with --bag")  # fmt: skip
    print(f"  without --bag {cost['steps_per_s_without_bag']:8,.0f} steps/s  "
          f"(runs: {', '.join(f'{x:,.0f}' for x in cost['runs_without'])})")  # fmt: skip
    print(f"  with --bag    {cost['steps_per_s_with_bag']:8,.0f} steps/s  "
          f"(runs: {', '.join(f'{x:,.0f}' for x in cost['runs_with'])}; {cost['messages_per_run']:,} messages "
          f"per bag, lost {cost['lost']})")  # fmt: skip
    print(f"  cost of recording: {100 * cost['cost']:.1f} % of steps/s, median of the pairs "
          f"({', '.join(f'{100 * c:.1f} %' for c in cost['pair_costs'])}); goal < {100 * GOAL_COST:.0f} %: "
          f"{'ok' if cost['goal_met'] else 'MISSED'}")  # fmt: skip
    print(f"  control: beside a bare raw reader of the same topics (takes, writes nothing) "
          f"{100 * cost['bare_reader_cost']:.1f} % ({', '.join(f'{100 * c:.1f} %' for c in cost['bare_reader_costs'])})"
          f": the cost of one more DDS reader")  # fmt: skip
    print(f"  control: beside a busy loop taking {100 * BURN_DUTY:.0f} % of one core, no DDS "
          f"{100 * cost['busy_loop_cost']:.1f} % ({', '.join(f'{100 * c:.1f} %' for c in cost['busy_loop_costs'])})"
          f"; the recorder took {100 * cost['recorder_cpu_share']:.0f} % of one core (median)")  # fmt: skip
    waits = {k: cost[f"wait_max_{k}"] for k in ("without", "with")}
    stalls = {k: sum(w > STALL_S for w in v) for k, v in waits.items()}
    print(f"  longest plant command wait per run (s): without --bag {', '.join(f'{w:.3f}' for w in waits['without'])}"
          f"; with --bag {', '.join(f'{w:.3f}' for w in waits['with'])} (stalls over {STALL_S:g} s: without "
          f"{stalls['without']}, with {stalls['with']} of {len(waits['with'])})")  # fmt: skip
    print(f"  start-up without --bag: the plant waited {', '.join(f'{w:.2f}' for w in cost['connect_s_without'])} s "
          f"for its peers and amb-rig's collector; the whole command took "
          f"{', '.join(f'{w:.1f}' for w in cost['command_s_without'])} s for {RIG_DURATION:g} s simulated")  # fmt: skip
    for line in cost["failed_runs"]:
        print(f"  FAILED run (its pair left out): {line}")
    pct = [100 * c for c in cost["pair_costs"]]
    record("recording cost: lockstep steps/s lost with --bag, back-to-back pairs", pct, "%", goal="< 20",
           note=f"lost {cost['lost']} messages")  # fmt: skip
    record("  control: beside a bare raw reader of the same topics", [100 * c for c in cost["bare_reader_costs"]], "%")
    record(f"  control: beside a busy loop of {100 * BURN_DUTY:.0f} % of one core, no DDS",
           [100 * c for c in cost["busy_loop_costs"]], "%")  # fmt: skip
    record("lockstep steps/s without --bag (the pairs above)", cost["runs_without"], "steps/s")
    record("lockstep steps/s with --bag (the pairs above)", cost["runs_with"], "steps/s")
    record("amb-rig start-up: the plant's wait for its peers and the collector (runs without --bag)",
           cost["connect_s_without"], "s", goal="< 1")  # fmt: skip
    record(f"amb-rig run --duration {RIG_DURATION:g} --no-monitor, whole command (runs without --bag)",
           cost["command_s_without"], "s")  # fmt: skip
    return cost


if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("--reader", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--burn", type=float, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.reader:
        bare_reader()
    elif args.burn:
        busy_loop(args.burn)
    else:
        from amb_ros.env import ensure_localhost_dds

        ensure_localhost_dds()
        main()
