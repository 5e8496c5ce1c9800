"""Hardware-in-the-loop across two hosts: two network namespaces joined by a veth pair, UDP only.

Namespace A (10.213.77.1/30) runs the rig side, ``amb-rig run --only plant``; namespace B (10.213.77.2/30) the
host side, ``amb-rig run --no-plant`` (base_motion, controller, monitor); realtime with ``--discovery subnet``
(multicast on the veth), lockstep with ``--discovery peers:<the other address>`` (unicast only).
Fast DDS's shared memory is off (``FASTDDS_BUILTIN_TRANSPORTS=UDPv4``: the namespaces share /dev/shm, and the
link must be real), which the veth's packet counters confirm: every sample and every command crossed it.  Both
sides use the same ROS_DOMAIN_ID and /tmp, so the per-namespace run lock is exercised too.  Meanwhile an AF_PACKET
capture on this machine's own interfaces must see no DDS frame.  The namespaces and the veth pair are removed in a
``finally``, also when the test fails.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import time
from pathlib import Path

import pytest

from helpers import Sniffer, interfaces, rig_json
from procs import spawn

pytestmark = [
    pytest.mark.ros,
    pytest.mark.skipif(os.geteuid() != 0 or shutil.which("ip") is None, reason="network namespaces need root and ip"),
]

ADDR = {"a": "10.213.77.1", "b": "10.213.77.2"}
PAPER = str(Path(__file__).resolve().parents[1] / "config" / "seed_paper.yaml")  # the link, not the rig physics
RT = ["--mode", "realtime", "--motion", "none", "--set", "controller.rate_hz=1000", "--set", "modal_cutoff=800",
      "--config", PAPER]  # fmt: skip
# this test is about the link, not about deadlines on a shared 2-core machine: a late command is held for up to
# 1 s and the controller waits 1 s for samples before it de-levitates (defaults: 10 samples, 0.1 s)
LENIENT = ["--param", "plant:hold_samples=1000", "--param", "controller:sensor_timeout_s=1.0",
           # the plant side counts its ticks before the host side has started as steps without a command; the
           # test asserts the fraction answered over the link itself (below)
           "--max-command-loss", "1"]  # fmt: skip


def ip(*args: str) -> None:
    subprocess.run(["ip", *args], check=True, capture_output=True, timeout=30)


@pytest.fixture
def two_hosts():
    """Two network namespaces joined by a veth pair (addresses only inside them); always torn down."""
    tag = f"{os.getpid() % 100000}"
    ns = {"a": f"amb{tag}a", "b": f"amb{tag}b"}
    dev = {"a": f"ambv{tag}a", "b": f"ambv{tag}b"}
    try:
        for side in ns:
            ip("netns", "add", ns[side])
        ip("link", "add", dev["a"], "type", "veth", "peer", "name", dev["b"])
        for side in ns:
            ip("link", "set", dev[side], "netns", ns[side])
            ip("-n", ns[side], "addr", "add", f"{ADDR[side]}/30", "dev", dev[side])
            ip("-n", ns[side], "link", "set", "lo", "up")
            ip("-n", ns[side], "link", "set", dev[side], "up")
            ip("-n", ns[side], "route", "add", "224.0.0.0/4", "dev", dev[side])  # SUBNET discovery's multicast
        yield ns, dev
    finally:
        for side in ns:
            subprocess.run(["ip", "netns", "del", ns[side]], capture_output=True, timeout=30)
        subprocess.run(["ip", "link", "del", dev["a"]], capture_output=True, timeout=30)  # if never moved


def tx_packets(ns: str, dev: str) -> int:
    out = subprocess.run(["ip", "-n", ns, "-j", "-s", "link", "show", dev], capture_output=True, text=True,
                         check=True, timeout=30)  # fmt: skip
    return int(json.loads(out.stdout)[0]["stats64"]["tx"]["packets"])


def run_pair(tmp_path, venv_bin, ns, plant_args, host_args, timeout=90.0, peers=False):
    """Start the plant side in A, then the host side in B (``--discovery subnet``, or each other as static peers
    with ``peers``); return both exit codes and logs."""
    tmp_path.mkdir(parents=True, exist_ok=True)
    env = {"FASTDDS_BUILTIN_TRANSPORTS": "UDPv4"}  # no shared memory between the namespaces
    rig = str(venv_bin / "amb-rig")
    disc = {side: f"peers:{ADDR['b' if side == 'a' else 'a']}" if peers else "subnet" for side in ("a", "b")}
    cmd_a = ["ip", "netns", "exec", ns["a"], rig, "run", "--json", "--discovery", disc["a"], "--only", "plant",
             "--log-dir", str(tmp_path / "a"), *plant_args]  # fmt: skip
    cmd_b = ["ip", "netns", "exec", ns["b"], rig, "run", "--json", "--discovery", disc["b"], "--no-plant",
             "--log-dir", str(tmp_path / "b"), *host_args]  # fmt: skip
    with spawn(cmd_a, tmp_path / "a.log", env=dict(os.environ, **env)) as a:
        with spawn(cmd_b, tmp_path / "b.log", env=dict(os.environ, **env)) as b:
            code_b = b.wait(timeout)
            text_b = b.text()
        code_a = a.wait(timeout)
        text_a = a.text()
    return (code_a, text_a), (code_b, text_b)


def test_hil_across_two_network_namespaces(tmp_path, venv_bin, two_hosts):
    ns, dev = two_hosts
    sniffer = Sniffer(interfaces(), int(os.environ["ROS_DOMAIN_ID"]))
    try:
        tx0 = tx_packets(ns["a"], dev["a"]), tx_packets(ns["b"], dev["b"])
        (code_a, text_a), (code_b, text_b) = run_pair(
            # the host side without the monitor: its period and sample time over a lossy link are not settled yet
            tmp_path / "rt",
            venv_bin,
            ns,
            [*RT, *LENIENT, "--duration", "40"],
            [*RT, *LENIENT, "--duration", "5", "--no-monitor"],
        )
        tx1 = tx_packets(ns["a"], dev["a"]), tx_packets(ns["b"], dev["b"])
        assert code_b == 0, text_b[-3000:]
        assert code_a == 0, text_a[-3000:]
        plant_side, host_side = rig_json(text_a), rig_json(text_b)
        assert "warning: DDS discovery reaches every host on the local subnets" in text_a
        assert plant_side["ended_by"].startswith("the other side left")  # the host side ended the run
        ctl = host_side["nodes"]["controller"]["values"]
        plant = plant_side["nodes"]["plant"]["values"]
        # realtime: a sample that never arrived shows as a gap in the sample stamps (`skipped ticks`)
        # a gap in the controller's sample stamps is a sample the link lost or one the plant never sent (its own
        # skipped ticks, late on a loaded machine): only the first kind is the link's
        answered = int(ctl["samples answered"])
        lost = max(int(ctl["skipped ticks"]) - int(plant["skipped ticks"]), 0)
        assert answered >= 1500  # at least 2 s at 1 kHz (the controller answers from its start)
        # of the samples sent over the link, those answered: over 99 % on a quiet machine, 87-98 % when this shared
        # 2-core machine was slower (the plant side then skipped up to 24 % of its own ticks): a controller late by
        # 5-25 ms finds only the newest 5 samples in its sensor-data reader. A link that carries the loop answers
        # most samples and returns most commands; a broken one, few
        assert answered / (answered + lost) >= 0.8, (answered, lost)
        commands_back = int(plant["samples answered"])  # commands that came back and answered a sample
        assert commands_back >= 0.95 * answered, (commands_back, answered)
        # the link is real: each sample and each command is at least one UDP frame on the veth
        assert tx1[0] - tx0[0] >= commands_back and tx1[1] - tx0[1] >= commands_back
        rtt = {q: float(plant[f"round trip {q} (us)"]) for q in ("p50", "p99", "max")}
        assert 0.0 < rtt["p50"] <= rtt["p99"] <= rtt["max"]
        print(f"\nrealtime 1 kHz across the veth: {answered} samples answered, {lost} never arrived; round trip "
              f"p50 {rtt['p50']:.0f} us, p99 {rtt['p99']:.0f} us, max {rtt['max']:.0f} us; jitter (period error) "
              f"p50/p99 {ctl['period error p50 (us)']}/{ctl['period error p99 (us)']} us; the plant skipped "
              f"{plant['skipped ticks']} ticks")  # fmt: skip

        # lockstep, with unicast discovery of the other host only (LOCALHOST + ROS_STATIC_PEERS, no multicast)
        tx0 = tx_packets(ns["a"], dev["a"])
        (code_a, text_a), (code_b, text_b) = run_pair(
            tmp_path / "ls",
            venv_bin,
            ns,
            ["--duration", "0.1", "--initial-displacement", "1e-4"],
            ["--no-monitor"],
            peers=True,
        )
        assert code_a == 0, text_a[-3000:]
        assert code_b == 0, text_b[-3000:]
        plant_side, host_side = rig_json(text_a), rig_json(text_b)
        assert plant_side["steps"] == 500  # 0.1 s at 5 kHz
        # the plant's final report, or (a short run can end before the host side's amb-rig has discovered the
        # plant, whose volatile final report it then misses) its publisher gone after the controller answered it
        assert host_side["ended_by"] == "the plant finished" or host_side["ended_by"].startswith("the other side left")
        ctl = host_side["nodes"]["controller"]["values"]
        # y_0 .. y_500: the plant publishes its final sample too, and the controller answers every one, in order
        assert int(ctl["samples answered"]) == 501 and int(ctl["samples lost"]) == 0
        assert "ROS_STATIC_PEERS=10.213.77.2" in text_a
        assert tx_packets(ns["a"], dev["a"]) - tx0 >= 501  # every sample crossed the link
        time.sleep(0.5)
    finally:
        sniffer.close()
    assert sniffer.hits == []  # nothing of either run on this machine's own interfaces
