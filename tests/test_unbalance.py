"""Unbalance (issue 15): force direction, forward whirl, the frequency-domain response against a direct solve
and against a time integration, and `amb-dynamics unbalance` (JSON schema, PNG, bad input)."""

import json
import re

import numpy as np
import pytest
import scipy.linalg as sla

from amb_dynamics import cli
from amb_dynamics.config import load_config, paper_config_path
from amb_dynamics.fe import dof_index
from amb_dynamics.modes import modes_at_speed
from amb_dynamics.structure import build_structure
from amb_dynamics.system import closed_loop
from amb_dynamics.unbalance import SynchronousResponse, Unbalance, channels, input_matrix

U = 1.0e-3  # kg m on the disk (node 7)


@pytest.fixture(scope="module")
def rotor():
    cfg = load_config(
        paper_config_path(), ["modal_cutoff=null", f"disks.0.unbalance={U}", "disks.0.unbalance_phase_deg=30"]
    )
    model = build_structure(cfg)
    loop = closed_loop(model, cfg)
    return cfg, model, loop, SynchronousResponse(model, loop, Unbalance.from_config(cfg))


def test_force_turns_with_the_spin_from_y_to_z(rotor):
    cfg, model, _, _ = rotor
    ub = Unbalance.from_config(cfg)
    w = 100.0
    v, z = dof_index(7, 0), dof_index(7, 1)
    for phi in np.linspace(0, 2 * np.pi, 9):
        f = ub.force_fe(model.fe.n, phi, w)
        heavy = phi + np.radians(30)  # the heavy spot at unbalance_phase_deg from +Y toward +Z
        assert f[[v, z]] == pytest.approx(U * w**2 * np.array([np.cos(heavy), np.sin(heavy)]), abs=1e-12)
    # on a base turning at constant Omega_z the relative (Coriolis and centripetal) terms add, as in PHYSICS 4.7
    Om = np.array([0.0, 0.0, 2.0])
    f = ub.force_fe(model.fe.n, 0.0, w, 0.0, Om, np.zeros(3))
    r = np.array([0.0, np.cos(np.radians(30)), np.sin(np.radians(30))])
    acc = -(w**2) * r + 2 * np.cross(Om, w * np.array([0.0, -r[2], r[1]])) + np.cross(Om, np.cross(Om, r))
    assert f[[v, z]] == pytest.approx(-U * acc[1:], rel=1e-12)


def test_unbalance_excites_forward_whirl(rotor):
    _, model, loop, resp = rotor
    speeds = np.array([150.0, 232.0, 240.0, 500.0, 1000.0, 3000.0])
    y = resp.displacements(speeds)
    t = np.linspace(0, 1, 64, endpoint=False)
    for k, s in enumerate(speeds):
        w = s * np.pi / 30
        for node in (1, 5, 7):
            a, b = y[k, dof_index(node, 0)], y[k, dof_index(node, 1)]
            yy, zz = np.real(a * np.exp(1j * w * t)), np.real(b * np.exp(1j * w * t))
            dy, dz = np.real(1j * w * a * np.exp(1j * w * t)), np.real(1j * w * b * np.exp(1j * w * t))
            assert np.all(yy * dz - zz * dy > 0)  # the orbit turns from +Y toward +Z, with the spin
            assert abs(b + 1j * a) <= 1e-9 * abs(a)  # isotropic rotor: circular, z lags y by 90 degrees
    # the resonance is the forward mode's crossing of 1x, and that mode stiffens with spin (gyroscopics)
    crit = resp.critical_speeds_rpm(0, 3000)
    assert len(crit) == 1
    wc = crit[0] * np.pi / 30
    fwd = [m for m in modes_at_speed(model, loop, crit[0]).modes if m.whirl == "forward"]
    mode = min(fwd, key=lambda m: abs(m.frequency_rad_s - wc))
    assert mode.frequency_rad_s == pytest.approx(wc, rel=2e-3)
    later = [m for m in modes_at_speed(model, loop, 2 * crit[0]).modes if m.whirl == "forward"]
    assert min(later, key=lambda m: abs(m.frequency_rad_s - wc)).frequency_rad_s > mode.frequency_rad_s


def test_vectorised_response_equals_direct_solve(rotor):
    _, model, loop, resp = rotor
    b = input_matrix(model, loop) @ Unbalance.from_config(rotor[0]).amplitude_fe(model.fe.n)
    speeds = np.array([37.0, 232.7, 1000.0, 2999.0])
    got = resp.displacements(speeds)
    for k, s in enumerate(speeds):
        w = s * np.pi / 30
        L = 1j * w * np.eye(loop.N) - (loop.A0 + w * loop.A_terms["Phi"])
        ref = np.linalg.solve(L, w**2 * b)[: model.n]
        assert np.max(np.abs(got[k] - ref)) <= 1e-9 * np.max(np.abs(ref))


def test_time_domain_steady_state_equals_frequency_domain(rotor):
    """The periodic steady state of the time-domain equations, with the time-domain force, computed without the
    frequency domain: exact propagation of [x; cos; sin] (the force generator) over one revolution T, and the
    fixed point x* = (I - Phi_T)^-1 x_forced(T) of the period map.  Its orbit at the AMBs and the disk equals
    Re(x^ e^{i w t}) to 1e-4 of the amplitude."""
    cfg, model, loop, resp = rotor
    ub = Unbalance.from_config(cfg)
    Bu = input_matrix(model, loop)
    idx = [i for _, i in channels(cfg)]
    for rpm in (240.0, 1000.0):
        w = rpm * np.pi / 30
        T = 2 * np.pi / w
        # the generator's force, checked against the time-domain force function at the same spin angles
        F = np.stack([ub.force_fe(model.fe.n, 0.0, w), ub.force_fe(model.fe.n, np.pi / 2, w)], axis=1)
        for t in np.linspace(0, T, 5):
            assert ub.force_fe(model.fe.n, w * t, w) == pytest.approx(F @ [np.cos(w * t), np.sin(w * t)], abs=1e-9)
        N = loop.N
        aug = np.zeros((N + 2, N + 2))
        aug[:N, :N] = loop.A0 + w * loop.A_terms["Phi"]
        aug[:N, N:] = Bu @ F
        aug[N:, N:] = [[0.0, -w], [w, 0.0]]
        P = sla.expm(T * aug)
        x_star = np.linalg.solve(np.eye(N) - P[:N, :N], P[:N, N])  # starts at cos = 1, sin = 0
        x_hat = resp.states([rpm])[0]
        amp = np.abs(x_hat[idx])
        for t in np.linspace(0, T, 8, endpoint=False):
            x_t = (sla.expm(t * aug) @ np.concatenate([x_star, [1.0, 0.0]]))[:N]
            expected = np.real(x_hat[idx] * np.exp(1j * w * t))
            assert np.max(np.abs(x_t[idx] - expected) / amp) <= 1e-4


def run_cli(capsys, *argv):
    code = cli.main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


def test_cli_json_schema_and_png(capsys, tmp_path):
    code, out, _ = run_cli(capsys, "unbalance", "--config", str(paper_config_path()), "--set",
                           f"disks.0.unbalance={U}", "--speed-rpm", "250", "500", "1000", "3000", "--json")  # fmt: skip
    assert code == 0
    data = json.loads(out)
    assert set(data) == {"schema_version", "speeds"} and data["schema_version"] == 1
    names = {"amb1_y", "amb1_z", "amb5_y", "amb5_z", "disk7_y", "disk7_z"}
    assert [s["speed_rpm"] for s in data["speeds"]] == [250, 500, 1000, 3000]
    for s in data["speeds"]:
        assert set(s) == {"speed_rpm", "amplitude_m", "phase_deg"}
        assert set(s["amplitude_m"]) == names and set(s["phase_deg"]) == names
        for node in ("amb1", "amb5", "disk7"):  # forward circular: z lags y by 90 degrees
            assert (s["phase_deg"][f"{node}_y"] - s["phase_deg"][f"{node}_z"]) % 360 == pytest.approx(90, abs=1e-6)
    png = tmp_path / "u" / "bode.png"
    code, out, _ = run_cli(capsys, "unbalance", "--speeds", "100:3000:200", "--out", str(png))
    assert code == 0 and png.read_bytes()[:4] == b"\x89PNG" and re.search(r"critical speeds \(rpm\): .*232\.7", out)


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["--config", str(paper_config_path())], "has no unbalance"),
        (["--set", "disks.2.unbalance=1e-4"], "index 2 out of range"),
        (["--set", "disks.0.balance_grade=-1"], "'disks[0].balance_grade' must be > 0"),
    ],
)
def test_cli_bad_input_one_line(capsys, tmp_path, args, needle):
    code, _, err = run_cli(capsys, "unbalance", *args, "--out", str(tmp_path / "x.png"))
    assert code == 2 and needle in err and len(err.strip().splitlines()) == 1
    assert not list(tmp_path.iterdir())
