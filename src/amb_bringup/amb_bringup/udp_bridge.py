"""Example rig bridge: UDP frames of a real-time target <-> /amb/displacement and /amb/current (docs/rig-bridge.md).

    python -m amb_bringup.udp_bridge [--listen 127.0.0.1:47001] [--target 127.0.0.1:47002] [--config F]
                                     [--set key=value]... [--duration S]

A real rig's I/O computer (the "target": a DSP, an FPGA, a real-time PC) samples the four AMB displacement
channels and drives the amplifiers; this node stands between it and ``amb-rig run --no-plant --mode realtime``.

Frames (little endian; n = the number of channels, 4 for the seed rotor, in the order of the config's channel
names, e.g. amb1_y, amb1_z, amb5_y, amb5_z):

* target -> bridge, one per sample: ``b"AMBD"``, uint32 sequence number, int64 target time (ns, the target's own
  clock, opaque to the bridge), n float64 displacements (m).
* bridge -> target, one per command: ``b"AMBC"``, the uint32 sequence number and int64 target time of the sample
  the command answers (echoed), n float64 coil control currents (A).

Each sample is published on /amb/displacement (sensor_msgs/JointState, ``name`` = channels, ``position`` = m) with
``header.stamp`` = this machine's system clock when the frame arrived (realtime stamps are the sampling time on
the ROS side; the controller's current keeps the stamp, which is how the bridge finds the sample a command
answers).  QoS: sensor data (best effort, keep last 5), as amb-rig's realtime nodes.  A command for a sample the
bridge no longer knows (older than ``KEEP`` samples) is dropped and counted.  The bridge binds 127.0.0.1 unless
told otherwise.  No watchdog here: the target must hold, then zero, its currents when commands stop (see the doc).
"""

from __future__ import annotations

import argparse
import socket
import struct
import sys
import threading
import time
from collections import OrderedDict

HEADER = struct.Struct("<4sIq")
SAMPLE_MAGIC, COMMAND_MAGIC = b"AMBD", b"AMBC"
KEEP = 1000  # samples remembered for matching their commands


def frame(magic: bytes, seq: int, t_ns: int, values) -> bytes:
    """One frame: header and float64 values."""
    return HEADER.pack(magic, seq & 0xFFFFFFFF, t_ns) + struct.pack(f"<{len(values)}d", *values)


def unframe(data: bytes, magic: bytes, n: int) -> tuple[int, int, tuple[float, ...]] | None:
    """(sequence, target time, values) of a frame with ``magic`` and ``n`` values, else None."""
    if len(data) != HEADER.size + 8 * n or data[:4] != magic:
        return None
    _, seq, t_ns = HEADER.unpack_from(data)
    return seq, t_ns, struct.unpack_from(f"<{n}d", data, HEADER.size)


def address(text: str) -> tuple[str, int]:
    host, _, port = text.rpartition(":")
    try:
        return socket.gethostbyname(host or "127.0.0.1"), int(port)
    except (OSError, ValueError):
        raise argparse.ArgumentTypeError(f"{text!r}: expected HOST:PORT") from None


class Bridge:
    """The rclpy node and the UDP socket; ``run()`` until the duration ends or the process is stopped."""

    def __init__(self, args, stop):
        import rclpy
        from sensor_msgs.msg import JointState

        from amb_dynamics.config import load_config
        from amb_dynamics.structure import build_structure
        from amb_ros import messages as m
        from amb_ros.qos import realtime_qos

        self.rclpy, self.JointState, self.stop, self.args = rclpy, JointState, stop, args
        self.channels = build_structure(load_config(args.config, args.set)).channels
        self.node = rclpy.create_node("amb_udp_bridge")
        self.pub = self.node.create_publisher(JointState, m.DISPLACEMENT, realtime_qos())
        self.node.create_subscription(JointState, m.CURRENT, self.on_command, realtime_qos())
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(args.listen)
        self.sock.settimeout(0.05)
        self.pending: OrderedDict[int, tuple[int, int]] = OrderedDict()  # stamp ns -> (seq, target time)
        self.lock = threading.Lock()
        self.samples = self.commands = self.dropped = self.bad_frames = 0

    def on_command(self, msg) -> None:
        t_ns = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        with self.lock:
            ident = self.pending.pop(t_ns, None)
        try:
            values = [msg.effort[list(msg.name).index(name)] for name in self.channels]  # names say the order
        except (ValueError, IndexError):
            values = None
        if ident is None or values is None:
            self.dropped += 1
            return
        self.sock.sendto(frame(COMMAND_MAGIC, ident[0], ident[1], values), self.args.target)
        self.commands += 1

    def receive(self) -> None:
        n = len(self.channels)
        while not self.stop.is_set():
            try:
                data = self.sock.recv(65536)
            except TimeoutError:
                continue
            got = unframe(data, SAMPLE_MAGIC, n)
            if got is None:
                self.bad_frames += 1
                continue
            seq, target_ns, values = got
            msg = self.JointState()
            now = self.node.get_clock().now()
            msg.header.stamp = now.to_msg()
            msg.name = list(self.channels)
            msg.position = list(values)
            with self.lock:
                self.pending[now.nanoseconds] = (seq, target_ns)
                while len(self.pending) > KEEP:
                    self.pending.popitem(last=False)
            self.pub.publish(msg)
            self.samples += 1

    def run(self) -> int:
        from rclpy.executors import SingleThreadedExecutor

        rx = threading.Thread(target=self.receive, daemon=True)
        rx.start()
        executor = SingleThreadedExecutor()
        executor.add_node(self.node)
        end = time.monotonic() + self.args.duration if self.args.duration > 0 else None
        while not self.stop.is_set() and (end is None or time.monotonic() < end):
            executor.spin_once(timeout_sec=0.05)
        self.stop.set()
        rx.join(2)
        print(f"amb_udp_bridge: {self.samples} samples in, {self.commands} commands out, {self.dropped} commands "
              f"dropped, {self.bad_frames} bad frames", flush=True)  # fmt: skip
        self.node.destroy_node()
        self.sock.close()
        return 0


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(prog="amb_udp_bridge", description=__doc__.splitlines()[0])
    ap.add_argument("--listen", type=address, default=("127.0.0.1", 47001), help="HOST:PORT the target sends to")
    ap.add_argument("--target", type=address, default=("127.0.0.1", 47002), help="HOST:PORT of the target")
    ap.add_argument("--config", help="rotor config YAML (channel names; default: the seed rotor)")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="config override")
    ap.add_argument("--duration", type=float, default=0.0, help="wall s to run (0: until SIGINT/SIGTERM)")
    args = ap.parse_args(argv)
    from amb_dynamics.errors import AmbError
    from amb_ros.env import DdsEnvError, ensure_localhost_dds
    from amb_ros.fastdds import init_rclpy

    try:
        ensure_localhost_dds()
    except DdsEnvError as exc:
        print(f"amb_udp_bridge: {exc}", file=sys.stderr)
        sys.exit(2)
    import signal

    import rclpy
    from rclpy.signals import SignalHandlerOptions

    stop = threading.Event()
    signal.signal(signal.SIGINT, lambda *_: stop.set())
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    init_rclpy(args=[], signal_handler_options=SignalHandlerOptions.NO)  # stopped by ``stop``, cleanly
    try:
        code = Bridge(args, stop).run()
    except (AmbError, OSError) as exc:
        print(f"amb_udp_bridge: {exc}", file=sys.stderr)
        code = 2
    finally:
        rclpy.try_shutdown()
    sys.exit(code)


if __name__ == "__main__":
    main()
