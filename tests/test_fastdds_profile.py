"""The rig's Fast DDS profile (src/amb_ros/amb_ros/fastdds_profile.xml): set for every process, and in effect.

Under Fast DDS's defaults a reliable writer appends a HEARTBEAT to each sample it sends, and each reliable reader
answers from its event thread (an ACKNACK, which wakes the writer in turn).  The profile turns the piggybacked
heartbeats off (the writer's 50 ms timer sends them instead).  Shown side by side: the event thread of a reader
of 2,000 samples at ~2 kHz wakes about a third as often with the profile as with Fast DDS's defaults.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from amb_ros.env import child_env, ensure_localhost_dds
from amb_ros.fastdds import LOCALHOST_PROFILE_FILE, PROFILE_FILE, PROFILE_VARS, SWITCH, rig_transports

SAMPLES = 2000

ROLE = """
import json, os, sys, time
import rclpy
from std_msgs.msg import Float64MultiArray
from amb_bag.qos import request_for_offers
from amb_ros.qos import lockstep_qos

def event_thread_wakeups():
    total = 0
    for tid in os.listdir("/proc/self/task"):
        try:
            if open(f"/proc/self/task/{tid}/comm").read().startswith("dds.ev"):
                total += sum(int(line.split()[1]) for line in open(f"/proc/self/task/{tid}/status")
                             if line.startswith("voluntary_ctxt_switches"))
        except OSError:
            pass
    return total

role, n = sys.argv[1], int(sys.argv[2])
rclpy.init()
node = rclpy.create_node("profile_" + role)
if role == "writer":  # as the plant publishes: reliable, transient local, KEEP_LAST 1000
    pub = node.create_publisher(Float64MultiArray, "/profile_test", lockstep_qos())
    deadline = time.monotonic() + 30
    while pub.get_subscription_count() < 1 and time.monotonic() < deadline:
        time.sleep(0.01)
    msg = Float64MultiArray(data=[0.0] * 4)
    for _ in range(n):
        pub.publish(msg)
        time.sleep(0.0005)
    time.sleep(1.0)  # let the reader take the last samples before this writer goes
else:  # as the recorder subscribes: reliable, KEEP_ALL, raw, drained every 10 ms
    qos = request_for_offers([{"reliability": "reliable", "durability": "transient_local"}])
    sub = node.create_subscription(Float64MultiArray, "/profile_test", lambda _: None, qos, raw=True)
    got, start, deadline = 0, None, time.monotonic() + 60
    while got < n and time.monotonic() < deadline:
        time.sleep(0.01)
        while sub.handle.take_message(Float64MultiArray, True) is not None:
            start = event_thread_wakeups() if start is None else start
            got += 1
    print(json.dumps({"got": got, "wakeups": event_thread_wakeups() - (start or 0)}), flush=True)
"""


def event_thread_wakeups_per_sample(env: dict) -> float:
    procs = [subprocess.Popen([sys.executable, "-c", ROLE, role, str(SAMPLES)], env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for role in ("reader", "writer")]  # fmt: skip
    try:
        outs = [p.communicate(timeout=90) for p in procs]
    finally:
        for p in procs:
            p.kill()
    assert all(p.returncode == 0 for p in procs), [err[-500:] for _, err in outs]
    got = json.loads(outs[0][0])
    assert got["got"] == SAMPLES
    return got["wakeups"] / SAMPLES


def test_every_process_gets_the_rig_profile_unless_switched_off_or_the_user_has_one(tmp_path):
    env = ensure_localhost_dds({})
    assert env["FASTRTPS_DEFAULT_PROFILES_FILE"] == str(LOCALHOST_PROFILE_FILE) and LOCALHOST_PROFILE_FILE.is_file()
    assert child_env({})["FASTRTPS_DEFAULT_PROFILES_FILE"] == str(LOCALHOST_PROFILE_FILE)
    # a wider discovery the user asked for gets the profile without the loopback-only transports, also when the
    # parent's localhost profile was inherited
    wide = child_env(
        {"ROS_AUTOMATIC_DISCOVERY_RANGE": "subnet", "FASTRTPS_DEFAULT_PROFILES_FILE": str(LOCALHOST_PROFILE_FILE)}
    )
    assert wide["FASTRTPS_DEFAULT_PROFILES_FILE"] == str(PROFILE_FILE) and PROFILE_FILE.is_file()
    peers = ensure_localhost_dds({"ROS_STATIC_PEERS": "10.213.77.2"})
    assert peers["FASTRTPS_DEFAULT_PROFILES_FILE"] == str(PROFILE_FILE)
    assert not any(v in ensure_localhost_dds({SWITCH: "0"}) for v in PROFILE_VARS)
    own = tmp_path / "mine.xml"
    for var in PROFILE_VARS:
        env = ensure_localhost_dds({var: str(own)})
        assert env[var] == str(own) and {v for v in PROFILE_VARS if v in env} == {var}


@pytest.mark.parametrize(
    "change, hands_over",
    [
        ({}, True),
        ({"RMW_IMPLEMENTATION": "rmw_fastrtps_cpp"}, True),
        ({"RMW_IMPLEMENTATION": "rmw_cyclonedds_cpp"}, False),  # the profile means nothing to another RMW
        ({"ROS_STATIC_PEERS": "10.213.77.2"}, False),  # unicast peers: rmw_fastrtps's own handling
        ({"ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET"}, False),
        ({"FASTRTPS_DEFAULT_PROFILES_FILE": "/tmp/mine.xml"}, False),  # a profile of the user's own
        ({"FASTDDS_DEFAULT_PROFILES_FILE": "/tmp/mine.xml"}, False),
        ({SWITCH: "0"}, False),
    ],
)
def test_rmw_leaves_the_transports_to_the_localhost_profile_only_while_rclpy_starts(monkeypatch, change, hands_over):
    base = {"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", "FASTRTPS_DEFAULT_PROFILES_FILE": str(LOCALHOST_PROFILE_FILE)}
    for var in ("RMW_IMPLEMENTATION", "ROS_STATIC_PEERS", *PROFILE_VARS):
        monkeypatch.delenv(var, raising=False)
    env = ensure_localhost_dds({**base, **change})
    for var, value in env.items():
        monkeypatch.setenv(var, value)
    before = dict(os.environ)
    with rig_transports() as did:
        during = os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"]
    assert did is hands_over
    assert during == ("SYSTEM_DEFAULT" if hands_over else before["ROS_AUTOMATIC_DISCOVERY_RANGE"])
    assert dict(os.environ) == before  # the process's environment (and its children's) as it was


def test_the_two_profiles_share_their_writer_settings():
    def writer(path):
        text = path.read_text()
        return text[text.index("<data_writer") : text.index("</data_writer>")]

    assert "disable_heartbeat_piggyback" in writer(PROFILE_FILE)
    assert writer(PROFILE_FILE) == writer(LOCALHOST_PROFILE_FILE)
    assert "<address>127.0.0.1</address>" in LOCALHOST_PROFILE_FILE.read_text()
    assert "interfaceWhiteList" not in PROFILE_FILE.read_text()


def test_the_profile_spares_the_readers_event_thread(tmp_path):
    defaults = tmp_path / "fastdds_defaults.xml"  # a profile file of the user's own that changes nothing
    defaults.write_text(
        '<?xml version="1.0" encoding="UTF-8" ?>\n<profiles xmlns="http://www.eprosima.com/XMLSchemas/'
        'fastRTPS_Profiles">\n  <data_writer profile_name="not_default"><qos/></data_writer>\n</profiles>\n'
    )
    with_profile = event_thread_wakeups_per_sample(child_env(FASTRTPS_DEFAULT_PROFILES_FILE=str(PROFILE_FILE)))
    with_defaults = event_thread_wakeups_per_sample(child_env(FASTRTPS_DEFAULT_PROFILES_FILE=str(defaults)))
    # measured here: 0.035-0.05 with the profile (its 50 ms heartbeat timer), 0.14 with Fast DDS's defaults; under a
    # loaded CI run 0.076 against 0.139
    assert with_profile < 0.1, (with_profile, with_defaults)
    assert with_defaults > 1.5 * with_profile, (with_profile, with_defaults)


def test_the_profile_file_is_installed_with_the_package():
    setup = (Path(__file__).parents[1] / "src" / "amb_ros" / "setup.py").read_text()
    assert f'"{PROFILE_FILE.name}"' in setup  # package_data: colcon and pip install it next to amb_ros/fastdds.py
