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

from amb_dynamics.config import load_config
from amb_dynamics.modes import modes_at_speed
from amb_dynamics.structure import build_structure
from amb_dynamics.system import closed_loop

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
def test_modes_match_ross(ross_eigenvalues, speed):
    ross, _ = ross_eigenvalues
    cfg = load_config(overrides=["modal_cutoff=null"])
    model = build_structure(cfg)
    res = modes_at_speed(model, closed_loop(model, cfg), speed)
    ref = ross[speed]
    upper = ref[ref.imag > 0]
    assert 2 * len(res.modes) + len(res.real_roots) == 2 * model.n  # every eigenvalue is accounted for
    for mode in res.modes:
        j = np.argmin(np.abs(upper - mode.eigenvalue))
        assert abs(upper[j].imag - mode.frequency_rad_s) <= REL_TOL * mode.frequency_rad_s, (mode, upper[j])
        assert abs(upper[j] - mode.eigenvalue) <= REL_TOL * abs(mode.eigenvalue)
    for root in res.real_roots:  # overdamped AMB roots (about -1208 and -4582 1/s at rest)
        assert np.min(np.abs(ref - root)) <= REL_TOL * abs(root)


def test_disk_properties_match_ross(ross_eigenvalues):
    _, data = ross_eigenvalues
    disk = build_structure(load_config()).fe.disks[0]
    np.testing.assert_allclose([disk.m, disk.Ip, disk.Id], [data["disk"][k] for k in ("m", "Ip", "Id")], rtol=1e-12)
