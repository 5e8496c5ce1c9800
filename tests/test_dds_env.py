"""DDS hygiene: localhost-only discovery everywhere, and a domain id no concurrent run shares."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

from amb_ros.env import DdsEnvError, child_env, ensure_localhost_dds, hold_run_lock


def test_session_environment_is_localhost_only():
    assert os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
    assert 0 <= int(os.environ["ROS_DOMAIN_ID"]) <= 101
    assert "ROS_STATIC_PEERS" not in os.environ


def test_ensure_sets_missing_and_refuses_wider_ranges():
    env = {}
    ensure_localhost_dds(env)
    assert env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST" and env["ROS_DOMAIN_ID"].isdigit()
    for wider in ("SUBNET", "SYSTEM_DEFAULT", "OFF_BUT_TYPO"):
        with pytest.raises(DdsEnvError, match="LOCALHOST"):
            ensure_localhost_dds({"ROS_AUTOMATIC_DISCOVERY_RANGE": wider})


def test_child_env_inherits_the_session_domain():
    env = child_env({"ROS_DOMAIN_ID": "42", "ROS_STATIC_PEERS": "10.0.0.1"})
    assert env["ROS_DOMAIN_ID"] == "42" and env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
    assert "ROS_STATIC_PEERS" not in env


def test_concurrent_reservations_never_share_a_domain():
    code = (
        "import sys, time; from amb_ros.env import reserve_domain_id; print(reserve_domain_id(seed=7), "
        "flush=True); time.sleep(3)"
    )
    procs = [subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True) for _ in range(4)]
    try:
        ids = [int(p.stdout.readline()) for p in procs]  # same seed: without the lock they would all collide
    finally:
        for p in procs:
            p.kill()
            p.wait()
    assert len(set(ids)) == 4 and int(os.environ["ROS_DOMAIN_ID"]) not in ids


def test_run_lock_is_exclusive_until_every_holder_has_closed_it():
    domain = f"test-{os.getpid()}"
    first = hold_run_lock(domain)
    waited = []
    with pytest.raises(
        DdsEnvError, match=rf"ROS_DOMAIN_ID={domain} is used by another amb-rig run \(amb-rig pid {os.getpid()}"
    ):
        hold_run_lock(domain, wait_s=0.3, on_wait=waited.append)
    assert waited == [f"amb-rig pid {os.getpid()}"]  # told once, with the holder
    # a child that inherited the lock (a node of the run) keeps it after the first holder closed its copy
    child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)"], pass_fds=(first.fileno(),))
    try:
        first.close()
        with pytest.raises(DdsEnvError):
            hold_run_lock(domain)
    finally:
        child.kill()
        child.wait()
    last = hold_run_lock(domain)  # free once the last holder is gone
    Path(last.name).unlink()
    last.close()


def test_makefile_and_ci_set_localhost(repo):
    assert "export ROS_AUTOMATIC_DISCOVERY_RANGE := LOCALHOST" in (repo / "Makefile").read_text()
    assert "ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST" in (repo / ".ci" / "run").read_text()
