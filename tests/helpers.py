"""Helpers shared by several test files (import them from here, not from another test file).

* DDS: :class:`DdsRecorder` records topics in the test process; :func:`run_rig` runs ``amb-rig run --json`` and
  :func:`rig_json` reads its summary; :func:`rig_in_progress` yields a run once its loop is seen running.
* Monitor: :func:`model_rho`, the sampled-data model's max|mu| of a pitch run of the seed rotor.
* Estimator: :func:`synthetic` builds period-stacked snapshots with known multipliers ``MU``; :func:`matched`
  measures how far identified multipliers are from expected ones.

The physics tests have their own module, tests/physics_helpers.py.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import socket
import struct
import threading
import time

import numpy as np

from amb_bringup.supervisor import alive
from amb_dynamics import BaseMotion, SampledLoop, build_structure, load_config, sampled_floquet
from amb_dynamics.config import paper_config_path
from amb_dynamics.estimator.mapfit import forcing_regressors
from amb_ros.fastdds import init_rclpy
from procs import spawn


# ---- DDS and amb-rig (moved from test_rig_lockstep.py) ---------------------------------------------------------
class DdsRecorder:
    """Records raw messages of some topics in this process (own rclpy context, spun in a thread).

    A topic's subscription is created once a publisher of it is known here, as amb-bag record does.  The reader
    then matches the writer at once, and the writer's reader count (the rig's start gates) tells that the reader
    gets its first sample.  Subscribed before the writer exists, the reader may match it only after the writer
    has matched the reader and sent: a volatile reader drops that sample (seen: step 0's current, in CI).
    """

    def __init__(self, topics: dict, qos=None, name: str = "test_recorder"):
        import rclpy
        from rclpy.executors import SingleThreadedExecutor

        from amb_ros.qos import diagnostics_qos, lockstep_qos

        self.ctx = rclpy.Context()
        init_rclpy(context=self.ctx)
        self.node = rclpy.create_node(name, context=self.ctx)
        self.messages: dict[str, list] = {t: [] for t in topics}
        qos = qos if qos is not None else lockstep_qos(100000)
        self._pending = {t: (ty, diagnostics_qos() if t == "/diagnostics" else qos) for t, ty in topics.items()}
        self.executor = SingleThreadedExecutor(context=self.ctx)
        self.executor.add_node(self.node)
        self._stop = threading.Event()
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()

    def _subscribe_published(self):
        for topic in [t for t in self._pending if self.node.count_publishers(t) > 0]:
            msg_type, qos = self._pending.pop(topic)
            self.node.create_subscription(msg_type, topic, self.messages[topic].append, qos)

    def _spin(self):
        while not self._stop.is_set():
            if self._pending:
                self._subscribe_published()
            self.executor.spin_once(timeout_sec=0.005 if self._pending else 0.05)

    def close(self):
        self._stop.set()
        self.thread.join(5)
        self.node.destroy_node()
        self.ctx.try_shutdown()


# a shallow, wide notch over the real rig's bending modes at 690-940 Hz on AMB1's axes (docs/commissioning.md)
AMB1_NOTCH = "controller.filters=[{kind: notch, frequency_hz: 700, bandwidth_hz: 400, depth: 0.5, axes: [0, 1]}]"


TS_NS = 200_000  # the seed configs' 5 kHz loop (ns)


def stamp(msg) -> int:
    """A message's header stamp in ns."""
    return msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec


def user_pid_setting(gains, continuous: bool, Ts: float = TS_NS / 1e9) -> str:
    """A ``controller.state_space=...`` override equal to the PID of ``gains`` (continuous, or discrete at Ts)."""
    from amb_dynamics.control_law import discrete_pid_state_space, pid_state_space

    ss = pid_state_space(gains, 1) if continuous else discrete_pid_state_space(gains, Ts, 0, 1)
    rows = lambda M: "[" + ", ".join("[" + ", ".join(repr(float(v)) for v in r) + "]" for r in M) + "]"  # noqa: E731
    dt = "null" if continuous else repr(Ts)
    return (f"controller.state_space={{A: {rows(ss.A)}, B: {rows(ss.B)}, C: {rows(ss.C)}, D: {rows(ss.D)}, "
            f"sample_time: {dt}}}")  # fmt: skip


def rig_json(text: str) -> dict:
    return json.loads(text[text.index("{") : text.rindex("}") + 1])


@contextlib.contextmanager
def rig_in_progress(cmd: list[str], log, samples: int = 500, realtime: bool = False):
    """Start ``cmd`` (an amb-rig run) and yield its process once ``samples`` displacement samples were seen over
    DDS (the loop is running); the process is stopped and reaped on exit."""
    from sensor_msgs.msg import JointState

    from amb_ros.qos import realtime_qos

    rec = DdsRecorder({"/amb/displacement": JointState}, qos=realtime_qos() if realtime else None)
    try:
        with spawn(cmd, log) as proc:
            end = time.monotonic() + 90
            while len(rec.messages["/amb/displacement"]) < samples and time.monotonic() < end:
                time.sleep(0.05)
            assert len(rec.messages["/amb/displacement"]) >= samples, proc.text()
            yield proc
    finally:
        rec.close()


def run_rig(tmp_path, venv_bin, args, timeout=180.0):
    """amb-rig run --json with ``args``; returns (exit code, summary dict, log text)."""
    tmp_path.mkdir(parents=True, exist_ok=True)
    log = tmp_path / "rig.log"
    cmd = [str(venv_bin / "amb-rig"), "run", "--json", "--log-dir", str(tmp_path / "logs"), *args]
    with spawn(cmd, log) as proc:
        code = proc.wait(timeout)
        text = proc.text()
    return code, rig_json(text), text


# ---- the monitor's truth: the sampled-data model --------------------------------------------------------------
def model_rho(amplitude: float, T: float) -> float:
    """max|mu| of the sampled-data model of a pitch run of the paper rotor without current limit.

    The digital loop's monodromy over T = N Ts (``sampled_floquet``), the truth the monitor's estimate must meet.
    """
    cfg = load_config(paper_config_path(), ["controller.current_limit=1e9"])  # the rig tests run the paper loop
    motion = BaseMotion.single("pitch", amplitude, np.pi / T)
    return sampled_floquet(SampledLoop(build_structure(cfg), cfg, forcing=False), motion, T).max_abs


# ---- the estimator on synthetic data (moved from test_estimate_core.py) ----------------------------------------
MU = np.array([1.03 * np.exp(0.7j), 1.03 * np.exp(-0.7j), 0.9 * np.exp(2.1j), 0.9 * np.exp(-2.1j), 0.5, -0.3])


def synthetic(mu, cols, m=60, forcing="alternating", seed=0, noise=0.0):
    """Columns z_0..z_{cols-1} of z_{j+1} = A z_j + d_j observed through a random (m x len(mu)) map."""
    rng = np.random.default_rng(seed)
    n = len(mu)
    V = rng.standard_normal((n, n)) + 0j
    # complex-conjugate pairs get conjugate eigenvectors so that A is real
    k = 0
    while k < n:
        if abs(mu[k].imag) > 0:
            v = rng.standard_normal(n) + 1j * rng.standard_normal(n)
            V[:, k], V[:, k + 1] = v, v.conj()
            k += 2
        else:
            k += 1
    A = np.real(V @ np.diag(mu) @ np.linalg.inv(V))
    O = rng.standard_normal((m, n))
    E = forcing_regressors(forcing, cols)
    D = rng.standard_normal((n, E.shape[0]))
    x = rng.standard_normal(n)
    Z = np.empty((m, cols))
    for j in range(cols):
        Z[:, j] = O @ x
        x = A @ x + D @ E[:, j]
    return Z + noise * rng.standard_normal(Z.shape)


def matched(got, expected):
    return max(np.min(np.abs(got - z)) for z in expected)


def started_pids(text: str) -> dict[str, int]:
    return {name: int(pid) for name, pid in re.findall(r"started (\w+) \(pid (\d+)\)", text)}


def wait_gone(pids, timeout=10.0) -> list[int]:
    end = time.monotonic() + timeout
    while time.monotonic() < end and any(alive(p) for p in pids):
        time.sleep(0.05)
    return [p for p in pids if alive(p)]


# ---- packet capture on this machine's interfaces (moved from test_ros_localhost.py) ------------------------------
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


# ---- the command-line entry points, called in-process (bad-input and exit-code tests) ----------------------
def cli_dyn(argv):
    from amb_dynamics import cli

    return cli.main(argv)


def cli_bag(argv):
    from amb_bag import cli

    cli.main(argv)


def cli_monitor(argv):
    from stability_monitor import cli

    cli.main(argv)


def cli_rig(argv):
    from amb_bringup import rig

    rig.main(argv)


@contextlib.contextmanager
def ros_node(name: str):
    """A test's own rclpy node in its own context, with a single-threaded executor: yields (node, executor)."""
    import rclpy

    ctx = rclpy.Context()
    init_rclpy(context=ctx)
    node = rclpy.create_node(name, context=ctx)
    executor = rclpy.executors.SingleThreadedExecutor(context=ctx)
    executor.add_node(node)
    try:
        yield node, executor
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.shutdown(context=ctx)


def worker_processes(proc) -> list:
    """The multiprocessing (spawn) worker processes under ``proc`` (psutil.Process objects)."""
    import psutil

    return [c for c in psutil.Process(proc.pid).children(recursive=True) if "spawn_main" in " ".join(c.cmdline())]


def stop_and_check(proc, workers: list, signum: int, group: bool) -> float:
    """Send ``signum`` to ``proc`` (``group``: to its whole process group, as a terminal's Ctrl-C does), check that
    it exits with 128 + signum saying so in one stderr line and leaves no worker alive; return the seconds it
    took to exit."""
    import psutil

    t0 = time.monotonic()
    if group:
        os.killpg(proc.pid, signum)
    else:
        proc.send_signal(signum)
    proc.wait(10)
    elapsed = time.monotonic() - t0
    assert proc.returncode == 128 + signum
    assert f"stopped by signal {int(signum)}" in proc.stderr.read().decode()
    time.sleep(0.5)
    assert [w.pid for w in workers if w.is_running() and w.status() != psutil.STATUS_ZOMBIE] == []
    return elapsed
