"""The seed rotor's closed-loop eigenvalues against an independent FE code, ROSS (petrobras/ross).

ROSS runs in its own venv (.venv-ref, `make ref`, installed by `make test`): tests/reference/ross_modes.py builds
the same rotor (6 Euler-Bernoulli elements with rotary inertia and gyroscopics, the disk, AMBs as k_eq = 1.388e6
N/m and c_eq = 2000 N s/m) and returns ROSS's eigenvalues at 0 and 1000 rpm.  ROSS also has axial and torsional
DOFs; every lateral mode of amb-rig must have a ROSS eigenvalue within 1e-6 relative (the agreement the README
states; the first requirement was 0.1 % in frequency; measured: 1.2e-7 at worst).
"""

import json
import subprocess

import numpy as np
import pytest

from amb_dynamics import cli
from amb_dynamics.config import load_config, paper_config_path
from amb_dynamics.structure import build_structure

SPEEDS = (0.0, 1000.0)
REL_TOL = 1e-6


@pytest.fixture(scope="module")
def ross_eigenvalues(repo, tmp_path_factory):
    out = tmp_path_factory.mktemp("ross") / "ross.json"
    py = repo / ".venv-ref" / "bin" / "python"
    assert py.exists(), "the reference venv is missing: run `make ref` (make test does it)"
    subprocess.run(
        [str(py), str(repo / "tests/reference/ross_modes.py"), str(out), *map(str, SPEEDS)],
        check=True,
        capture_output=True,
        timeout=300,
    )
    data = json.loads(out.read_text())
    return {s: np.array([complex(*z) for z in data[str(s)]]) for s in SPEEDS}, data


@pytest.mark.parametrize("speed", SPEEDS)
def test_modes_match_ross(ross_eigenvalues, capsys, speed):
    """`amb-dynamics modes --config config/seed_paper.yaml` as a user runs it, without any extra flag."""
    ross, _ = ross_eigenvalues
    assert cli.main(["modes", "--config", str(paper_config_path()), "--speed-rpm", str(speed), "--json"]) == 0
    res = json.loads(capsys.readouterr().out)["speeds"][0]
    n_fe = build_structure(load_config(paper_config_path(), ["modal_cutoff=null"])).n
    ref = ross[speed]
    upper = ref[ref.imag > 0]
    pairs = res["overdamped_pairs_1_s"]
    assert 2 * len(res["modes"]) + 2 * len(pairs) + len(res["real_roots_1_s"]) == 2 * n_fe  # every eigenvalue
    for re, im in pairs:  # the overdamped roots that spinning made into pairs
        lam = complex(re, im)
        assert np.min(np.abs(upper - lam)) <= REL_TOL * abs(lam) and im < 0.045 * -re, lam
    for mode in res["modes"]:
        lam = complex(*mode["eigenvalue"])
        j = np.argmin(np.abs(upper - lam))
        assert abs(upper[j].imag - mode["frequency_rad_s"]) <= REL_TOL * mode["frequency_rad_s"], (mode, upper[j])
        assert abs(upper[j] - lam) <= REL_TOL * abs(lam)
    for root in res["real_roots_1_s"]:  # overdamped AMB roots (about -1208 and -4582 1/s at rest)
        assert np.min(np.abs(ref - root)) <= REL_TOL * abs(root)


def test_disk_properties_match_ross(ross_eigenvalues):
    _, data = ross_eigenvalues
    disk = build_structure(load_config(paper_config_path())).fe.disks[0]
    np.testing.assert_allclose([disk.m, disk.Ip, disk.Id], [data["disk"][k] for k in ("m", "Ip", "Id")], rtol=1e-12)
