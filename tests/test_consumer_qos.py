"""A consumer beside a realtime loop (the monitor) keeps a deep history of its own (amb_ros.qos.consumer_qos).

The realtime data topics are best effort and shallow (sensor-data QoS, 5 messages), which a loop node wants: only the
latest sample matters to it.  A monitor that is busy refitting for longer than 5 messages last (62 ms of the
plant's state blocks at 2 kHz) lost most of each run's samples with that profile (7,000-7,900 of 10,000 in a
5 s run of the real rig at 2 kHz).  Its reader-side history of ``qos_depth`` holds them while it is busy: here a
reader that takes nothing while 300 best-effort messages go out then finds every one of them.
"""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from amb_ros.env import child_env

pytestmark = pytest.mark.ros

SCRIPT = r"""
import json, sys, time
import rclpy
from std_msgs.msg import String
from amb_ros.qos import consumer_qos, data_qos
from amb_ros.fastdds import init_rclpy

N = 300
init_rclpy()
node = rclpy.create_node("consumer_qos_test")
pub = node.create_publisher(String, "/consumer_qos_test", data_qos("realtime"))
subs = {kind: node.create_subscription(String, "/consumer_qos_test", lambda m: None, qos, raw=True)
        for kind, qos in (("consumer", consumer_qos("realtime", 1000)), ("data", data_qos("realtime")))}
end = time.monotonic() + 10
while pub.get_subscription_count() < 2 and time.monotonic() < end:
    time.sleep(0.01)
for i in range(N):  # a busy reader: nothing is taken meanwhile
    pub.publish(String(data=str(i)))
    time.sleep(0.001)
time.sleep(0.5)
got = {}
for kind, sub in subs.items():
    taken = []
    while (out := sub.handle.take_message(sub.msg_type, True)) is not None:
        taken.append(out[0])
    got[kind] = len(taken)
print(json.dumps({"matched": pub.get_subscription_count(), **got}))
"""


def test_a_busy_consumer_finds_every_best_effort_sample_in_its_own_history():
    out = subprocess.run([sys.executable, "-c", SCRIPT], env=child_env(), capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr[-2000:]
    got = json.loads(out.stdout.strip().splitlines()[-1])
    assert got["matched"] == 2, got
    assert got["consumer"] == 300, got  # the monitor's profile: every sample held
    assert got["data"] <= 5, got  # the loop's profile keeps the latest few only
