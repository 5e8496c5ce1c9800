"""A node's final /diagnostics report reaches a reader that matches only after the node has finished.

/diagnostics is volatile, so a report published before a reader is matched is never delivered to it; a short
lockstep run can end before amb-rig's collector has discovered every node (seen: every report of base_motion and
the controller missing).  ``Diagnostics.publish_final`` therefore waits, at most ``timeout_s``, for
``min_readers`` matched readers.  Shown with a reader that appears 0.5 s after the node is ready to report, and
the control without the wait, where the same reader gets nothing.  In a split run the other host's readers count
too, so a count can be met while this side's collector is not yet matched: the wait also names that reader
(``collector``), shown with another reader that is there from the start.
"""

from __future__ import annotations

import json
import subprocess
import sys
import time

import pytest
from diagnostic_msgs.msg import DiagnosticArray

from amb_ros.env import child_env
from helpers import DdsRecorder

REPORTER = """
import json, sys, time
import rclpy
from amb_ros.diagnostics import OK, Diagnostics
rclpy.init()
node = rclpy.create_node("final_report_test")
diag = Diagnostics(node, 0.5, min_readers=int(sys.argv[1]), collector=sys.argv[2])
deadline = time.monotonic() + 10.0
while diag.pub.get_subscription_count() < int(sys.argv[3]) and time.monotonic() < deadline:
    time.sleep(0.01)  # the early reader, when there is one, is matched before "ready"
print("ready", flush=True)
t0 = time.monotonic()
diag.publish_final(OK, "done", {"answer": "42"}, timeout_s=5.0)
print(json.dumps({"waited_s": time.monotonic() - t0}), flush=True)
"""


def late_reader_gets(min_readers: int, collector: str = "", early_reader: bool = False) -> tuple[list, float]:
    """The reports that a reader named ``test_recorder`` gets when it appears 0.5 s after the reporter is ready;
    ``early_reader``: another reader (``other_host``) is there from the start."""
    early = DdsRecorder({"/diagnostics": DiagnosticArray}, name="other_host") if early_reader else None
    argv = [sys.executable, "-c", REPORTER, str(min_readers), collector, str(int(early_reader))]
    proc = subprocess.Popen(argv, env=child_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    rec = None
    try:
        assert proc.stdout.readline().strip() == "ready", proc.stderr.read()[-2000:]
        time.sleep(0.5)
        rec = DdsRecorder({"/diagnostics": DiagnosticArray})
        waited = json.loads(proc.stdout.readline())["waited_s"]
        deadline = time.monotonic() + 3.0
        while time.monotonic() < deadline and not rec.messages["/diagnostics"]:
            time.sleep(0.05)
        time.sleep(0.2)
        reports = [s for m in rec.messages["/diagnostics"] for s in m.status if s.name == "final_report_test"]
        return reports, waited
    finally:
        for r in (rec, early):
            if r is not None:
                r.close()
        proc.kill()
        proc.wait()


@pytest.mark.ros
def test_final_report_waits_for_a_late_reader():
    reports, waited = late_reader_gets(1)
    assert len(reports) == 1 and reports[0].message == "done"
    assert {kv.key: kv.value for kv in reports[0].values} == {"answer": "42", "final": "true"}
    assert 0.4 < waited < 5.5  # it waited for the reader (then for its acknowledgement), bounded by timeout_s
    control, waited0 = late_reader_gets(0)
    assert control == [] and waited0 < 0.4  # without the wait the late reader never hears the report


@pytest.mark.ros
def test_final_report_waits_for_the_named_collector_not_just_a_count():
    reports, waited = late_reader_gets(1, collector="test_recorder", early_reader=True)
    assert [r.message for r in reports] == ["done"]
    assert 0.4 < waited < 5.5  # the early reader met the count; the report waited for the named one
    control, waited0 = late_reader_gets(1, early_reader=True)
    assert control == [] and waited0 < 0.4  # the count alone: met by the other reader, the late one hears nothing
