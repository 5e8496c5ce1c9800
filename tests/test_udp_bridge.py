"""The example rig bridge (docs/rig-bridge.md): a fake real-time target on loopback UDP, a fake controller on DDS.

The target sends displacement frames; the bridge publishes them on /amb/displacement; a stand-in controller in this
process answers each with effort = -GAIN * position (channel names in reverse order, which the bridge must undo)
and the sample's stamp; the bridge sends command frames back.  Checked at the target: the sequence number and
target time of each answer echo a sample that was sent, and the currents equal -GAIN times that sample's
displacements, channel by channel (computed here, independently of the bridge).
"""

from __future__ import annotations

import socket
import sys
import threading
import time

import pytest

from amb_bringup.udp_bridge import COMMAND_MAGIC, SAMPLE_MAGIC, frame, unframe
from helpers import DdsRecorder
from procs import spawn

pytestmark = pytest.mark.ros

CHANNELS = ("amb1_y", "amb1_z", "amb5_y", "amb5_z")  # the seed rotor's, in the config's order
GAIN = 2000.0  # A/m
FRAMES = 200
PERIOD_S = 0.01  # 100 Hz: best-effort QoS on a shared, loaded machine (at 500 Hz a busy test process dropped half)


def test_frames_round_trip():
    data = frame(SAMPLE_MAGIC, 7, -5, (1.0, 2.5, -3.0, 4e-6))
    assert len(data) == 16 + 32 and unframe(data, SAMPLE_MAGIC, 4) == (7, -5, (1.0, 2.5, -3.0, 4e-6))
    assert unframe(data, COMMAND_MAGIC, 4) is None and unframe(data[:-1], SAMPLE_MAGIC, 4) is None


class FakeController:
    """Answers /amb/displacement with -GAIN * position on /amb/current, names reversed, stamp kept."""

    def __init__(self):
        from sensor_msgs.msg import JointState

        from amb_ros.qos import realtime_qos

        self.rec = DdsRecorder({}, qos=realtime_qos())
        self.JointState = JointState
        self.pub = self.rec.node.create_publisher(JointState, "/amb/current", realtime_qos())
        self.rec.node.create_subscription(JointState, "/amb/displacement", self.answer, realtime_qos())

    def answer(self, msg):
        out = self.JointState()
        out.header.stamp = msg.header.stamp
        out.name = list(reversed(msg.name))
        out.effort = [-GAIN * v for v in reversed(msg.position)]
        self.pub.publish(out)

    def close(self):
        self.rec.close()


def test_bridge_translates_target_frames_to_dds_and_back(tmp_path):
    target = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    target.bind(("127.0.0.1", 0))
    target.settimeout(0.05)
    probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    probe.bind(("127.0.0.1", 0))
    listen_port = probe.getsockname()[1]
    probe.close()
    cmd = [sys.executable, "-m", "amb_bringup.udp_bridge", "--listen", f"127.0.0.1:{listen_port}",
           "--target", f"127.0.0.1:{target.getsockname()[1]}"]  # fmt: skip
    ctl = FakeController()
    replies, sent = [], {}
    stop = threading.Event()

    def collect():
        while not stop.is_set():
            try:
                replies.append(unframe(target.recv(1024), COMMAND_MAGIC, 4))
            except TimeoutError:
                continue

    rx = threading.Thread(target=collect, daemon=True)
    try:
        with spawn(cmd, tmp_path / "bridge.log") as bridge:
            rx.start()
            # warm-up: frames until the first answer comes back (bridge started, DDS matched both ways)
            deadline = time.monotonic() + 60
            k = 0
            while not replies and time.monotonic() < deadline and bridge.popen.poll() is None:
                target.sendto(frame(SAMPLE_MAGIC, k, 0, (0.0,) * 4), ("127.0.0.1", listen_port))
                k += 1
                time.sleep(0.05)
            assert replies, bridge.text()[-2000:]
            time.sleep(0.3)
            replies.clear()
            for k in range(1000, 1000 + FRAMES):  # distinct values per channel
                y = (1e-5 * k, -2e-5, 3e-5 + 1e-9 * k, 4e-6 * (k % 7))
                sent[k] = (k * 1_000_003, y)
                target.sendto(frame(SAMPLE_MAGIC, k, k * 1_000_003, y), ("127.0.0.1", listen_port))
                time.sleep(PERIOD_S)
            time.sleep(0.5)
            bridge.stop()
            text = bridge.text()
    finally:
        stop.set()
        rx.join(2)
        ctl.close()
        target.close()
    answered = [r for r in replies if r is not None and r[0] in sent]
    assert len(answered) >= 0.9 * FRAMES, (len(answered), text[-1500:])  # best effort: a few may drop
    assert len({r[0] for r in answered}) == len(answered)  # each sample answered once
    for seq, t_ns, current in answered:
        assert t_ns == sent[seq][0]
        assert current == tuple(-GAIN * v for v in sent[seq][1])  # channel order restored, exact doubles
    # every command that reached the bridge answered a sample it had sent, and every frame was well formed
    assert "0 commands dropped, 0 bad frames" in text, text[-1500:]
