"""kill -9 of each node: amb-rig notices within 2 s (its process watch polls every 50 ms), names the dead node as
the run's first error, and exits 1.

Before: 13.6 s (controller, base_motion; the latter reported through the plant as a configuration hint) and 21 s
(monitor, recorder) until the run failed.  What the plant reports about a dead controller is in
test_rig_faults.py.
"""

from __future__ import annotations

import os
import signal
import time

import pytest

from helpers import rig_json, started_pids, wait_gone
from procs import spawn

pytestmark = pytest.mark.ros


@pytest.mark.parametrize("name", ["plant", "controller", "base_motion", "monitor", "recorder"])
def test_kill_9_of_a_node_is_noticed_and_named(tmp_path, venv_bin, name):
    cmd = [str(venv_bin / "amb-rig"), "run", "--json", "--duration", "100", "--initial-displacement", "1e-4",
           "--log-dir", str(tmp_path / "logs"), "--bag", str(tmp_path / "bag")]  # fmt: skip
    with spawn(cmd, tmp_path / "rig.log") as proc:
        assert proc.wait_for("started plant", 60), proc.text()
        time.sleep(3.0)  # running (the plant waits for its peers, then steps)
        pids = started_pids(proc.text())
        assert proc.popen.poll() is None, proc.text()
        os.kill(pids[name], signal.SIGKILL)
        t_kill = time.monotonic()
        noticed = proc.wait_for(f"amb-rig: {name} died (killed by SIGKILL); stopping the run", 10.0)
        noticed_s = time.monotonic() - t_kill
        code = proc.wait(60)
        text = proc.text()
    assert noticed and noticed_s < 2.0, (noticed_s, text)  # the watch polls every 50 ms
    assert code == 1, text
    s = rig_json(text)
    assert s["errors"][0] == f"{name} died (killed by SIGKILL)"
    assert not [e for e in s["errors"][1:] if e.startswith(name)], s["errors"]  # said once
    assert s["verdict"]["line"].startswith(f"verdict: FAILED: {name} died (killed by SIGKILL)")
    assert wait_gone(pids.values()) == []
