"""A publisher that lives for a burst of commands is noticed (issue 20, item 1).

During a lockstep run, a second process creates a publisher on /amb/current, waits until it has matched the plant,
sends a burst of well-formed commands, waits for their delivery and destroys it: it lives a few milliseconds after
its match, far less than the 0.25 s period of amb-rig's graph poll.  amb-rig's event watch
(amb_bringup/intruders.py: DDS reports every publisher it discovers on the loop's topics) fails the run naming the
topic and, when its node's name arrived before it left, the intruder (or the publisher never matches the plant:
amb-rig, told as DDS discovered it, stopped the run first).  Each DDS participant discovers on its own, so amb-rig's
node may miss a publisher that leaves within milliseconds of matching the plant; the plant, which received the
burst, must then have rejected every command (another run token), and the verdict must say so.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from helpers import rig_in_progress, rig_json

pytestmark = pytest.mark.ros

PAPER = Path(__file__).resolve().parents[1] / "config" / "seed_paper.yaml"
BURST = 50

INTRUDER = f"""
import time, rclpy, rclpy.duration
from sensor_msgs.msg import JointState
from amb_ros.qos import lockstep_qos
rclpy.init()
node = rclpy.create_node("burst_intruder")
pub = node.create_publisher(JointState, "/amb/current", lockstep_qos())  # the plant's QoS: it matches
end = time.monotonic() + 5  # amb-rig may stop the run on discovering it, before the plant matched it
while pub.get_subscription_count() < 1 and time.monotonic() < end:
    time.sleep(0.001)
matched = pub.get_subscription_count() >= 1
t0 = time.monotonic()
msg = JointState(name=["amb1_y", "amb1_z", "amb5_y", "amb5_z"], position=[12.0] * 4)
for k in range({BURST}):
    msg.header.stamp.sec, msg.header.stamp.nanosec = 0, k * 200_000
    pub.publish(msg)
pub.wait_for_all_acked(rclpy.duration.Duration(seconds=1.0))  # delivered, then gone
node.destroy_publisher(pub)
print(f"lived {{(time.monotonic() - t0) * 1e3:.1f}} ms after its match" if matched else "never matched", flush=True)
node.destroy_node()
rclpy.shutdown()
"""


def test_a_burst_intruder_is_noticed(tmp_path, venv_bin):
    cmd = [str(venv_bin / "amb-rig"), "run", "--json", "--config", str(PAPER), "--duration", "5",
           "--no-monitor", "--log-dir", str(tmp_path / "logs")]  # fmt: skip
    with rig_in_progress(cmd, tmp_path / "rig.log") as proc:
        burst = subprocess.run([sys.executable, "-c", INTRUDER], capture_output=True, text=True, timeout=60)
        assert burst.returncode == 0, burst.stderr
        words = burst.stdout.split()
        code = proc.wait(60)
        text = proc.text()
    s = rig_json(text)
    plant = s["nodes"]["plant"]["values"]
    rejected = int(plant.get("foreign /amb/current", 0))
    joined = [e for e in s["errors"] if "joined this run" in e]
    if joined:  # the event watch saw it: the run failed, naming the topic (and the intruder when it could)
        assert code == 1 and "/amb/current by" in joined[0], s["errors"]
        assert any(w in joined[0] for w in ("burst_intruder", "a node not yet named", "1 more that left")), joined
    else:  # it left before amb-rig's node discovered it: the plant, which received it, rejected every message
        assert words[0] == "lived" and float(words[1]) < 250.0, burst.stdout
        assert rejected == BURST, plant
        assert any(f"rejected {BURST} commands with another run token" in w for w in s["verdict"]["warnings"])
