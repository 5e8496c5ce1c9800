"""/diagnostics publishing and message accounting shared by the nodes.

Each node publishes one DiagnosticStatus named after the node (``hardware_id`` "amb-rig pid <pid>", so that
amb-rig takes only its own children's reports, never a replayed bag's) every
``period_s`` of wall time and once more when it stops (key ``final`` = ``true``), waiting until every reader
has acknowledged that last one so that ``amb-rig`` can summarise the run from it.  Values are strings; keys carry
units in parentheses, as diagnostic_updater's do (``rate (Hz)``).
"""

from __future__ import annotations

import os
import time
from collections import defaultdict

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.duration import Duration

from .messages import DIAGNOSTICS, Foreign, Rejected
from .qos import diagnostics_qos

OK, WARN, ERROR = DiagnosticStatus.OK, DiagnosticStatus.WARN, DiagnosticStatus.ERROR
LEVEL_NAMES = {OK: "OK", WARN: "WARN", ERROR: "ERROR", DiagnosticStatus.STALE: "STALE"}
HARDWARE_ID = f"amb-rig pid {os.getpid()}"  # the publishing process: amb-rig accepts only its children's


class Counters:
    """Messages published, received and rejected per topic, with the last rejection reason."""

    def __init__(self):
        self.published: dict[str, int] = defaultdict(int)
        self.received: dict[str, int] = defaultdict(int)
        self.rejected: dict[str, int] = defaultdict(int)
        self.foreign: dict[str, int] = defaultdict(int)  # of the rejected: another run's token
        self.last_rejection = ""

    def decode(self, topic: str, decoder, raw: bytes):
        """Count a received message and decode it; a rejected one (NaN, wrong names or sizes) is counted with its
        reason and gives None, so that it never reaches the physics."""
        self.received[topic] += 1
        try:
            return decoder(raw)
        except Foreign as exc:
            self.foreign[topic] += 1
            self.reject(topic, str(exc))
            return None
        except Rejected as exc:
            self.reject(topic, str(exc))
            return None

    def reject(self, topic: str, reason: str) -> None:
        self.rejected[topic] += 1
        self.last_rejection = f"{topic}: {reason}"

    @property
    def total_rejected(self) -> int:
        return sum(self.rejected.values())

    def values(self) -> dict[str, str]:
        out = {}
        tables = (("published", self.published), ("received", self.received), ("rejected", self.rejected),
                  ("foreign", self.foreign))  # fmt: skip
        for name, table in tables:
            for topic, count in sorted(table.items()):
                out[f"{name} {topic}"] = str(count)
        out["rejected total"] = str(self.total_rejected)
        if self.last_rejection:
            out["last rejection"] = self.last_rejection
        return out


class Timings:
    """A bounded record of durations (s) with percentiles, for jitter and compute-time statistics."""

    def __init__(self, capacity: int = 2_000_000):
        self._buf = np.empty(capacity)
        self.count = 0

    def add(self, value: float) -> None:
        if self.count < self._buf.size:
            self._buf[self.count] = value
        self.count += 1

    def summary(self, prefix: str, unit_scale: float = 1e6, unit: str = "us") -> dict[str, str]:
        data = self._buf[: min(self.count, self._buf.size)]
        if data.size == 0:
            return {}
        p50, p99 = np.percentile(data, [50.0, 99.0])
        return {
            f"{prefix} p50 ({unit})": f"{p50 * unit_scale:.1f}",
            f"{prefix} p99 ({unit})": f"{p99 * unit_scale:.1f}",
            f"{prefix} max ({unit})": f"{data.max() * unit_scale:.1f}",
        }


class Diagnostics:
    """Periodic and final DiagnosticStatus of one node."""

    def __init__(self, node, period_s: float = 0.5, min_readers: int = 0, collector: str = ""):
        self.node, self.min_readers, self.collector = node, min_readers, collector
        self.pub = node.create_publisher(DiagnosticArray, DIAGNOSTICS, diagnostics_qos())
        self.period_ns = int(period_s * 1e9)
        self._next_ns = time.monotonic_ns()
        self.level, self.message = OK, "starting"
        self.published = 0

    def readers_missing(self) -> str | None:
        """What the final report still waits for: ``min_readers`` matched readers and, when named, the collector's
        own reader.  The count alone is not enough in a split run: the other host's readers count too, and the
        report must reach this side's amb-rig (seen: a plant ended and reported before its own collector matched)."""
        if self.pub.get_subscription_count() < self.min_readers:
            return f"{self.min_readers} reader(s) of {DIAGNOSTICS}"
        if self.collector and not any(
            i.node_name == self.collector for i in self.node.get_subscriptions_info_by_topic(DIAGNOSTICS)
        ):
            return f"{DIAGNOSTICS} reader {self.collector} (amb-rig's collector)"
        return None

    def due(self) -> bool:
        return time.monotonic_ns() >= self._next_ns

    def publish(self, level: bytes, message: str, values: dict[str, str], final: bool = False) -> None:
        self.level, self.message = level, message
        status = DiagnosticStatus(level=level, name=self.node.get_name(), message=message, hardware_id=HARDWARE_ID)
        values = dict(values, final="true" if final else "false")
        status.values = [KeyValue(key=k, value=str(v)) for k, v in values.items()]
        arr = DiagnosticArray(status=[status])
        arr.header.stamp = self.node.get_clock().now().to_msg()
        self.pub.publish(arr)
        self.published += 1
        self._next_ns = time.monotonic_ns() + self.period_ns

    def publish_final(self, level: bytes, message: str, values: dict[str, str], timeout_s: float = 4.0) -> None:
        """Publish the last status and wait (bounded by ``timeout_s`` in all) until every matched reader has it.

        /diagnostics is volatile: a reader that this publisher has not matched yet would never get the report, and
        a short run can end before discovery has completed (seen: amb-rig's collector missed base_motion's and the
        controller's every report).  So first wait for the readers of ``readers_missing``: up to 4 s by default,
        longer than Fast DDS's 3 s announcement period, so that a pair of participants that missed each other's
        initial announcements (processes starting together) is matched by the next periodic one in time."""
        deadline = time.monotonic() + timeout_s
        while self.readers_missing() and time.monotonic() < deadline:
            time.sleep(0.01)
        self.publish(level, message, values, final=True)
        self.pub.wait_for_all_acked(Duration(seconds=max(0.1, deadline - time.monotonic())))
