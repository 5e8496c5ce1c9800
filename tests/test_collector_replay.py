"""amb-rig's collector takes only its own children's /diagnostics (issue 20 item 6).

Before: a replayed bag's /diagnostics (same node names) once appeared in the summary as the live run's.  Every
node now stamps ``hardware_id`` "amb-rig pid <pid>" and the collector accepts the pids amb-rig started.
"""

from __future__ import annotations

import os

import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

pytestmark = pytest.mark.ros


def _status(name: str, hardware_id: str, message: str) -> DiagnosticArray:
    st = DiagnosticStatus(level=0, name=name, message=message, hardware_id=hardware_id)
    st.values = [KeyValue(key="final", value="true")]
    return DiagnosticArray(status=[st])


def test_reports_of_other_processes_are_ignored_and_counted():
    import rclpy

    from amb_bringup.collector import DiagnosticsCollector
    from amb_ros.diagnostics import HARDWARE_ID

    assert HARDWARE_ID == f"amb-rig pid {os.getpid()}"
    rclpy.init(args=[])
    try:
        col = DiagnosticsCollector()
        try:
            col.accept_pids = lambda: {4242}
            col._on_diag(_status("amb_plant", "amb-rig pid 1234", "replayed: 99 steps"))  # a bag's
            col._on_diag(_status("amb_plant", "amb-rig", "an old bag's, without a pid"))
            col._on_diag(_status("amb_plant", "amb-rig pid 4242", "finished: 5 steps"))  # this run's
            assert col.get("amb_plant")["message"] == "finished: 5 steps"
            assert col.foreign == {"amb_plant": 2}
        finally:
            col.close()
    finally:
        rclpy.try_shutdown()
