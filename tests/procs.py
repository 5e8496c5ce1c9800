"""Spawned processes for integration tests: bounded in time, always cleaned up, logs in files."""

from __future__ import annotations

import contextlib
import signal
import subprocess
import time
from pathlib import Path

from amb_ros.env import child_env

STOP_TIMEOUT_S = 10.0


class Proc:
    """A child process whose stdout+stderr go to ``log``; ``stop()`` sends SIGINT, then escalates."""

    def __init__(self, cmd: list[str], log: Path, env: dict | None = None, cwd: Path | None = None):
        self.cmd, self.log = cmd, log
        self._fh = open(log, "wb")
        self.popen = subprocess.Popen(
            cmd, env=child_env(env), cwd=cwd, stdout=self._fh, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL
        )

    def stop(self, sig: int = signal.SIGINT, timeout: float = STOP_TIMEOUT_S) -> int:
        if self.popen.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                self.popen.send_signal(sig)
            try:
                self.popen.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                self.popen.kill()
                self.popen.wait()
        self._fh.close()
        return self.popen.returncode

    def wait(self, timeout: float) -> int:
        try:
            return self.popen.wait(timeout=timeout)
        finally:
            if self.popen.poll() is None:
                self.stop()

    def text(self) -> str:
        if not self._fh.closed:
            self._fh.flush()
        return self.log.read_text(errors="replace")

    def wait_for(self, needle: str, timeout: float) -> bool:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if needle in self.text():
                return True
            if self.popen.poll() is not None:
                return needle in self.text()
            time.sleep(0.05)
        return False


@contextlib.contextmanager
def spawn(cmd: list[str], log: Path, env: dict | None = None, cwd: Path | None = None):
    """Context manager: the process is stopped (SIGINT, then SIGKILL) and reaped on exit."""
    proc = Proc(cmd, log, env, cwd)
    try:
        yield proc
    finally:
        proc.stop()
