"""amb-rig's own small node: collects every node's /diagnostics (latest status per node) in a thread."""

from __future__ import annotations

import threading
import time

from diagnostic_msgs.msg import DiagnosticArray

from amb_ros.diagnostics import LEVEL_NAMES
from amb_ros.messages import DIAGNOSTICS
from amb_ros.qos import diagnostics_qos


class DiagnosticsCollector:
    """``latest[node] = {"level", "message", "values", "final"}``; rclpy must be initialised."""

    def __init__(self, name: str = "amb_rig"):
        import rclpy
        from rclpy.executors import SingleThreadedExecutor

        self.node = rclpy.create_node(name)
        self.latest: dict[str, dict] = {}
        self.accept_pids = None  # callable returning the pids whose reports count (None: everyone's)
        self.peer_names: set[str] = set()  # a split run: the other side's nodes, whose pids are on another host
        self.foreign: dict[str, int] = {}  # status name -> reports ignored (not from this run's processes)
        self.first_seen: dict[str, float] = {}
        self._lock = threading.Lock()
        self.node.create_subscription(DiagnosticArray, DIAGNOSTICS, self._on_diag, diagnostics_qos())
        self._executor = SingleThreadedExecutor(context=self.node.context)
        self._executor.add_node(self.node)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._spin, name="diagnostics", daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        while not self._stop.is_set():
            self._executor.spin_once(timeout_sec=0.05)

    def _accepted(self, hardware_id: str) -> bool:
        """A report of one of this run's processes (``hardware_id`` "amb-rig pid N"), when a pid set is given."""
        if self.accept_pids is None:
            return True
        head, _, pid = hardware_id.rpartition(" pid ")
        return head == "amb-rig" and pid.isdigit() and int(pid) in self.accept_pids()

    def _on_diag(self, msg: DiagnosticArray) -> None:
        with self._lock:
            for st in msg.status:
                own = st.name not in self.peer_names
                if own and not self._accepted(st.hardware_id):  # a replayed bag's, another run's: never this run's
                    self.foreign[st.name] = self.foreign.get(st.name, 0) + 1
                    continue
                values = {kv.key: kv.value for kv in st.values}
                self.first_seen.setdefault(st.name, time.monotonic())
                prev = self.latest.get(st.name)
                if prev is not None and prev["final"] and values.get("final") != "true":
                    continue  # a late periodic message never replaces the final one
                self.latest[st.name] = {
                    "level": LEVEL_NAMES.get(st.level, str(st.level)),
                    "message": st.message,
                    "values": values,
                    "final": values.get("final") == "true",
                }

    def get(self, node: str) -> dict | None:
        with self._lock:
            entry = self.latest.get(node)
            return None if entry is None else dict(entry)

    def seen(self, node: str) -> bool:
        with self._lock:
            return node in self.first_seen

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2.0)
        self._executor.remove_node(self.node)
        self.node.destroy_node()
