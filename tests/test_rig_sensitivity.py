"""ISO 14839-3 on the rig: `amb-rig sensitivity` injects a multisine into amb1_y of a lockstep run (1 kHz digital
loop of the paper rotor), and the measured S_11 agrees with the frequency-domain model of the digital loop;
`amb-bag sensitivity` gives the same estimate from the recorded bag; bad input is refused before anything starts."""

from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest

from amb_dynamics.config import load_config
from amb_dynamics.sensitivity import loop_state_spaces, sensitivity_matrix
from amb_dynamics.structure import build_structure

pytestmark = pytest.mark.ros

SETS = ["controller.rate_hz=1000", "modal_cutoff=800"]


def test_measured_sensitivity_agrees_with_digital_loop_model(repo, venv_bin, tmp_path):
    cfg_file = str(repo / "config/seed_paper.yaml")
    sets = [a for s in SETS for a in ("--set", s)]
    cmd = [str(venv_bin / "amb-rig"), "sensitivity", "--axis", "amb1_y", "--band", "5:50", "--duration", "6",
           "--resolution", "1", "--settle", "1", "--config", cfg_file, *sets, "--json",
           "--keep-bag", str(tmp_path / "bag"), "--out", str(tmp_path / "S.png")]  # fmt: skip
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=600, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    r = json.loads(proc.stdout)
    f, coh, meas = np.array(r["frequency_hz"]), np.array(r["coherence"]), np.array(r["abs"])
    # the model of the same digital loop, evaluated here from the core's state spaces
    cfg = load_config(cfg_file, SETS)
    plant, ctrl = loop_state_spaces(build_structure(cfg), cfg, cfg.spin_speed_rpm, "sampled")
    model = np.abs(sensitivity_matrix(plant, ctrl, 2 * np.pi * f)[:, 0, 0])
    good = coh >= 0.9
    assert good.sum() >= 10 and f.min() >= 5 and f.max() <= 50
    assert np.max(np.abs(meas[good] - model[good]) / model[good]) < 0.05
    assert r["segments"] >= 4 and r["resolution_hz"] == pytest.approx(1.0)
    assert (tmp_path / "S.png").read_bytes()[:4] == b"\x89PNG"
    # the same estimate from the recorded bag
    bag = subprocess.run(
        [str(venv_bin / "amb-bag"), "sensitivity", str(tmp_path / "bag"), "--axis", "amb1_y", "--resolution", "1",
         "--settle", "1", "--band", "5:50", "--config", cfg_file, *sets, "--json"],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert bag.returncode == 0, bag.stderr
    b = json.loads(bag.stdout)
    assert np.allclose(b["abs"], meas, rtol=1e-12) and b["max_rel_error_where_coherent"] < 0.05
    wrong = subprocess.run([str(venv_bin / "amb-bag"), "sensitivity", str(tmp_path / "bag"), "--axis", "amb5_z"],
                           capture_output=True, text=True, timeout=300)  # fmt: skip
    assert wrong.returncode == 2 and wrong.stderr.count("\n") == 1 and "amb5_z" in wrong.stderr


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["--axis", "amb3_y"], "amb3_y"),
        (["--axis", "amb1_y", "--band", "5:5"], "empty"),
        (["--axis", "amb1_y", "--amplitude", "0.01"], "current limit"),
        (["--axis", "amb1_y", "--band", "5:2600"], "Nyquist"),
    ],
)
def test_bad_input_refused_before_start(venv_bin, tmp_path, args, needle):
    proc = subprocess.run([str(venv_bin / "amb-rig"), "sensitivity", *args], capture_output=True, text=True,
                          timeout=120, cwd=tmp_path)  # fmt: skip
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1 and needle in proc.stderr, proc.stderr
