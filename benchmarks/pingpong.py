"""The bare rclpy ping-pong of benchmarks/bench_lockstep.py: two processes echo a 4-channel JointState with the
nodes' own transport settings (reliable, transient local, raw CDR, one reused wait set, synchronous Fast DDS
publication), on the nodes' wait-set path or driven by an executor's callbacks (EventsExecutor, SingleThreadedExecutor).

    .venv/bin/python benchmarks/pingpong.py [N]        round trips/s and CPU per round trip of each side
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time


def bench_env() -> dict:
    """The environment of every process a benchmark starts: one BLAS thread, synchronous publication."""
    from amb_ros.env import child_env
    from amb_ros.runtime import low_latency_dds

    env = child_env(OPENBLAS_NUM_THREADS="1")
    low_latency_dds(env)
    return env


def _pingpong_side(role: str, tag: str, n: int, path: str = "waitset") -> None:
    import numpy as np
    import rclpy
    from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
    from sensor_msgs.msg import JointState

    from amb_ros.fastdds import init_rclpy
    from amb_ros.messages import joint_state_codec
    from amb_ros.qos import lockstep_qos

    init_rclpy()  # as the nodes start DDS (like with like)
    node = rclpy.create_node(f"pingpong_{role}")
    out_t, in_t = (
        (f"/bench/ping{tag}", f"/bench/pong{tag}") if role == "ping" else (f"/bench/pong{tag}", f"/bench/ping{tag}")
    )
    pub = node.create_publisher(JointState, out_t, lockstep_qos())
    sub = node.create_subscription(JointState, in_t, lambda _: None, lockstep_qos(), raw=True)
    codec = joint_state_codec(("amb1_y", "amb1_z", "amb5_y", "amb5_z"), ("position",))
    ws = _rclpy.WaitSet(1, 0, 0, 0, 0, 0, node.context.handle)
    end = time.monotonic() + 30.0
    while (pub.get_subscription_count() < 1 or node.count_publishers(in_t) < 1) and time.monotonic() < end:
        time.sleep(0.01)

    def receive() -> bytes:
        limit = time.monotonic() + 10.0
        while time.monotonic() < limit:
            out = sub.handle.take_message(sub.msg_type, True)
            if out is not None:
                return out[0]
            ws.clear_entities()
            ws.add_subscription(sub.handle)
            ws.wait(100_000_000)
        raise SystemExit(f"pingpong {role}: no message for 10 s")

    y = np.zeros(4)
    if path != "waitset":
        _pingpong_callbacks(role, n, path, node, pub, sub, codec)
        return
    if role == "ping":
        time.sleep(0.2)
        t0, c0 = time.perf_counter(), time.process_time()
        for k in range(n):
            y[0] = k
            pub.publish(codec.encode(k, y))
            if codec.decode(receive())[1][0] != k:
                raise SystemExit("pingpong: echo out of order")
        rate, cpu = n / (time.perf_counter() - t0), time.process_time() - c0
        print(json.dumps({"round_trips_per_s": rate, "cpu_us": 1e6 * cpu / n}), flush=True)
    else:  # the CPU of every thread of the process (time.process_time), from the first ping on
        pub.publish(receive())
        c0 = time.process_time()
        for _ in range(n - 1):
            pub.publish(receive())
        print(json.dumps({"cpu_us": 1e6 * (time.process_time() - c0) / (n - 1)}), flush=True)
        pub.wait_for_all_acked()
    node.destroy_node()
    rclpy.shutdown()


def _pingpong_callbacks(role: str, n: int, path: str, node, pub, sub_unused, codec) -> None:
    """The same ping-pong driven by subscription callbacks of an executor: rclpy's EventsExecutor
    (rclpy.experimental) or the standard SingleThreadedExecutor."""
    import numpy as np
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.experimental import EventsExecutor
    from rclpy.task import Future
    from sensor_msgs.msg import JointState

    from amb_ros.qos import lockstep_qos

    in_t = sub_unused.topic_name
    node.destroy_subscription(sub_unused)
    done, y, count, t0 = Future(), np.zeros(4), [0], [0.0]

    def on_message(raw: bytes) -> None:
        if role == "echo":
            pub.publish(raw)
            count[0] += 1
            if count[0] == n:
                done.set_result(True)
            return
        k = int(codec.decode(raw)[1][0])
        if k < count[0]:  # the echo of a resent first ping
            return
        if k != count[0]:
            raise SystemExit("pingpong: echo out of order")
        count[0] += 1
        if count[0] == n:
            done.set_result(n / (time.perf_counter() - t0[0]))
            return
        y[0] = count[0]
        pub.publish(codec.encode(count[0], y))

    sub = node.create_subscription(JointState, in_t, on_message, lockstep_qos(), raw=True)
    executor = EventsExecutor() if path == "events" else SingleThreadedExecutor()
    executor.add_node(node)
    end = time.monotonic() + 30.0  # both of this side's endpoints matched again (the new subscription too)
    while (pub.get_subscription_count() < 1 or sub.get_publisher_count() < 1) and time.monotonic() < end:
        time.sleep(0.01)
    time.sleep(0.5)  # and the other side's
    if role == "ping":  # the first ping again until it is echoed: a reader that did not yet know this writer
        for _ in range(20):  # drops a volatile sample (the later echoes of a resent one are ignored)
            t0[0] = time.perf_counter()
            pub.publish(codec.encode(0, y))
            while count[0] == 0 and time.perf_counter() - t0[0] < 0.5:
                executor.spin_once(timeout_sec=0.05)
            if count[0]:
                break
    executor.spin_until_future_complete(done, timeout_sec=60.0)
    if not done.done():
        raise SystemExit(f"pingpong {role} ({path}): not finished in 60 s")
    if role == "ping":
        print(json.dumps({"round_trips_per_s": done.result()}), flush=True)
    else:  # a resent first ping makes one message more than n: echo until the ping side has left
        end = time.monotonic() + 5.0
        while node.count_publishers(in_t) > 0 and time.monotonic() < end:
            executor.spin_once(timeout_sec=0.05)
        pub.wait_for_all_acked()
    executor.shutdown()
    node.destroy_node()
    rclpy.shutdown()


def pingpong(n: int, path: str = "waitset") -> float:
    """Round trips/s of two processes echoing a 4-channel JointState: ``path`` waitset (the nodes' own wait-set
    loop), events (EventsExecutor callbacks) or single (SingleThreadedExecutor callbacks)."""
    return pingpong_detail(n, path)["round_trips_per_s"]


def pingpong_detail(n: int, path: str = "waitset") -> dict:
    """:func:`pingpong` with, on the wait-set path, the CPU time per round trip of each side's process, all
    threads (``ping_cpu_us``: publishes then takes, as the plant; ``echo_cpu_us``: takes then publishes, as the
    controller): what one lockstep step's DDS traffic costs rclpy with no computation at all."""
    env, tag = bench_env(), f"{os.getpid()}_{time.monotonic_ns() % 10**6}"
    cmd = [sys.executable, __file__, "--side"]
    echo = subprocess.Popen([*cmd, "echo", tag, str(n), path], env=env, stdout=subprocess.PIPE, text=True)
    try:
        out = subprocess.run([*cmd, "ping", tag, str(n), path], env=env, capture_output=True, text=True,
                             timeout=120)  # fmt: skip
    finally:
        try:
            echo_out = echo.communicate(timeout=15)[0]
        except subprocess.TimeoutExpired:
            echo.kill()
            echo_out = echo.communicate()[0]
    if out.returncode:
        raise RuntimeError(f"ping-pong failed: {out.stderr.strip()[-300:]}")
    ping = json.loads(out.stdout.strip().splitlines()[-1])
    result = {"round_trips_per_s": ping["round_trips_per_s"]}
    echo_lines = [ln for ln in (echo_out or "").splitlines() if ln.startswith("{")]
    if path == "waitset" and echo_lines:
        result.update(ping_cpu_us=ping["cpu_us"], echo_cpu_us=json.loads(echo_lines[-1])["cpu_us"])
    return result


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--side":
        _pingpong_side(sys.argv[2], sys.argv[3], int(sys.argv[4]), sys.argv[5])
        sys.exit(0)
    print(json.dumps(pingpong_detail(int(sys.argv[1]) if len(sys.argv) > 1 else 5000)))
