"""A full disk (a 1 MiB tmpfs) under ``amb-bag record`` and ``amb-bag check``: one line, exit 1, no traceback.

Before: the run failed but the recorder's row said ``OK ... lost 0``, and both commands printed a traceback.
Needs root for ``mount -t tmpfs`` (the test machine runs as root); elsewhere it cannot run and says so.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from procs import spawn

sys.path.insert(0, str(Path(__file__).parent / "bagtools"))
import mix

PUBLISHER = Path(__file__).parent / "bagtools" / "publisher.py"


@pytest.fixture
def small_disk(tmp_path):
    mnt = tmp_path / "disk"
    mnt.mkdir()
    if os.geteuid() != 0 or subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(mnt)],
                                           capture_output=True).returncode != 0:  # fmt: skip
        pytest.skip("mounting a tmpfs needs root")
    try:
        yield mnt
    finally:
        subprocess.run(["umount", "-l", str(mnt)], check=False)


def test_check_on_a_full_disk_is_one_line_and_leaves_the_bag_as_it_was(small_disk, capsys):
    from amb_bag import cli

    bag = small_disk / "bag"
    mix.write_bag(bag, 300, chunk_size=2048)
    data = (bag / "bag_0.mcap").read_bytes()
    (bag / "bag_0.mcap").write_bytes(data[: len(data) // 2])
    before = {p.name: p.read_bytes() for p in bag.iterdir()}
    free = os.statvfs(small_disk)
    (small_disk / "filler").write_bytes(bytes(free.f_bavail * free.f_frsize - 4096))  # leave less than a copy
    with pytest.raises(SystemExit) as exc:
        cli.main(["check", str(bag)])
    err = capsys.readouterr().err
    assert exc.value.code == 1 and err.count("\n") == 1 and "No space left on device" in err, err
    assert {p.name: p.read_bytes() for p in bag.iterdir()} == before  # nothing half-written, nothing replaced


@pytest.mark.ros
def test_record_on_a_full_disk_is_one_line_and_an_error_row(small_disk, tmp_path, venv_bin):
    bag = small_disk / "bag"
    rec_cmd = [str(venv_bin / "amb-bag"), "record", "-o", str(bag), "--flush-interval", "0.2"]
    pub_cmd = [sys.executable, str(PUBLISHER), "--steps", "20000", "--rate", "0", "--log", str(tmp_path / "sent.pkl"),
               "--wait-subscribers", "30"]  # fmt: skip
    with spawn(rec_cmd, tmp_path / "rec.log") as rec:
        assert rec.wait_for("recording to", 30), rec.text()
        with spawn(pub_cmd, tmp_path / "pub.log") as pub:
            code = rec.wait(90)
            pub.stop()
        text = rec.text()
    assert code == 1, text
    last = text.strip().splitlines()[-1]
    assert last == f"amb-bag record: {bag}: No space left on device; the bag is incomplete, run `amb-bag check`"
    assert "Traceback" not in text


@pytest.mark.ros
def test_a_rig_run_recording_to_a_full_disk_fails_with_the_recorder_row_an_error(small_disk, tmp_path, venv_bin):
    """amb-rig run --bag on a disk that fills up: the run fails (exit 1), and the recorder's row is an ERROR that
    says what reached the disk and what was lost, never ``OK ... lost 0``."""
    from helpers import rig_json

    bag = small_disk / "bag"
    cmd = [str(venv_bin / "amb-rig"), "run", "--json", "--duration", "4", "--no-monitor", "--bag", str(bag),
           "--log-dir", str(tmp_path / "logs")]  # fmt: skip
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 1, proc.stdout[-3000:] + proc.stderr[-3000:]
    s = rig_json(proc.stdout)
    rec = s["nodes"]["recorder"]
    assert rec["level"] == "ERROR", rec
    values = rec["values"]
    assert values["write error"].startswith("No space left on device"), values
    received, on_disk = int(values["received"]), int(values["messages on disk"])
    assert 0 <= on_disk < received  # a 1 MiB disk cannot hold a 4 s lockstep run (20,000 steps per topic)
    assert f"lost at least {received - on_disk}" in rec["message"], rec
    assert any("recorder" in e for e in s["errors"]), s["errors"]
    assert "Traceback" not in proc.stderr


@pytest.mark.ros
def test_a_write_error_report_waits_for_the_named_collector(small_disk, tmp_path, venv_bin):
    """/diagnostics is volatile: the recorder's ERROR report of a full disk reaches a reader that is matched only
    after the disk has filled, because ``--diagnostics-collector`` (amb-rig passes its collector's name) makes the
    recorder wait for that reader before it exits.  Before, amb-rig's row of the recorder sometimes said "no
    diagnostics received" (3 runs in 14 of `amb-rig run --bag` on a 1 MiB disk)."""
    import time

    from diagnostic_msgs.msg import DiagnosticArray

    from amb_bag.recorder import NODE_NAME
    from helpers import DdsRecorder

    bag = small_disk / "bag"
    rec_cmd = [str(venv_bin / "amb-bag"), "record", "-o", str(bag), "--flush-interval", "0.2",
               "--diagnostics-collector", "late_collector"]  # fmt: skip
    pub_cmd = [sys.executable, str(PUBLISHER), "--steps", "20000", "--rate", "0", "--log", str(tmp_path / "sent.pkl"),
               "--wait-subscribers", "30"]  # fmt: skip
    collector = None
    try:
        with spawn(rec_cmd, tmp_path / "rec.log") as rec:
            assert rec.wait_for("recording to", 30), rec.text()
            with spawn(pub_cmd, tmp_path / "pub.log") as pub:
                deadline = time.monotonic() + 60.0
                while os.statvfs(small_disk).f_bavail > 0 and time.monotonic() < deadline:
                    time.sleep(0.02)
                assert os.statvfs(small_disk).f_bavail == 0, "the disk did not fill"
                collector = DdsRecorder({"/diagnostics": DiagnosticArray}, name="late_collector")
                code = rec.wait(90)
                pub.stop()
            text = rec.text()
        assert code == 1 and "No space left on device" in text, text
        deadline = time.monotonic() + 3.0
        while time.monotonic() < deadline and not collector.messages["/diagnostics"]:
            time.sleep(0.05)
        time.sleep(0.2)
        reports = [s for m in collector.messages["/diagnostics"] for s in m.status if s.name == NODE_NAME]
        errors = [s for s in reports if s.level == b"\x02" and "No space left on device" in s.message]  # ERROR
        assert errors, [(s.level, s.message) for s in reports]
        assert {kv.key: kv.value for kv in errors[-1].values}["final"] == "true"
    finally:
        if collector is not None:
            collector.close()
