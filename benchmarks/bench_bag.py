"""Recorder throughput for the lockstep message mix: the in-process write path and end to end over DDS.

1. Write path: ``BagWriter.write`` of pre-serialized CDR bytes (what the recorder does per message), per chunk
   compression.  Goal >= 50,000 msg/s.
2. End to end: a recorder process (``amb-bag record``) and a publisher process publishing the mix flat out
   (reliable, KEEP_ALL, so a lagging recorder slows the publisher instead of losing messages); the rate is
   messages recorded / span of their reception times, and the loss table must be all zeros.

The recording cost of the lockstep loop is benchmarks/bench_recording_cost.py.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from report import record, record_ratio

CHANNELS = ["amb1_y", "amb1_z", "amb5_y", "amb5_z"]
DOFS = [f"n{n}_{d}" for n in range(1, 8) for d in ("v", "w", "ty", "tz")]
WRITE_STEPS = 10_000
STATE_BLOCK = 25  # the plant's default state_block (and base_motion's rates_block): one block per 25 steps
# steps between messages of each topic of the mix, as the nodes publish them by default (docs/topics.md)
EVERY = {"/clock": 5, "/base/rates": STATE_BLOCK, "/base/imu": 5, "/base/angular_acceleration": 5,
         "/amb/displacement": 1, "/amb/current": 1, "/amb_plant/state": STATE_BLOCK}  # fmt: skip
_STEPS_APART = list(EVERY.values())
E2E_STEPS = 5_000
GOAL_MSG_S = 50_000
ROUNDS = 3  # flood rounds (bimodal DDS delivery: ~10k or ~30-60k msg/s per round, see docs/bags.md)
PACED_STEPS_S = 4000  # 20,160 msg/s offered: above what the recorder sustains here, so it shows its capacity
BIN = Path(sys.executable).parent


def lockstep_mix() -> list[tuple[str, str, bytes]]:
    """One lockstep step of the docs/topics.md topics as (topic, type, CDR bytes); sizes as the nodes publish them."""
    from geometry_msgs.msg import Vector3Stamped
    from rclpy.serialization import serialize_message
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import Imu, JointState
    from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

    disp = JointState(name=CHANNELS, position=[1e-5, -2e-5, 3e-5, 4e-6])
    current = JointState(name=CHANNELS, effort=[0.1, -0.2, 0.3, 0.04])
    state = JointTrajectory(
        joint_names=DOFS, points=[JointTrajectoryPoint(positions=[1e-6] * 28, velocities=[1e-4] * 28)] * STATE_BLOCK
    )
    rates = JointTrajectory(
        joint_names=["omega_x", "omega_y", "omega_z"],
        points=[JointTrajectoryPoint(positions=[0.0, 0.0, 7.35], velocities=[0.0, 0.0, -54.0])] * STATE_BLOCK,
    )
    imu = Imu()
    imu.orientation.w = 1.0
    mix = [
        ("/clock", "rosgraph_msgs/msg/Clock", serialize_message(Clock())),
        ("/base/rates", "trajectory_msgs/msg/JointTrajectory", serialize_message(rates)),
        ("/base/imu", "sensor_msgs/msg/Imu", serialize_message(imu)),
        ("/base/angular_acceleration", "geometry_msgs/msg/Vector3Stamped", serialize_message(Vector3Stamped())),
        ("/amb/displacement", "sensor_msgs/msg/JointState", serialize_message(disp)),
        ("/amb/current", "sensor_msgs/msg/JointState", serialize_message(current)),
        ("/amb_plant/state", "trajectory_msgs/msg/JointTrajectory", serialize_message(state)),
    ]
    assert [t for t, _, _ in mix] == list(EVERY)
    return mix


def due(i: int, k: int) -> bool:
    """Entry ``i`` of the mix (the order of ``EVERY``) is published at step ``k``."""
    return (k + 1) % _STEPS_APART[i] == 0


def published_in(steps: int) -> list[int]:
    """Messages per mix entry in ``steps`` steps."""
    return [sum(due(i, k) for k in range(steps)) for i in range(len(lockstep_mix()))]


def bench_write_path(tmp: Path, compression: str, steps: int = WRITE_STEPS) -> dict:
    """Messages per second through BagWriter.write (in-process, file on disk, close included)."""
    from amb_bag.writer import BagWriter

    offer = [{"history": "keep_last", "depth": 1000, "reliability": "reliable", "durability": "volatile"}]
    mix = lockstep_mix()
    tmp.mkdir(parents=True, exist_ok=True)
    bag = tmp / f"write_{compression}"
    writer = BagWriter(bag, compression=compression)
    ids = [writer.add_topic(t, ty, offer) for t, ty, _ in mix]
    items = [(i, data) for i, (_, _, data) in zip(ids, mix, strict=True)]
    write, t_ns = writer.write, time.time_ns()
    t0 = time.perf_counter()
    for k in range(steps):
        stamp = t_ns + k * 200_000
        for i, (tid, data) in enumerate(items):
            if due(i, k):
                write(tid, stamp, data, stamp)
    writer.close()
    seconds = time.perf_counter() - t0
    n = sum(published_in(steps))
    size = sum(f.stat().st_size for f in bag.glob("*.mcap"))
    return {"messages": n, "seconds": seconds, "msg_per_s": n / seconds, "bytes_per_msg_on_disk": size / n}


def flood_publisher(steps: int, diagnostics: bool = True, rate: float = 0.0) -> None:
    """Child process: publish ``steps`` lockstep steps flat out, then a /diagnostics report with the counts."""
    from amb_ros.env import ensure_localhost_dds

    ensure_localhost_dds()
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
    from rclpy.duration import Duration
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

    from amb_bag.msgdefs import message_class
    from amb_ros.fastdds import init_rclpy

    init_rclpy()  # as the nodes start DDS (like with like)
    node = rclpy.create_node("bag_bench_flood", enable_rosout=False)
    qos = QoSProfile(history=HistoryPolicy.KEEP_ALL, depth=1000, reliability=ReliabilityPolicy.RELIABLE)
    mix = lockstep_mix()
    pubs = [node.create_publisher(message_class(ty), t, qos) for t, ty, _ in mix]
    diag = node.create_publisher(DiagnosticArray, "/diagnostics", qos)
    while any(p.get_subscription_count() == 0 for p in [*pubs, diag] if diagnostics or p is not diag):
        time.sleep(0.02)
    time.sleep(0.2)
    items = [(p.publish, data) for p, (_, _, data) in zip(pubs, mix, strict=True)]
    t0 = time.perf_counter()
    for k in range(steps):
        for i, (publish, data) in enumerate(items):
            if due(i, k):
                publish(data)
        if rate and (delay := t0 + (k + 1) / rate - time.perf_counter()) > 0:
            time.sleep(delay)
    seconds = time.perf_counter() - t0
    counts = published_in(steps)
    values = [KeyValue(key=f"published {t}", value=str(n)) for (t, _, _), n in zip(mix, counts, strict=True)]
    status = DiagnosticStatus(name="bag_bench_flood", values=values)
    status.values.append(KeyValue(key="published /diagnostics", value="1"))
    if diagnostics:
        diag.publish(DiagnosticArray(status=[status]))
    for p in [*pubs, diag]:
        p.wait_for_all_acked(Duration(seconds=30))
    print(f"flood: published {sum(counts)} in {seconds:.3f} s", flush=True)
    node.destroy_node()
    rclpy.try_shutdown()


def bare_sink(expected: int) -> None:
    """Child process: the DDS limit. Raw subscriptions drained with take_message, nothing written."""
    from amb_ros.env import ensure_localhost_dds

    ensure_localhost_dds()
    import rclpy
    from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

    from amb_bag.msgdefs import message_class
    from amb_ros.fastdds import init_rclpy

    init_rclpy()  # as the nodes start DDS (like with like)
    node = rclpy.create_node("bag_bench_sink", enable_rosout=False)
    qos = QoSProfile(history=HistoryPolicy.KEEP_ALL, depth=1000, reliability=ReliabilityPolicy.RELIABLE)
    subs = [node.create_subscription(message_class(ty), t, lambda _m: None, qos, raw=True) for t, ty, _ in
            lockstep_mix()]  # fmt: skip
    wait_set = _rclpy.WaitSet(len(subs), 0, 0, 0, 0, 0, node.context.handle)
    n, first, last, give_up = 0, None, None, time.monotonic() + 60
    while n < expected and time.monotonic() < give_up:
        wait_set.clear_entities()
        for sub in subs:
            wait_set.add_subscription(sub.handle)
        wait_set.wait(100_000_000)
        for sub in subs:
            while (taken := sub.handle.take_message(sub.msg_type, True)) is not None:
                last = taken[1]["received_timestamp"]
                first = first or last
                n += 1
                give_up = time.monotonic() + 5  # stop 5 s after the last message if some never come
    print(f"sink: received {n} in {(last - first) * 1e-9 if n else 0:.6f} s", flush=True)
    node.destroy_node()
    rclpy.try_shutdown()


def _sink_baseline(steps: int) -> dict:
    """Messages/s a bare raw subscriber receives from the same flood (measured in the same run)."""

    expected = sum(published_in(steps))
    sink = subprocess.Popen([sys.executable, __file__, "--sink", str(expected)], stdout=subprocess.PIPE, text=True)
    try:
        pub = subprocess.run([sys.executable, __file__, "--flood", str(steps), "--no-diagnostics"],
                             capture_output=True, text=True, timeout=600)  # fmt: skip
        out, _ = sink.communicate(timeout=120)
    finally:
        if sink.poll() is None:
            sink.kill()
            sink.wait()
    if pub.returncode != 0 or sink.returncode != 0:
        raise RuntimeError("baseline sink or publisher failed")
    n, seconds = int(out.split()[2]), float(out.split()[4])
    return {"messages": n, "seconds": seconds, "msg_per_s": n / seconds}


def bench_end_to_end(tmp: Path, steps: int = E2E_STEPS, rate: float = 0.0) -> dict:
    """Recorder process vs a publisher process over DDS (localhost), flat out or paced at ``rate`` steps/s."""

    from amb_bag.launch import RecorderProcess
    from amb_bag.metadata import load_metadata

    tmp.mkdir(parents=True, exist_ok=True)
    bag = tmp / f"e2e_{rate:g}"
    topics = [t for t, _, _ in lockstep_mix()] + ["/diagnostics"]
    with RecorderProcess(bag, topics=topics, log_path=tmp / "e2e-record.log") as rec:
        pub = subprocess.run([sys.executable, __file__, "--flood", str(steps), "--rate", str(rate)],
                             capture_output=True, text=True, timeout=600)  # fmt: skip
        if pub.returncode != 0:
            raise RuntimeError(f"flood publisher failed: {pub.stderr.strip()[-300:]}")
        rc = rec.stop()
    if rc != 0:
        raise RuntimeError(f"recorder exited {rc}: {rec.text()[-300:]}")
    meta = load_metadata(bag)
    data_topics = [e for e in meta["topics_with_message_count"] if e["topic_metadata"]["name"] != "/diagnostics"]
    n = sum(e["message_count"] for e in data_topics)
    seconds = meta["duration"]["nanoseconds"] * 1e-9
    pub_seconds = float(pub.stdout.split(" in ")[1].split()[0])
    rows = rec.loss()
    return {
        "messages": n,
        "expected": sum(published_in(steps)),
        "seconds": seconds,
        "msg_per_s": n / seconds,
        "publisher_msg_per_s": sum(published_in(steps)) / pub_seconds,
        "lost": sum(r["lost"] or 0 for r in rows.values()),
    }


def main() -> dict:
    tmp = Path(tempfile.mkdtemp(prefix="bench_bag_"))
    try:
        write_runs = {c: [bench_write_path(tmp / f"w{i}", c) for i in range(3)] for c in ("zstd", "lz4", "none")}
        write = {c: max(runs, key=lambda r: r["msg_per_s"]) for c, runs in write_runs.items()}  # best of 3: shared
        # Flood: recorder and bare subscriber alternately, best of ROUNDS each (the machine is shared and noisy).
        floods, sinks = [], []
        for i in range(ROUNDS):
            floods.append(bench_end_to_end(tmp / f"round{i}"))
            sinks.append(_sink_baseline(E2E_STEPS))
        e2e = max(floods, key=lambda r: r["msg_per_s"])
        e2e["lost"] = sum(r["lost"] for r in floods)
        e2e["bare_subscriber"] = max(sinks, key=lambda r: r["msg_per_s"])
        paced = bench_end_to_end(tmp, 2 * E2E_STEPS, rate=PACED_STEPS_S)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    print(
        "recorder throughput, lockstep mix (displacement, current per step; clock, imu, angular acc. per 5; state "
        "and base-rate blocks per 25)"
    )
    print(f"  (write path best of 3 runs of {sum(published_in(WRITE_STEPS)):,} messages)")
    for c, r in write.items():
        print(f"  write path, {c:<4}  {r['msg_per_s']:10,.0f} msg/s  {r['bytes_per_msg_on_disk']:6.1f} B/msg on disk "
              f"(goal >= {GOAL_MSG_S:,}: {'ok' if r['msg_per_s'] >= GOAL_MSG_S else 'MISSED'})")  # fmt: skip
    print(f"  end to end, flood   {e2e['msg_per_s']:10,.0f} msg/s recorded, best of {ROUNDS} "
          f"({e2e['messages']}/{e2e['expected']} messages, lost {e2e['lost']}); "
          f"publisher alone {e2e['publisher_msg_per_s']:,.0f} msg/s")  # fmt: skip
    print(f"  paced publisher, {PACED_STEPS_S} steps/s ({sum(published_in(PACED_STEPS_S)):,} msg/s offered): recorded "
          f"{paced['msg_per_s']:,.0f} msg/s sustained, lost {paced['lost']}")  # fmt: skip
    base = e2e["bare_subscriber"]["msg_per_s"]
    print(f"  bare raw subscriber (DDS limit, same flood) {base:10,.0f} msg/s, best of {ROUNDS}")
    print(f"  ratio recorder / bare subscriber: {e2e['msg_per_s'] / base:.2f}")
    for c, runs in write_runs.items():
        record(f"recorder write path, lockstep message mix, {c}", [r["msg_per_s"] for r in runs], "msg/s",
               goal=">= 50,000" if c == "zstd" else None)  # fmt: skip
    record("recorder end to end through DDS, flood", [r["msg_per_s"] for r in floods], "msg/s",
           note=f"lost {e2e['lost']}")  # fmt: skip
    record_ratio("recorder / bare raw subscriber, same flood", [r["msg_per_s"] for r in floods],
                 [r["msg_per_s"] for r in sinks])  # fmt: skip
    record(f"recorder, paced publisher at {PACED_STEPS_S} steps/s", paced["msg_per_s"], "msg/s",
           note=f"lost {paced['lost']}")  # fmt: skip
    return {"write_path": write, "end_to_end": e2e, "paced": paced}


if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("--flood", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--no-diagnostics", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--sink", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--rate", type=float, default=0.0, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.flood:
        flood_publisher(args.flood, diagnostics=not args.no_diagnostics, rate=args.rate)
    elif args.sink:
        bare_sink(args.sink)
    else:
        from amb_ros.env import ensure_localhost_dds

        ensure_localhost_dds()
        main()
