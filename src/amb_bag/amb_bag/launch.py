"""Start and stop a recorder process from Python (for ``amb-rig run --bag`` and benchmarks).

    rec = RecorderProcess("bags/run1", topics=None, log_path="out/record.log")   # all topics
    rec.wait_subscribed(["/clock", "/amb/displacement"], timeout=10)           # before the run starts
    ... run ...
    rc = rec.stop()                 # SIGINT: drains, writes the last chunk and metadata.yaml
    rows = rec.loss()               # per-topic received / published / lost from metadata.yaml

The command is ``python -m amb_bag.cli record -o DIR [--topics ...] [options]`` (the same as ``amb-bag
record``); the recorder prints ``amb-bag record: subscribed <topic> [<type>]`` for each topic it records.
Start it before the publishers, and stop it after their last /diagnostics report, so that the loss table
compares complete counts.
"""

from __future__ import annotations

import contextlib
import signal
import subprocess
import sys
import time
from pathlib import Path

from .errors import BagError
from .loss import CUSTOM_KEY
from .metadata import custom_json, load_metadata

STOP_TIMEOUT_S = 30.0


def recorder_command(bag_dir, topics=None, extra_args=()) -> list[str]:
    """argv of a recorder writing ``bag_dir`` (``topics`` None = all topics)."""
    cmd = [sys.executable, "-m", "amb_bag.cli", "record", "-o", str(bag_dir)]
    if topics:
        cmd += ["--topics", *topics]
    return cmd + [str(a) for a in extra_args]


class RecorderProcess:
    """A recorder child process with its output in ``log_path`` (default: ``<bag_dir>.record.log``)."""

    def __init__(self, bag_dir, topics=None, extra_args=(), env=None, log_path=None):
        self.bag_dir = Path(bag_dir)
        self.log_path = Path(log_path) if log_path else self.bag_dir.with_name(self.bag_dir.name + ".record.log")
        self._log = open(self.log_path, "wb")
        self.popen = subprocess.Popen(
            recorder_command(bag_dir, topics, extra_args), env=env, stdout=self._log, stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
        )  # fmt: skip

    def text(self) -> str:
        return self.log_path.read_text(errors="replace")

    def subscribed(self) -> set[str]:
        """Topics the recorder has subscribed to so far."""
        marker = "amb-bag record: subscribed "
        return {line[len(marker) :].split(" [")[0] for line in self.text().splitlines() if line.startswith(marker)}

    def wait_subscribed(self, topics, timeout: float) -> bool:
        """Wait until every topic in ``topics`` is being recorded (False on timeout or if the recorder died)."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if set(topics) <= self.subscribed():
                return True
            if self.popen.poll() is not None:
                return False
            time.sleep(0.02)
        return set(topics) <= self.subscribed()

    def stop(self, timeout: float = STOP_TIMEOUT_S) -> int:
        """SIGINT (clean finish), then SIGKILL after ``timeout``; returns the exit code."""
        if self.popen.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                self.popen.send_signal(signal.SIGINT)
            try:
                self.popen.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                self.popen.kill()
                self.popen.wait()
        self._log.close()
        return self.popen.returncode

    def loss(self) -> dict:
        """Loss rows written by the finished recording."""
        rows = custom_json(load_metadata(self.bag_dir), CUSTOM_KEY)
        if rows is None:
            raise BagError(f"{self.bag_dir} has no loss table")
        return rows

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.stop()
