"""`amb-dynamics unbalance` of the paper rotor against ROSS's unbalance response (petrobras/ross, .venv-ref).

tests/reference/ross_unbalance.py builds the rotor of tests/reference/ross_modes.py in ROSS and returns its
complex synchronous response to the same disk unbalance.  ROSS's x, y are amb-rig's Y, Z (v, w); both put the
unbalance force U w^2 (cos, sin)(w t + p) on them.  Three speeds, one 0.01 % from the critical speed (232.7 rpm,
the forward conical mode's crossing of 1x, damping ratio 0.2 %): amplitude and phase to 1 % (complex error).
"""

import json
import subprocess

import numpy as np
import pytest

from amb_dynamics import cli
from amb_dynamics.config import paper_config_path

U, PHASE_DEG = 1.0e-3, 30.0
SPEEDS = (232.7, 1000.0, 3000.0)
CHANNELS = {"amb1": 1, "amb5": 5, "disk7": 7}


@pytest.fixture(scope="module")
def ross(repo, tmp_path_factory):
    out = tmp_path_factory.mktemp("ross") / "ross_unbalance.json"
    py = repo / ".venv-ref" / "bin" / "python"
    assert py.exists(), "the reference venv is missing: run `make ref` (make test does it)"
    args = [str(out), str(U), str(np.radians(PHASE_DEG)), *map(str, SPEEDS)]
    subprocess.run([str(py), str(repo / "tests/reference/ross_unbalance.py"), *args], check=True, capture_output=True,
                   timeout=600)  # fmt: skip
    return json.loads(out.read_text())


def test_unbalance_response_matches_ross(ross, capsys):
    argv = ["unbalance", "--config", str(paper_config_path()), "--set", f"disks.0.unbalance={U}", "--set",
            f"disks.0.unbalance_phase_deg={PHASE_DEG}", "--speed-rpm", *map(str, SPEEDS), "--json"]  # fmt: skip
    assert cli.main(argv) == 0
    ours = json.loads(capsys.readouterr().out)["speeds"]
    for entry, rpm in zip(ours, SPEEDS, strict=True):
        ref = ross[str(rpm)]
        for name, node in CHANNELS.items():
            for ax, rax in (("y", "x"), ("z", "y")):
                a = entry["amplitude_m"][f"{name}_{ax}"]
                z = a * np.exp(1j * np.radians(entry["phase_deg"][f"{name}_{ax}"]))
                r = complex(*ref[f"{node}_{rax}"])
                assert abs(z - r) <= 0.01 * abs(r), (rpm, name, ax, z, r)
    near = ours[0]["amplitude_m"]["disk7_y"]
    assert near > 20 * ours[1]["amplitude_m"]["disk7_y"]  # 232.7 rpm is on the resonance peak
