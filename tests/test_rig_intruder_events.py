"""An intruder on /amb/current that the plant matched only briefly is still found: the plant counts the publishers
its command subscription has matched from DDS match status (amb_ros/matches.py: the count is cumulative, so it
does not depend on anyone looking at the graph while the intruder exists), and amb-rig fails the run naming the
topic.  Before, the graph watch (a 0.25 s poll) missed a publisher that lived under a second in 2 of 4 runs.

The intruder publishes a burst of BURST well-formed 12 A commands within half a second (without the run token: the
plant rejects each as foreign), waits until every matched reader has acknowledged them, which proves that the plant
matched it, and leaves at once: under a second in all, as in the case that once went unnoticed.
"""

from __future__ import annotations

import time

import numpy as np
import pytest

from helpers import DdsRecorder, rig_json
from procs import spawn

BURST = 400

pytestmark = pytest.mark.ros


def wait_running(rec, proc, samples: int = 500) -> None:
    """Until ``rec`` (a DdsRecorder of /amb/displacement) has seen ``samples`` of the rig's loop."""
    end = time.monotonic() + 90
    while len(rec.messages["/amb/displacement"]) < samples and time.monotonic() < end:
        time.sleep(0.05)
    assert len(rec.messages["/amb/displacement"]) >= samples, proc.text()


def matched_publisher(node, msg_type, topic: str):
    """A publisher of ``topic`` on ``node`` (lockstep QoS), once it has matched a reader (30 s at most)."""
    from amb_ros.qos import lockstep_qos

    pub = node.create_publisher(msg_type, topic, lockstep_qos())
    deadline = time.monotonic() + 30.0
    while pub.get_subscription_count() < 1 and time.monotonic() < deadline:
        time.sleep(0.002)
    return pub


def brief_intruder(node, topic: str) -> tuple[int, bool, float]:
    """On ``node`` (one that has discovered the rig), a publisher of ``topic`` that sends BURST commands, waits
    until every matched reader has acknowledged them, and leaves: (readers matched, acknowledged, seconds it
    existed after its first match)."""
    from rclpy.duration import Duration
    from sensor_msgs.msg import JointState

    pub = matched_publisher(node, JointState, topic)
    matched, t0 = pub.get_subscription_count(), time.monotonic()
    for _ in range(BURST):
        pub.publish(JointState(name=["amb1_y", "amb1_z", "amb5_y", "amb5_z"], effort=[12.0] * 4))
        time.sleep(0.001)
    acked = pub.wait_for_all_acked(Duration(seconds=10.0))
    node.destroy_publisher(pub)
    return matched, acked, time.monotonic() - t0


def test_a_briefly_matched_publisher_is_counted_and_fails_the_run(tmp_path, venv_bin, seed_config_path):
    from sensor_msgs.msg import JointState

    rig = [str(venv_bin / "amb-rig"), "run", "--duration", "30", "--no-monitor", "--json", "--log-dir",
           str(tmp_path / "logs"), "--config", str(seed_config_path)]  # fmt: skip
    # this process's node sees the loop running first (a participant that joins a running rig late was not
    # discovered within 60 s in about half of the trials here); the intruder's publisher then needs no new
    # participant, only the match of one more endpoint
    rec = DdsRecorder({"/amb/displacement": JointState})
    try:
        with spawn(rig, tmp_path / "rig.log") as proc:
            wait_running(rec, proc)
            matched, acked, lived = brief_intruder(rec.node, "/amb/current")
            code = proc.wait(120)
            text = proc.text()
    finally:
        rec.close()
    assert matched >= 1 and acked
    print(f"\nthe intruder existed {1e3 * lived:.0f} ms after its first match")  # about 0.5-0.7 s here
    s = rig_json(text)
    assert code == 1, text[-3000:]
    plant = s["nodes"]["plant"]["values"]
    assert plant["publishers matched /amb/current"] == "2" and plant["foreign publishers /amb/current"] == "1", plant
    # every command of the burst that reached the plant was rejected (no run token) and counted, none applied; the
    # run may be stopped before the burst ends (amb-rig saw the intruder), and then the rest never arrives
    foreign = int(plant["foreign /amb/current"])
    assert 1 <= foreign <= BURST and plant["rejected /amb/current"] == str(foreign), str(plant)
    assert plant["duplicate commands"] == "0"  # no second command for any step reached the loop
    errors = " ".join(s["errors"])
    assert "/amb/current by" in errors and "joined this run" in errors, s["errors"]
    assert plant["publishers seen /amb/current"] == "/test_recorder", plant  # named from the graph at its match
    assert "/test_recorder" in errors, s["errors"]
    assert int(plant["steps"]) < 30 * s["rate_hz"]  # the run was stopped, not finished


def test_a_future_stamp_and_a_flood_with_the_run_token_leave_the_loop_unharmed(tmp_path, venv_bin, seed_config_path):
    """Over DDS, during a lockstep run: a publisher that knows the run token (a misconfigured bridge) sends one
    /amb/displacement sample stamped t = 1000 s, then a flood of 4,000 samples with random stamps as fast as rclpy
    publishes them (the rate is printed: 4,000-13,000/s on this machine).
    Before: the future stamp wedged the controller (it counted ~5 million samples lost and rejected every real
    sample).  Now the controller rejects each as out of its window, answers every real sample (none lost), and
    amb-rig stops the run naming the intruder."""
    from rclpy.duration import Duration
    from sensor_msgs.msg import JointState

    from amb_controller.node import SAMPLE_WINDOW

    token = "floodtest1"
    rig = [str(venv_bin / "amb-rig"), "run", "--duration", "30", "--no-monitor", "--json", "--run-token", token,
           "--log-dir", str(tmp_path / "logs"), "--config", str(seed_config_path)]  # fmt: skip
    rec = DdsRecorder({"/amb/displacement": JointState})
    rng = np.random.default_rng(7)
    try:
        with spawn(rig, tmp_path / "rig.log") as proc:
            wait_running(rec, proc)
            ts_ns = round(1e9 / 5000)
            pub = matched_publisher(rec.node, JointState, "/amb/displacement")
            msg = JointState(name=["amb1_y", "amb1_z", "amb5_y", "amb5_z"], position=[1e-3] * 4)
            msg.header.frame_id = token
            msg.header.stamp.sec = 1000  # t = 1000 s
            pub.publish(msg)
            sent, t0 = 1, time.monotonic()
            # far beyond any window of this stream: a 30 s run at 5 kHz ends before step 150,000 (stamps drawn from
            # 10 * SAMPLE_WINDOW up landed within the 64 steps ahead of the stream in ~3 % of runs: taken as real)
            for k in rng.integers(max(10 * SAMPLE_WINDOW, 10**6), 10**7, size=4000):
                msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(int(k) * ts_ns, 10**9)
                pub.publish(msg)
                sent += 1
            flood_s = time.monotonic() - t0
            pub.wait_for_all_acked(Duration(seconds=10.0))
            rec.node.destroy_publisher(pub)
            code = proc.wait(120)
            text = proc.text()
    finally:
        rec.close()
    print(f"\n{sent} samples in {flood_s:.2f} s ({sent / flood_s:,.0f}/s)")
    s = rig_json(text)
    assert code == 1, text[-3000:]
    ctl, plant = s["nodes"]["controller"]["values"], s["nodes"]["plant"]["values"]
    assert ctl["samples lost"] == "0", ctl
    # each one that reached it rejected as out of its window, none answered (amb-rig may stop the run on the
    # intruder's appearance before the controller has taken any: then there are none)
    rejected = int(ctl.get("rejected /amb/displacement", 0))  # written once non-zero
    assert rejected == int(ctl["samples out of window"]) <= sent, ctl
    # every real sample was answered: the plant stepped on the controller's answers until amb-rig stopped it
    assert int(plant["steps"]) >= 500 and int(ctl["samples answered"]) >= int(plant["steps"]), (ctl, plant)
    assert int(plant["steps"]) < 30 * s["rate_hz"]  # stopped, not finished
    errors = " ".join(s["errors"])
    assert "/amb/displacement by" in errors and "/test_recorder" in errors, s["errors"]
