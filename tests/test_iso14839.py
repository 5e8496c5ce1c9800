"""ISO 14839 zones (sensitivity peak, shaft vibration vs C_min) and `amb-dynamics sensitivity` end to end."""

import json
import subprocess

import numpy as np
import pytest

from amb_dynamics import cli
from amb_dynamics.config import load_config
from amb_dynamics.errors import ConfigError, InputError
from amb_dynamics.iso14839 import sensitivity_zone, vibration_zones, zone_of
from amb_dynamics.sensitivity import StateSpace, find_peaks, sensitivity_matrix

PAPER = "config/seed_paper.yaml"


def analytic_peak_loop(peak):
    """Mass 1 kg under PD: S = s^2/(s^2 + 2 zeta wn s + wn^2), max|S| = 1/(2 zeta sqrt(1 - zeta^2)) = peak."""
    zeta = np.sqrt((1 - np.sqrt(1 - 1 / peak**2)) / 2)
    wn = 2 * np.pi * 20
    plant = StateSpace(np.array([[0.0, 1.0], [0.0, 0.0]]), np.array([[0.0], [1.0]]), np.eye(2)[:1], np.zeros((1, 1)))
    ctrl = StateSpace(
        np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), -np.array([[wn**2]]), None, -np.array([[2 * zeta * wn]])
    )
    return plant, ctrl


@pytest.mark.parametrize(("peak", "zone"), [(2.0, "A"), (3.5, "B"), (4.5, "C"), (8.0, "D")])
def test_sensitivity_zone_of_loops_in_each_zone(peak, zone):
    """Loops whose analytic peak |S| lies in each zone of the default limits 3, 4, 5 (9.5, 12, 14 dB)."""
    limits = load_config(PAPER).iso14839.sensitivity_zone_limits
    assert tuple(limits) == (3.0, 4.0, 5.0)
    plant, ctrl = analytic_peak_loop(peak)
    w = 2 * np.pi * np.geomspace(1, 200, 50)
    (p,) = find_peaks(plant, ctrl, w, sensitivity_matrix(plant, ctrl, w), (w[0], w[-1]))
    assert p.abs == pytest.approx(peak, rel=1e-6)
    assert sensitivity_zone(p.abs, limits) == zone
    assert 20 * np.log10(limits[0]) == pytest.approx(9.54, abs=0.01)  # the "9.5, 12, 14 dB" of the literature
    assert 20 * np.log10(limits[2]) == pytest.approx(13.98, abs=0.01)


def test_zone_boundaries_belong_to_the_zone_below():
    assert [zone_of(x, (3, 4, 5)) for x in (3.0, 3.0000001, 4.0, 5.0, 5.0001)] == ["A", "B", "B", "C", "D"]
    with pytest.raises(InputError):
        zone_of(1.0, (3, 3, 5))


@pytest.mark.parametrize(("amp", "zone"), [(0.1e-3, "A"), (0.35e-3, "B"), (0.45e-3, "C"), (0.6e-3, "D")])
def test_vibration_zone_each_zone(amp, zone):
    """A 0-peak orbit of amplitude amp around the centre, C_min = 1 mm, limits 0.3/0.4/0.5 C_min."""
    t = np.linspace(0, 1, 1001)
    y = {"amb1_y": amp * np.sin(2 * np.pi * 7 * t), "amb1_z": amp * np.cos(2 * np.pi * 7 * t)}
    z = vibration_zones(y, 1e-3, (0.3, 0.4, 0.5), "zero_peak")
    assert z["amb1_y"].zone == zone and z["amb1_z"].zone == zone
    assert z["amb1_z"].ratio == pytest.approx(amp / 1e-3, rel=1e-12)
    pp = vibration_zones(y, 1e-3, (0.3, 0.4, 0.5), "peak_to_peak")["amb1_z"]
    assert pp.displacement_m == pytest.approx(2 * amp, rel=1e-12)


def test_vibration_zone_without_clearance_says_why():
    z = vibration_zones({"amb1_y": np.array([1e-4, -2e-4])}, None, (0.3, 0.4, 0.5))["amb1_y"]
    assert z.zone is None and "touchdown_clearance" in z.reason and z.displacement_m == 2e-4


def test_iso_config_keys_validated():
    cfg = load_config(PAPER, ["iso14839.touchdown_clearance=0.25e-3", "iso14839.vibration_measure=peak_to_peak"])
    assert cfg.iso14839.touchdown_clearance == 0.25e-3
    with pytest.raises(ConfigError, match=r"iso14839\.vibration_zone_limits"):
        load_config(PAPER, ["iso14839.vibration_zone_limits=[0.5,0.4,0.3]"])
    with pytest.raises(ConfigError, match=r"iso14839\.touchdown_clearance"):
        load_config(PAPER, ["iso14839.touchdown_clearance=-1"])


def test_cli_sensitivity_json_and_png(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    from pathlib import Path

    cfg = str(Path(__file__).parents[1] / PAPER)
    rc = cli.main(
        ["sensitivity", "--config", cfg, "--speed-rpm", "0", "1000", "--points", "500", "--json", "--out", "S.png"]
    )
    assert rc == 0
    data = json.loads(capsys.readouterr().out)
    assert data["schema_version"] == 1 and [s["speed_rpm"] for s in data["speeds"]] == [0.0, 1000.0]
    for s in data["speeds"]:
        assert set(s["axes"]) == {"amb1_y", "amb1_z", "amb5_y", "amb5_z"}
        f = np.array(s["frequency_hz"])
        for name, a in s["axes"].items():
            mags = np.array(s["abs"][name])
            assert mags.shape == f.shape and mags.max() == pytest.approx(a["peak_abs"], rel=1e-9)
            assert a["peak_db"] == pytest.approx(20 * np.log10(a["peak_abs"]), rel=1e-12)
            assert a["zone"] == "D"  # first mode, damping ratio ~1e-3
    assert (tmp_path / "S.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["--band", "50:5"], "--band"),
        (["--band", "x"], "--band"),
        (["--axis", "amb3_y"], "amb3_y"),
        (["--controller", "sampled", "--band", "1:2600"], "Nyquist"),
        (["--set", "iso14839.sensitivity_zone_limits=[5,4,3]"], "sensitivity_zone_limits"),
    ],
)
def test_cli_sensitivity_bad_input_one_line(args, needle, capsys):
    assert cli.main(["sensitivity", *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and needle in err[0]


def test_cli_sensitivity_entry_point_exit_2(venv_bin, tmp_path):
    proc = subprocess.run(
        [str(venv_bin / "amb-dynamics"), "sensitivity", "--band", "5:5"], capture_output=True, text=True, cwd=tmp_path
    )
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1 and "empty" in proc.stderr
