"""DDS hygiene: localhost-only discovery everywhere, and a domain id no concurrent run shares."""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from amb_ros.env import DdsEnvError, child_env, ensure_localhost_dds, force_localhost_dds, hold_run_lock


def test_session_environment_is_localhost_only():
    assert os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
    assert 0 <= int(os.environ["ROS_DOMAIN_ID"]) <= 101
    assert "ROS_STATIC_PEERS" not in os.environ


def test_ensure_sets_missing_keeps_a_valid_wider_choice_and_refuses_garbage():
    env = {}
    ensure_localhost_dds(env)
    assert env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST" and env["ROS_DOMAIN_ID"].isdigit()
    for wider, kept in (("SUBNET", "SUBNET"), ("subnet", "SUBNET"), ("System_Default", "SYSTEM_DEFAULT")):
        assert ensure_localhost_dds({"ROS_AUTOMATIC_DISCOVERY_RANGE": wider})["ROS_AUTOMATIC_DISCOVERY_RANGE"] == kept
    for garbage in ("OFF_BUT_TYPO", "LOCAL", "OFF", "1"):
        with pytest.raises(DdsEnvError, match=f"ROS_AUTOMATIC_DISCOVERY_RANGE={garbage}"):
            ensure_localhost_dds({"ROS_AUTOMATIC_DISCOVERY_RANGE": garbage})
    for garbage in ("10.0.0.256", "host name", "http://x", "-bad-.lan"):
        with pytest.raises(DdsEnvError, match="ROS_STATIC_PEERS"):
            ensure_localhost_dds({"ROS_STATIC_PEERS": f"10.0.0.1;{garbage}"})


def test_child_env_inherits_the_session_domain_and_the_users_peers():
    env = child_env({"ROS_DOMAIN_ID": "42", "ROS_STATIC_PEERS": " 10.0.0.1;rig-io.lab ;;fe80::1"})
    assert env["ROS_DOMAIN_ID"] == "42" and env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
    assert env["ROS_STATIC_PEERS"] == "10.0.0.1;rig-io.lab;fe80::1"
    forced = force_localhost_dds({"ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET", "ROS_STATIC_PEERS": "10.0.0.1"})
    assert forced["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST" and "ROS_STATIC_PEERS" not in forced


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
    assert "unexport ROS_STATIC_PEERS" in (repo / "Makefile").read_text()
    assert "ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST" in (repo / ".ci" / "run").read_text()
    assert "unset ROS_STATIC_PEERS" in (repo / ".ci" / "run").read_text()


def test_run_lock_is_per_network_namespace_and_per_side():
    domain = f"test-sides-{os.getpid()}"
    full = [hold_run_lock(domain, side=side) for side in ("plant", "host")]  # a full rig holds both sides
    try:
        for side in ("plant", "host"):
            with pytest.raises(DdsEnvError, match=f"{side} side"):
                hold_run_lock(domain, side=side)
    finally:
        for fh in full:
            fh.close()
    plant = hold_run_lock(domain, side="plant")
    host = hold_run_lock(domain, side="host")  # the two sides of one split run coexist
    try:
        ns = os.stat("/proc/self/ns/net").st_ino
        assert Path(plant.name).name == f"amb-rig-run-domain-{domain}-net{ns}-plant.lock"
        if os.geteuid() == 0 and shutil.which("unshare"):
            # the same side of the same domain in another network namespace (sharing /tmp) is not refused
            code = f"from amb_ros.env import hold_run_lock; hold_run_lock({domain!r}, side='plant'); print('held')"
            out = subprocess.run(["unshare", "--net", sys.executable, "-c", code], capture_output=True, text=True,
                                 timeout=60)  # fmt: skip
            assert out.returncode == 0 and out.stdout.strip() == "held", out.stderr[-500:]
            same_ns = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
            assert same_ns.returncode != 0 and "plant side" in same_ns.stderr  # control: refused in this one
    finally:
        for fh in (plant, host):
            Path(fh.name).unlink()
            fh.close()
