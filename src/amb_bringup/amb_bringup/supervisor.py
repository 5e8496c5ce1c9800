"""Child processes of a run: start each node as its own process, watch them, stop them cleanly.

Stopping is SIGINT (the nodes publish their final diagnostics and shut DDS down cleanly), then SIGTERM, then
SIGKILL, each after a bounded wait.  Every child is in its own session (a terminal's Ctrl-C reaches only amb-rig,
which then stops the children in order) and has PR_SET_PDEATHSIG = SIGTERM, so that even if amb-rig itself is
killed with SIGKILL no node is left behind.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import signal
import subprocess
import time
from dataclasses import dataclass, field
from pathlib import Path

PR_SET_PDEATHSIG = 1
# A node stopped with SIGINT may wait at exit up to amb_ros.node_base.ACK_TIMEOUT_S (5 s: slow readers take its
# last samples) and then up to the final report's 4 s (Diagnostics.publish_final) before rclpy shuts down; the
# supervisor waits for that budget and a margin before it escalates (8 s was too short on a loaded machine:
# a controller beside a lagging recorder was SIGTERMed).  tests/test_runtime_teardown.py keeps them in step.
NODE_EXIT_BUDGET_S = 5.0 + 4.0
SIGINT_WAIT_S = NODE_EXIT_BUDGET_S + 5.0
SIGTERM_WAIT_S = 3.0


@dataclass
class ProcessSpec:
    """One process of a run.

    name : short name used in messages and as the log file name
    cmd : argv
    node : the node's name in /diagnostics (None for a process that is not a rig node)
    ends_run : the run is over when this process exits by itself (the plant); others are stopped by amb-rig
    required : the run fails if this process exits before amb-rig stops it
    """

    name: str
    cmd: list[str]
    node: str | None = None
    ends_run: bool = False
    required: bool = True
    env: dict[str, str] = field(default_factory=dict)
    stop_tier: int = 0  # stopped after every process of a lower tier has exited
    verdict_only: bool = False  # its ERROR diagnostic is a finding (the monitor's UNSTABLE), not a failed run


def _pdeathsig() -> None:  # runs in the child between fork and exec
    with contextlib.suppress(Exception):
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGTERM)


def describe_exit(code: int | None) -> str:
    if code is None:
        return "running"
    if code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exit code {code}"


class Child:
    def __init__(self, spec: ProcessSpec, log_dir: Path, env: dict, pass_fds: tuple[int, ...] = ()):
        self.spec = spec
        self.log = log_dir / f"{spec.name}.log"
        self._fh = open(self.log, "wb")
        self.started = time.monotonic()
        self.popen = subprocess.Popen(
            spec.cmd,
            env={**env, **spec.env},
            stdout=self._fh,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
            start_new_session=True,
            preexec_fn=_pdeathsig,
            pass_fds=pass_fds,
        )
        self.stopped_by_us = False
        self.exited_at: float | None = None

    @property
    def pid(self) -> int:
        return self.popen.pid

    def poll(self) -> int | None:
        code = self.popen.poll()
        if code is not None and self.exited_at is None:
            self.exited_at = time.monotonic()
        return code

    def signal(self, sig: int) -> None:
        if self.popen.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                self.popen.send_signal(sig)

    def last_line(self) -> str:
        """Last non-empty line of the log (the one-line reason of a node that failed)."""
        if not self._fh.closed:
            self._fh.flush()
        try:
            lines = [ln for ln in self.log.read_text(errors="replace").splitlines() if ln.strip()]
        except OSError:
            return ""
        return lines[-1].strip() if lines else ""

    def close(self) -> None:
        self._fh.close()


class Supervisor:
    """Starts the specs in order and stops them in reverse order."""

    def __init__(self, log_dir: Path, env: dict, pass_fds: tuple[int, ...] = ()):
        """``pass_fds``: descriptors every child keeps open (the run's domain lock)."""
        self.log_dir, self.env, self.pass_fds = log_dir, env, pass_fds
        self.children: list[Child] = []

    def start(self, spec: ProcessSpec) -> Child:
        child = Child(spec, self.log_dir, self.env, self.pass_fds)
        self.children.append(child)
        return child

    def find(self, name: str) -> Child | None:
        return next((c for c in self.children if c.spec.name == name), None)

    def died_early(self) -> list[Child]:
        """Required children that exited although amb-rig did not stop them: those that do not end the run, and
        the one that does (the plant) when a signal killed it (it never ends that way by itself)."""
        out = []
        for c in self.children:
            code = c.poll()
            if c.spec.required and code is not None and not c.stopped_by_us and (not c.spec.ends_run or code < 0):
                out.append(c)
        return out

    def stop_all(self) -> None:
        """Tier by tier (by ``stop_tier``): SIGINT everyone still running, then escalate; reap all."""
        for tier in sorted({c.spec.stop_tier for c in self.children}):
            self._stop([c for c in self.children if c.spec.stop_tier == tier])
        for c in self.children:
            with contextlib.suppress(subprocess.TimeoutExpired):
                c.popen.wait(timeout=1.0)
            c.poll()
            c.close()

    @staticmethod
    def _stop(children: list[Child]) -> None:
        live = [c for c in children if c.poll() is None]
        for c in live:
            c.stopped_by_us = True
        for sig, wait_s in ((signal.SIGINT, SIGINT_WAIT_S), (signal.SIGTERM, SIGTERM_WAIT_S), (signal.SIGKILL, 5.0)):
            live = [c for c in live if c.poll() is None]
            if not live:
                break
            for c in live:
                c.signal(sig)
            end = time.monotonic() + wait_s
            while time.monotonic() < end and any(c.poll() is None for c in live):
                time.sleep(0.02)

    def pids(self) -> list[int]:
        return [c.pid for c in self.children]


def alive(pid: int) -> bool:
    """True if ``pid`` exists and is not a zombie."""
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().rsplit(")", 1)[1].split()[0] != "Z"
    except (FileNotFoundError, IndexError):
        return False
    except OSError:
        return os.path.exists(f"/proc/{pid}")
