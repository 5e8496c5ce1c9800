"""No DDS packet leaves the loopback interface, its ports are bound to loopback, and discovery settings are checked.

As root, an AF_PACKET socket on every non-loopback interface sees each outgoing frame.  During a short lockstep
run of the whole suite, no outgoing frame may be RTPS (payload starting with b"RTPS"), UDP to this test's DDS
domain ports (7400 + 250 d ... + 249) or IPv4/IPv6 multicast.  A positive control first sends one UDP datagram
to a domain port through the default route and checks that the sniffer counts it.
"""

from __future__ import annotations

import os
import re
import shutil
import socket
import subprocess
import sys
import time

import pytest

from amb_ros.env import child_env
from helpers import Sniffer, interfaces, run_rig
from procs import spawn

pytestmark = pytest.mark.ros


@pytest.mark.skipif(os.geteuid() != 0, reason="AF_PACKET capture needs root")
def test_no_dds_packet_leaves_loopback(tmp_path, venv_bin):
    ifaces = interfaces()
    assert ifaces, "no non-loopback interface to watch"
    domain = int(os.environ["ROS_DOMAIN_ID"])
    sniffer = Sniffer(ifaces, domain)
    try:
        # positive control: a datagram to a domain port through the default route is seen
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
            try:
                probe.sendto(b"probe", ("192.0.2.1", sniffer.lo))  # TEST-NET-1: documentation address
                sent = True
            except OSError:
                sent = False
        time.sleep(0.5)
        if sent:
            assert any(f"UDP to DDS port {sniffer.lo}" in h for h in sniffer.hits), sniffer.hits
        sniffer.hits.clear()
        code, s, text = run_rig(tmp_path, venv_bin, ["--duration", "0.2", "--initial-displacement", "1e-4"])
        assert code == 0, text[-2000:]
        assert s["steps"] == 1000
        time.sleep(0.5)
    finally:
        sniffer.close()
    assert sniffer.hits == []


def test_garbage_discovery_settings_are_refused_with_one_line(venv_bin):
    for var, value in (("ROS_AUTOMATIC_DISCOVERY_RANGE", "SUBNETT"), ("ROS_STATIC_PEERS", "10.0.0.300")):
        env = dict(os.environ, **{var: value})
        for exe in ("amb-plant", "amb-controller", "amb-base-motion", "amb-rig"):
            cmd = [str(venv_bin / exe)] + (["run"] if exe == "amb-rig" else [])
            out = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=60)
            lines = [ln for ln in (out.stdout + out.stderr).splitlines() if ln.strip()]
            assert out.returncode == 2 and len(lines) == 1 and f"{var}={value}" in lines[0], (exe, out)
    for bad in ("everywhere", "peers:", "peers:10.0.0.1,no such host"):
        out = subprocess.run([str(venv_bin / "amb-rig"), "run", "--discovery", bad], capture_output=True, text=True,
                             timeout=60)  # fmt: skip
        lines = [ln for ln in (out.stdout + out.stderr).splitlines() if ln.strip()]
        assert out.returncode == 2 and len(lines) == 1 and "--discovery" in lines[0], (bad, out)


def test_a_wider_discovery_is_announced_on_one_line(venv_bin):
    # a bad config stops amb-rig right after the discovery check, before any DDS participant exists
    for choice, expected in (("subnet", "ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET"),
                             ("peers:10.213.77.2,rig-io.lab", "ROS_STATIC_PEERS=10.213.77.2;rig-io.lab")):  # fmt: skip
        out = subprocess.run([str(venv_bin / "amb-rig"), "run", "--discovery", choice, "--set", "no_such_key=1"],
                             capture_output=True, text=True, timeout=60)  # fmt: skip
        warnings = [ln for ln in out.stderr.splitlines() if "warning: DDS discovery reaches" in ln]
        assert len(warnings) == 1 and expected in warnings[0], out.stderr
        assert "no_such_key" in out.stderr and out.returncode != 0
    out = subprocess.run([str(venv_bin / "amb-rig"), "run", "--discovery", "localhost", "--set", "no_such_key=1"],
                         capture_output=True, text=True, timeout=60)  # fmt: skip
    assert "warning" not in out.stderr and "no_such_key" in out.stderr  # control: localhost says nothing


def udp_sockets(pids: set[int]) -> list[tuple[str, int, int]]:
    """(local address, port, pid) of the UDP sockets of ``pids`` (from ``ss -uanp``)."""
    out = subprocess.run(["ss", "-uanpH"], capture_output=True, text=True, timeout=30).stdout
    found = []
    for line in out.splitlines():
        cols = line.split()
        addr, _, port = cols[3].rpartition(":")
        for pid in re.findall(r"pid=(\d+)", line):
            if int(pid) in pids:
                found.append((addr.strip("[]"), int(port), int(pid)))
    return found


def descendants(root: int) -> set[int]:
    parents = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                parents[int(entry)] = int(open(f"/proc/{entry}/stat").read().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
    out, frontier = {root}, [root]
    while frontier:
        pid = frontier.pop()
        kids = [p for p, pp in parents.items() if pp == pid and p not in out]
        out.update(kids)
        frontier.extend(kids)
    return out


PROBE = "import rclpy, time; rclpy.init(); n = rclpy.create_node('bind_probe'); print('up', flush=True); time.sleep(30)"


@pytest.mark.skipif(shutil.which("ss") is None, reason="needs ss (iproute2)")
def test_localhost_discovery_binds_every_udp_socket_to_loopback(tmp_path, venv_bin):
    domain = int(os.environ["ROS_DOMAIN_ID"])
    lo, hi = 7400 + 250 * domain, 7400 + 250 * domain + 249
    # positive control: without the rig's profile, Fast DDS binds the domain's ports on every interface
    env = child_env(dict(os.environ, AMB_RIG_FASTDDS_PROFILE="0"))
    assert "FASTRTPS_DEFAULT_PROFILES_FILE" not in env
    probe = subprocess.Popen([sys.executable, "-c", PROBE], env=env, stdout=subprocess.PIPE, text=True)
    try:
        assert probe.stdout.readline().strip() == "up"
        time.sleep(0.5)
        control = udp_sockets({probe.pid})
    finally:
        probe.kill()
        probe.wait()
    assert any(lo <= port <= hi and addr == "0.0.0.0" for addr, port, _ in control), control
    # a lockstep run of the suite with the rig's profile (lockstep: no deadline to miss on a loaded machine):
    # sockets sampled while it runs, from the nodes' start to their exit
    log = tmp_path / "rig.log"
    cmd = [str(venv_bin / "amb-rig"), "run", "--duration", "0.2", "--no-monitor", "--log-dir", str(tmp_path / "logs")]
    seen: set[tuple[str, int, int]] = set()
    with spawn(cmd, log) as rig:
        end = time.monotonic() + 60
        while rig.popen.poll() is None and time.monotonic() < end:
            seen.update(udp_sockets(descendants(rig.popen.pid)))  # amb-rig (its collector) too
            time.sleep(0.3)
        code = rig.wait(30)
    assert code == 0, rig.text()[-2000:]
    domain_ports = [s for s in seen if lo <= s[1] <= hi]
    assert len({pid for _, _, pid in domain_ports}) >= 3  # base_motion, controller, plant listen on the domain
    assert all(addr == "127.0.0.1" for addr, _, _ in domain_ports), sorted(domain_ports)
    # nothing else either: the profile describes the whole participant and rmw_fastrtps adds no transport of its
    # own (amb_ros.fastdds.rig_transports), so no send socket sits on 0.0.0.0 or an interface address
    outside = sorted(s for s in seen if s[0] not in ("127.0.0.1", "::1"))
    assert outside == [], outside
