"""`amb-rig run` starts the stability monitor itself and reports its verdict in the summary (issue 6, item 5)."""

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

from helpers import model_rho

pytestmark = pytest.mark.ros

TS = 2e-4
PAPER = str(Path(__file__).resolve().parents[1] / "config" / "seed_paper.yaml")  # the paper's idealised rotor
LINEAR = ["--config", PAPER, "--initial-displacement", "1e-3", "--set", "controller.current_limit=1e9",
          "--param", "plant:max_displacement_ratio=1e9"]  # fmt: skip


def rig(venv_bin, tmp_path, amplitude, N, periods):
    T = N * TS
    cmd = [str(venv_bin / "amb-rig"), "run", "--json", "--duration", repr(periods * T), "--motion", "pitch",
           "--amplitude", repr(amplitude), "--frequency", repr(np.pi / T), "--log-dir", str(tmp_path / "logs"),
           "--param", "monitor:input=displacement", *LINEAR]  # fmt: skip
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=400)
    return proc, T


def test_unstable_verdict_in_the_summary(venv_bin, tmp_path):
    proc, T = rig(venv_bin, tmp_path, 0.6, 718, 13)
    assert proc.returncode == 0, proc.stderr[-3000:]  # an UNSTABLE verdict is a result, not a failed run
    s = json.loads(proc.stdout)
    st = s["stability"]
    assert st["unstable"] is True and st["verdict"] == "unstable"
    assert st["flag_raised_at_s"] <= 8 * T  # the documented detection latency
    assert st["rho"] == pytest.approx(model_rho(0.6, T), abs=1e-3)  # the sampled-data model multiplier
    assert s["nodes"]["monitor"]["exit_code"] == 0
    # lockstep has no deadline: amb-rig runs the monitor at normal priority, so that it is never starved
    assert s["nodes"]["monitor"]["values"]["scheduling"] == "normal"
