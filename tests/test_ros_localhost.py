"""No DDS packet leaves the loopback interface, and a node refuses a wider discovery range.

As root, an AF_PACKET socket on every non-loopback interface sees each outgoing frame.  During a short lockstep
run of the whole suite, no outgoing frame may be RTPS (payload starting with b"RTPS"), UDP to this test's DDS
domain ports (7400 + 250 d ... + 249) or IPv4/IPv6 multicast.  A positive control first sends one UDP datagram
to a domain port through the default route and checks that the sniffer counts it.
"""

from __future__ import annotations

import os
import socket
import struct
import subprocess
import threading
import time

import pytest

from helpers import run_rig

pytestmark = pytest.mark.ros

ETH_P_ALL = 0x0003
PACKET_OUTGOING = 4


def interfaces() -> list[str]:
    return [name for name in os.listdir("/sys/class/net") if name != "lo"
            and open(f"/sys/class/net/{name}/operstate").read().strip() in ("up", "unknown")]  # fmt: skip


class Sniffer:
    """Counts outgoing frames on the given interfaces that look like DDS traffic."""

    def __init__(self, ifaces: list[str], domain: int):
        self.lo, self.hi = 7400 + 250 * domain, 7400 + 250 * domain + 249
        self.hits: list[str] = []
        self.frames = 0
        self._stop = threading.Event()
        self.socks = []
        for name in ifaces:
            s = socket.socket(socket.AF_PACKET, socket.SOCK_RAW, socket.htons(ETH_P_ALL))
            s.bind((name, 0))
            s.settimeout(0.05)
            self.socks.append(s)
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self):
        while not self._stop.is_set():
            for s in self.socks:
                try:
                    frame, addr = s.recvfrom(65535)
                except TimeoutError:
                    continue
                if addr[2] == PACKET_OUTGOING:
                    self.frames += 1
                    why = self.classify(frame)
                    if why:
                        self.hits.append(f"{addr[0]}: {why}")

    def classify(self, frame: bytes) -> str | None:
        ethertype = struct.unpack("!H", frame[12:14])[0]
        if ethertype == 0x0800:
            ihl = (frame[14] & 0x0F) * 4
            proto, dst = frame[23], frame[30:34]
            if dst[0] >= 224 and dst[0] <= 239:
                return f"IPv4 multicast to {socket.inet_ntoa(dst)}"
            if proto != 17:
                return None
            udp = 14 + ihl
        elif ethertype == 0x86DD:
            if frame[38] == 0xFF:
                return "IPv6 multicast"
            if frame[20] != 17:
                return None
            udp = 14 + 40
        else:
            return None
        dport = struct.unpack("!H", frame[udp + 2 : udp + 4])[0]
        payload = frame[udp + 8 : udp + 12]
        if payload == b"RTPS":
            return f"RTPS to port {dport}"
        if self.lo <= dport <= self.hi:
            return f"UDP to DDS port {dport}"
        return None

    def close(self):
        self._stop.set()
        self.thread.join(2)
        for s in self.socks:
            s.close()


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


def test_wider_discovery_range_is_refused(venv_bin):
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="SUBNET")
    for exe in ("amb-plant", "amb-controller", "amb-base-motion"):
        out = subprocess.run([str(venv_bin / exe)], env=env, capture_output=True, text=True, timeout=60)
        assert out.returncode == 2, out
        lines = [ln for ln in (out.stdout + out.stderr).splitlines() if ln.strip()]
        assert len(lines) == 1 and "ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET" in lines[0] and "LOCALHOST" in lines[0]
    out = subprocess.run([str(venv_bin / "amb-rig"), "run"], env=env, capture_output=True, text=True, timeout=60)
    assert out.returncode != 0 and "ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET" in out.stderr
