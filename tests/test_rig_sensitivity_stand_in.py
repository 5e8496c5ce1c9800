"""ISO 14839-3 against a stand-in rig: `amb-rig sensitivity --no-plant` measures S_11 of a plant that another
process plays (`amb-rig run --only plant`, the counterpart a real rig's I/O computer stands for), and gets the
same result as the measurement with its own plant: the lockstep loop is the same loop, split across processes.
Also right after a run on the same domain was killed with SIGKILL.  The stand-in starts stepping once the host's
readers of /amb/displacement are matched (``plant:min_subscribers``: the controller and the recorder, as a real
rig's I/O computer must wait for them, docs/rig-bridge.md); without it the recorder lost the first samples and
the record was too short."""

from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest

from helpers import rig_in_progress
from procs import spawn

pytestmark = pytest.mark.ros

SETS = ["controller.rate_hz=1000", "modal_cutoff=800"]
DURATION = 6.0
HOST_READERS = 2  # of /amb/displacement on the host side: the controller and amb-rig sensitivity's recorder


def measure(repo, venv_bin, tmp_path, *extra):
    sets = [a for s in SETS for a in ("--set", s)]
    cmd = [str(venv_bin / "amb-rig"), "sensitivity", "--axis", "amb1_y", "--band", "10:40", "--duration",
           str(DURATION), "--resolution", "1", "--settle", "1", "--config", str(repo / "config/seed_paper.yaml"),
           *sets, "--json", *extra]  # fmt: skip
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=600, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout)


def split_measurement(repo, venv_bin, tmp_path, tag: str) -> dict:
    sets = [a for s in SETS for a in ("--set", s)]
    stand_in = [str(venv_bin / "amb-rig"), "run", "--only", "plant", "--duration", str(DURATION + 0.05),
                "--motion", "none", "--config", str(repo / "config/seed_paper.yaml"), *sets,
                "--param", f"plant:min_subscribers={HOST_READERS}", "--log-dir", str(tmp_path / tag)]  # fmt: skip
    with spawn(stand_in, tmp_path / f"{tag}.log") as rig:
        split = measure(repo, venv_bin, tmp_path, "--no-plant")
        code = rig.wait(120)
    assert code == 0, rig.text()[-2000:]
    return split


def kill_a_run(repo, venv_bin, tmp_path) -> None:
    """A whole run on this domain killed by SIGKILL, its nodes included (their participants linger)."""
    import psutil

    cmd = [str(venv_bin / "amb-rig"), "run", "--duration", "60", "--motion", "none", "--config",
           str(repo / "config/seed_paper.yaml"), "--log-dir", str(tmp_path / "killed")]  # fmt: skip
    with rig_in_progress(cmd, tmp_path / "killed.log", samples=200) as proc:
        top = psutil.Process(proc.popen.pid)
        victims = [*top.children(recursive=True), top]
        for v in victims:
            v.kill()
        psutil.wait_procs(victims, timeout=10)


def test_no_plant_against_a_stand_in_rig_gives_the_same_result(repo, venv_bin, tmp_path):
    own = measure(repo, venv_bin, tmp_path)
    kill_a_run(repo, venv_bin, tmp_path)
    for tag in ("after_a_killed_run", "stand_in"):
        split = split_measurement(repo, venv_bin, tmp_path, tag)
        f, coh = np.array(split["frequency_hz"]), np.array(split["coherence"])
        assert (coh >= 0.9).sum() >= 10 and split["max_rel_error_where_coherent"] < 0.05
        assert np.array_equal(f, own["frequency_hz"])
        assert np.allclose(split["abs"], own["abs"], rtol=1e-9, atol=0.0)
        assert split["peak"]["zone"] == own["peak"]["zone"]
