"""Config loading: validation, unknown keys, overrides; bad config exits with one clear line on every CLI."""

import subprocess

import pytest

from amb_dynamics.config import load_config, to_dict
from amb_dynamics.errors import ConfigError


def test_seed_config_values(seed_config_path):
    cfg = load_config(seed_config_path)
    assert cfg.shaft.length == 1.5 and cfg.shaft.elements == 6
    assert cfg.bearings.nodes == (1, 5) and cfg.disks[0].node == 7
    assert cfg.spin_rad_s == pytest.approx(1000 * 2 * 3.141592653589793 / 60, rel=1e-15)
    assert to_dict(cfg)["controller"]["proportional_gain"] == 15648.2525


def test_override_nested_and_list(seed_config_path):
    cfg = load_config(seed_config_path, ["controller.rate_hz=10000", "disks.0.thickness=0.05", "modal_cutoff=null"])
    assert cfg.controller.rate_hz == 10000.0
    assert cfg.disks[0].thickness == 0.05
    assert cfg.modal_cutoff is None


@pytest.mark.parametrize(
    ("override", "message"),
    [
        ("shaft.lenght=1.0", "unknown key 'shaft.lenght'"),
        ("shaft.length=-1.5", "'shaft.length' must be > 0 m"),
        ("disks.0.node=9", "'disks[0].node' = 9 does not exist"),
        ("shaft.diameter=abc", "'shaft.diameter' must be a number"),
        ("controller.rate_hz=.nan", "must be finite"),
        ("formulation=papers", "'formulation' must be one of derived, seed"),
        ("bearings.nodes=[1, 9]", "bearing node 9 does not exist"),
        ("shaft.elements=2.5", "must be an integer"),
        ("nonsense", "expected key=value"),
    ],
)
def test_bad_config_rejected(seed_config_path, override, message):
    with pytest.raises(ConfigError, match=message.replace("[", r"\[").replace("]", r"\]")) as exc:
        load_config(seed_config_path, [override])
    assert "\n" not in str(exc.value)


def test_bad_yaml_and_missing_file(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("shaft: {length: 1.5\n")
    with pytest.raises(ConfigError, match=r"bad.yaml.*not valid YAML"):
        load_config(bad)
    with pytest.raises(ConfigError, match="cannot read config"):
        load_config(tmp_path / "missing.yaml")
    top = tmp_path / "list.yaml"
    top.write_text("- 1\n- 2\n")
    with pytest.raises(ConfigError, match="top level must be a mapping"):
        load_config(top)


@pytest.mark.parametrize(
    "args",
    [
        ["modes", "--set", "shaft.length=-1"],
        ["modes", "--set", "bogus.key=1"],
        ["campbell", "--set", "disks.0.node=12", "--out", "x.png"],
        ["floquet", "--motion", "pitch", "--amplitude", "0.3", "--frequency", "24.5", "--set", "shaft.diameter=abc"],
        ["chart", "--motion", "pitch", "--amplitude", "0:0.5:3", "--frequency", "1:40:3", "--set", "spin_speed_rpm=x"],
        ["simulate", "--motion", "pitch", "--amplitude", "0.3", "--frequency", "24.5", "--set", "shaft.elements=0"],
    ],
)
def test_cli_bad_config_one_line(venv_bin, tmp_path, args):
    proc = subprocess.run(
        [str(venv_bin / "amb-dynamics"), *args], capture_output=True, text=True, cwd=tmp_path, timeout=60
    )
    assert proc.returncode != 0
    assert "Traceback" not in proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, proc.stderr
    assert "error" in lines[0]
    assert not list(tmp_path.iterdir()), "nothing may be written on bad input"
