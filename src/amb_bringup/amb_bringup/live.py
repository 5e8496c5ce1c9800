"""amb-live: the rig's topics, live, in Foxglove (its WebSocket protocol, foxglove-sdk, 127.0.0.1 by default).

    amb-live [--port 8765] [--host 127.0.0.1] [--config F] [--set key=value]... [--currents]
    amb-rig run --live [--live-port 8765] ...            (starts amb-live beside the rig)

Open Foxglove, "Open connection", Foxglove WebSocket, ``ws://127.0.0.1:8765``, and import the layout
``docs/foxglove/amb-rig.layout.json``.  Channels (ROS 2 message types, CDR, ``ros2msg`` schemas, so Foxglove
decodes them as it decodes a ROS 2 bag):

- the rig's low-rate topics forwarded as received: /amb_plant/state (blocks of state_block samples),
  /stability/multipliers, /stability/unstable, /diagnostics (and /amb/current with ``--currents``);
- ``/live/displacement`` (sensor_msgs/JointState): the four AMB displacements y = Ba^T q (m), computed with the
  core's model from the last sample of each state block (200 Hz at 5 kHz with blocks of 25);
- ``/live/rho`` (std_msgs/Float64): the largest |multiplier| of each monitor refit;
- ``/live/orbit/<bearing>`` (sensor_msgs/JointState, 10 Hz): ``position`` = y, ``velocity`` = z of the last
  ``orbit_samples`` displacements of that bearing, then a NaN (a gap in the plot), then the clearance circle
  (radius = the air gap), for an x-y plot of the orbit inside its clearance.

What it costs the loop: it reads no per-step topic of the lockstep loop (the state comes in blocks; /amb/current is
per step and only read with ``--currents``), its readers are best effort, so a slow view drops messages
rather than holding the loop up, and its threads run under SCHED_IDLE (``--priority``, default ``idle``): it
gets only the CPU time that the loop's nodes leave.  It wakes DRAIN_S apart and takes every message that has
arrived meanwhile (readers deep enough for that interval), instead of waking for each one: on two cores any
wake-up beside the lockstep loop delays its next hand-over.
"""

from __future__ import annotations

import argparse
import copy
import math
import signal
import sys
import time
from collections import deque

import numpy as np

from amb_ros.scheduling import PRIORITIES

ORBIT_SAMPLES = 200
ORBIT_EVERY = 20  # state blocks between orbit messages (10 Hz at 5 kHz with blocks of 25)
CIRCLE_POINTS = 73
FORWARDED = {
    "/amb_plant/state": "trajectory_msgs/msg/JointTrajectory",
    "/stability/multipliers": "std_msgs/msg/Float64MultiArray",
    "/stability/unstable": "std_msgs/msg/Bool",
    "/diagnostics": "diagnostic_msgs/msg/DiagnosticArray",
}
LATCHED = ("/stability/unstable",)
REPEAT_S = 1.0
DRAIN_S = 0.05  # 20 Hz: the view's refresh
DRAIN_DEPTH = 64  # best-effort readers keep this many: > DRAIN_S x 200 blocks/s (5 kHz, blocks of 25), with margin
CURRENT = ("/amb/current", "sensor_msgs/msg/JointState")
JOINT_STATE = "sensor_msgs/msg/JointState"


def add_arguments(ap, prefix: str = "") -> None:
    """amb-live's options (``prefix`` 'live-' for amb-rig's)."""
    ap.add_argument(f"--{prefix}port", type=int, default=8765, help="Foxglove WebSocket port (0 = any free port)")
    ap.add_argument(f"--{prefix}host", default="127.0.0.1", help="address to bind (default: this machine only)")
    ap.add_argument(f"--{prefix}currents", action="store_true",
                    help="also forward /amb/current (a per-step topic: one more reader of the loop)")  # fmt: skip
    ap.add_argument(f"--{prefix}priority", choices=PRIORITIES, default="idle",
                    help="scheduling of its threads (default idle: SCHED_IDLE, the CPU the loop leaves)")  # fmt: skip


def channel(topic: str, type_name: str):
    """A Foxglove channel carrying ROS 2 CDR messages of ``type_name`` with rosbag2's ``ros2msg`` schema."""
    import foxglove

    from amb_bag.msgdefs import full_text

    schema = foxglove.Schema(name=type_name, encoding="ros2msg", data=full_text(type_name).encode())
    return foxglove.Channel(topic, schema=schema, message_encoding="cdr")


class LiveBridge:
    """DDS messages in (serialized), Foxglove channels out; the displacement and orbit channels derived here."""

    def __init__(self, cfg, currents: bool = False):
        from amb_dynamics.structure import build_structure
        from amb_ros.messages import joint_state_codec
        from amb_ros.state_block import StateBlockDecoder

        model = build_structure(cfg)
        self.Ba = np.asarray(model.Ba)  # (n, 4): y = Ba^T q
        self.channels = tuple(model.channels)
        self.gap = float(cfg.bearings.air_gap)
        self.decoder = StateBlockDecoder(tuple(model.dof_names), 25)
        self.forward = {t: channel(t, ty) for t, ty in FORWARDED.items()}
        if currents:
            self.forward[CURRENT[0]] = channel(*CURRENT)
        self.disp = channel("/live/displacement", JOINT_STATE)
        self.rho = channel("/live/rho", "std_msgs/msg/Float64")
        self.disp_codec = joint_state_codec(self.channels, ("position",))
        self.bearings = sorted({c.rsplit("_", 1)[0] for c in self.channels})
        self.orbit = {b: channel(f"/live/orbit/{b}", JOINT_STATE) for b in self.bearings}
        self.orbit_codec = {}
        self.history: deque = deque(maxlen=ORBIT_SAMPLES)
        theta = np.linspace(0.0, 2.0 * math.pi, CIRCLE_POINTS)
        self.circle = (self.gap * np.cos(theta), self.gap * np.sin(theta))
        self.blocks = self.rejected = 0
        self.latched: dict[str, bytes] = {}

    def repeat_latched(self, log_time_ns: int) -> None:
        """Send the latest value of latched topics again (every REPEAT_S): a client that connects or subscribes
        later still sees the current flag, as a late ROS subscriber of the latched topic does."""
        for topic, raw in self.latched.items():
            self.forward[topic].log(raw, log_time=log_time_ns)

    def on_message(self, topic: str, raw: bytes, log_time_ns: int) -> None:
        self.forward[topic].log(raw, log_time=log_time_ns)
        if topic in LATCHED:
            self.latched[topic] = raw
        if topic == "/amb_plant/state":
            self.on_state(raw, log_time_ns)
        elif topic == "/stability/multipliers":
            self.on_multipliers(raw, log_time_ns)

    def on_multipliers(self, raw: bytes, log_time_ns: int) -> None:
        """/live/rho: the largest |multiplier| of each refit (the monitor's [k, 2] re/im layout)."""
        from rclpy.serialization import deserialize_message, serialize_message
        from std_msgs.msg import Float64, Float64MultiArray

        data = np.asarray(deserialize_message(raw, Float64MultiArray).data, dtype=float)
        if data.size >= 2 and data.size % 2 == 0:
            rho = float(np.hypot(data[0::2], data[1::2]).max())
            self.rho.log(serialize_message(Float64(data=rho)), log_time=log_time_ns)

    def on_state(self, raw: bytes, log_time_ns: int) -> None:
        from amb_ros.messages import Rejected

        try:
            stamps, rows = self.decoder(raw)
        except Rejected:
            self.rejected += 1
            return
        n = self.Ba.shape[0]
        y = rows[-1, :n] @ self.Ba  # the block's last sample: one displacement per block
        self.disp.log(self.disp_codec.encode(int(stamps[-1]), y), log_time=log_time_ns)
        self.history.append(y)
        self.blocks += 1
        if self.blocks % ORBIT_EVERY == 1:
            self.publish_orbits(int(stamps[-1]), log_time_ns)

    def publish_orbits(self, stamp_ns: int, log_time_ns: int) -> None:
        from rclpy.serialization import serialize_message
        from sensor_msgs.msg import JointState

        hist = np.array(self.history)
        for b in self.bearings:
            iy, iz = self.channels.index(f"{b}_y"), self.channels.index(f"{b}_z")
            msg = JointState(name=[b])
            msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp_ns, 10**9)
            msg.position = [*hist[:, iy].tolist(), math.nan, *self.circle[0].tolist()]
            msg.velocity = [*hist[:, iz].tolist(), math.nan, *self.circle[1].tolist()]
            self.orbit[b].log(serialize_message(msg), log_time=log_time_ns)


def run(args) -> int:
    import foxglove
    import rclpy
    from rclpy.qos import qos_profile_sensor_data
    from rclpy.signals import SignalHandlerOptions

    from amb_bag.msgdefs import message_class
    from amb_dynamics.config import load_config
    from amb_dynamics.errors import InputError
    from amb_ros.fastdds import init_rclpy
    from amb_ros.qos import diagnostics_qos, latched_qos
    from amb_ros.scheduling import consumer_priority

    cfg = load_config(args.config, args.set)
    try:  # before DDS starts: a port in use is a one-line error
        server = foxglove.start_server(name="amb-rig", host=args.host, port=args.port)
    except RuntimeError as exc:
        raise InputError(f"cannot serve on {args.host}:{args.port} ({str(exc).splitlines()[0]})") from None
    stop = []
    init_rclpy(args=[], signal_handler_options=SignalHandlerOptions.NO)  # stop cleanly on our own flag
    signal.signal(signal.SIGINT, lambda *_: stop.append(1))
    signal.signal(signal.SIGTERM, lambda *_: stop.append(1))
    node = rclpy.create_node("amb_live", enable_rosout=False, start_parameter_services=False)
    scheduling = consumer_priority(args.priority)  # after the server and the node: their threads are included
    bridge = LiveBridge(cfg, args.currents)
    qos = {"/stability/unstable": latched_qos(), "/diagnostics": diagnostics_qos()}
    sensor = copy.copy(qos_profile_sensor_data)
    sensor.depth = DRAIN_DEPTH
    clock = node.get_clock()
    for topic in bridge.forward:
        node.create_subscription(
            message_class(FORWARDED.get(topic, CURRENT[1])), topic,
            lambda raw, t=topic: bridge.on_message(t, raw, clock.now().nanoseconds),
            qos.get(topic, sensor), raw=True,
        )  # fmt: skip
    print(f"amb-live: Foxglove WebSocket on ws://{args.host}:{server.port} ({scheduling})", flush=True)
    executor = rclpy.executors.SingleThreadedExecutor()
    executor.add_node(node)
    next_repeat = time.monotonic()
    try:
        while not stop:
            time.sleep(DRAIN_S)  # a signal sets the flag; the sleep ends within DRAIN_S
            drain(executor)
            if time.monotonic() >= next_repeat:
                next_repeat += REPEAT_S
                bridge.repeat_latched(clock.now().nanoseconds)
    finally:
        server.stop()
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
    print(f"amb-live: {bridge.blocks} state blocks shown ({bridge.rejected} rejected)", flush=True)
    return 0


def drain(executor) -> int:
    """Run the callback of every message that is ready now (no waiting); returns how many ran."""
    from rclpy.executors import ShutdownException, TimeoutException

    n = 0
    while True:
        try:
            handler, _, _ = executor.wait_for_ready_callbacks(timeout_sec=0)
        except (TimeoutException, ShutdownException):
            return n
        handler()
        if handler.exception() is not None:
            raise handler.exception()
        n += 1


def main(argv: list[str] | None = None) -> None:
    from amb_dynamics.errors import AmbError
    from amb_ros.env import DdsEnvError, ensure_localhost_dds

    ap = argparse.ArgumentParser(prog="amb-live", description="Serve the rig's topics to Foxglove (WebSocket).")
    add_arguments(ap)
    ap.add_argument("--config", help="rotor config YAML (default: the seed rotor), as the rig's")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="config override, as the rig's")
    args = ap.parse_args(argv)
    try:
        ensure_localhost_dds()
        sys.exit(run(args))
    except (AmbError, DdsEnvError) as exc:
        print(f"amb-live: {exc}", file=sys.stderr)
        sys.exit(2)


def live_process(args, run_dir):
    """``amb-live`` beside the rig for ``amb-rig run --live`` (amb_bringup.processes.EXTRA_PROCESSES)."""
    from pathlib import Path

    from .supervisor import ProcessSpec

    if not getattr(args, "live", False):
        return None
    exe = Path(sys.executable).parent / "amb-live"
    cmd = [str(exe) if exe.is_file() else "amb-live", "--port", str(args.live_port), "--host", args.live_host]
    cmd += ["--currents"] if args.live_currents else []
    cmd += ["--priority", args.live_priority]
    cmd += ["--config", str(Path(args.config).resolve())] if args.config else []
    for item in args.set:
        cmd += ["--set", item]
    return ProcessSpec("live", cmd, node=None, required=True, stop_tier=1)


if __name__ == "__main__":
    main()
