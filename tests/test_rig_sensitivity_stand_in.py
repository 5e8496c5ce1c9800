"""ISO 14839-3 against a stand-in rig: `amb-rig sensitivity --no-plant` measures S_11 of a plant that another
process plays (`amb-rig run --only plant`, the counterpart a real rig's I/O computer stands for), and gets the
same result as the measurement with its own plant: the lockstep loop is the same loop, split across processes."""

from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest

from helpers import spawn

pytestmark = pytest.mark.ros

SETS = ["controller.rate_hz=1000", "modal_cutoff=800"]
DURATION = 6.0


def measure(repo, venv_bin, tmp_path, *extra):
    sets = [a for s in SETS for a in ("--set", s)]
    cmd = [str(venv_bin / "amb-rig"), "sensitivity", "--axis", "amb1_y", "--band", "10:40", "--duration",
           str(DURATION), "--resolution", "1", "--settle", "1", "--config", str(repo / "config/seed_paper.yaml"),
           *sets, "--json", *extra]  # fmt: skip
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=600, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout)


def test_no_plant_against_a_stand_in_rig_gives_the_same_result(repo, venv_bin, tmp_path):
    own = measure(repo, venv_bin, tmp_path)
    sets = [a for s in SETS for a in ("--set", s)]
    stand_in = [str(venv_bin / "amb-rig"), "run", "--only", "plant", "--duration", str(DURATION + 0.05),
                "--motion", "none", "--config", str(repo / "config/seed_paper.yaml"), *sets,
                "--log-dir", str(tmp_path / "stand_in")]  # fmt: skip
    with spawn(stand_in, tmp_path / "stand_in.log") as rig:
        split = measure(repo, venv_bin, tmp_path, "--no-plant")
        code = rig.wait(120)
    assert code == 0, rig.text()[-2000:]
    f, coh = np.array(split["frequency_hz"]), np.array(split["coherence"])
    assert (coh >= 0.9).sum() >= 10 and split["max_rel_error_where_coherent"] < 0.05
    assert np.array_equal(f, own["frequency_hz"])
    assert np.allclose(split["abs"], own["abs"], rtol=1e-9, atol=0.0)
    assert split["peak"]["zone"] == own["peak"]["zone"]
