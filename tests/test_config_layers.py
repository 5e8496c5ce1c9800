"""A rotor file on a base (``base: OTHER.yaml``): merged as documented, every mistake one line naming the file."""

import subprocess

import pytest

from amb_dynamics.config import load_config
from amb_dynamics.config import seed_config_path as rig_config_path
from amb_dynamics.errors import ConfigError


@pytest.fixture
def rig_path():
    """The real-rig default (config/seed_rotor.yaml, packaged): it has every section a variant may change."""
    return rig_config_path()


def _write(path, text):
    path.write_text(text)
    return path


def test_a_variant_equals_its_base_with_the_same_values_set(tmp_path, rig_path):
    variant = _write(
        tmp_path / "v.yaml",
        f"base: {rig_path}\n"
        "controller:\n  rate_hz: 2000.0\n  filters: [{kind: notch, frequency_hz: 300.0, bandwidth_hz: 50.0}]\n"
        "sensor: {noise_rms: 1.0e-6}\n",
    )
    sets = [
        "controller.rate_hz=2000",
        "controller.filters=[{kind: notch, frequency_hz: 300.0, bandwidth_hz: 50.0}]",
        "sensor.noise_rms=1e-6",
    ]
    got, want = load_config(variant), load_config(rig_path, sets)
    assert got == want  # every field (source is not compared)
    base = load_config(rig_path)
    # a mapping merges key by key: the sensor's other keys and the controller's gains stay the base's
    assert got.sensor.filter_hz == base.sensor.filter_hz == 5000.0
    assert got.controller.proportional_gain == base.controller.proportional_gain
    assert got.source == str(variant)


def test_a_list_replaces_and_a_chain_of_bases_resolves_relative_paths(tmp_path, rig_path):
    (tmp_path / "sub").mkdir()
    _write(tmp_path / "sub" / "a.yaml", f"base: {rig_path}\ndisks: [{{node: 3, diameter: 0.2, thickness: 0.02}}]\n")
    b = _write(tmp_path / "b.yaml", "base: sub/a.yaml\nspin_speed_rpm: 1500.0\n")
    cfg = load_config(b)
    assert [d.node for d in cfg.disks] == [3] and cfg.disks[0].balance_grade is None  # replaced, not merged
    assert cfg.spin_speed_rpm == 1500.0 and cfg.shaft.length == 1.5


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("base: missing.yaml\n", "missing.yaml: cannot read config"),
        ("base: [a.yaml]\n", "'base' must name a rotor file"),
        ("base: self.yaml\n", "leads back to"),
        ("base: {seed}\ncontroler: {{rate_hz: 1.0}}\n", "unknown key 'controler'"),
        ("base: {seed}\ncontroller: {{rate_hz: -1.0}}\n", "'controller.rate_hz' must be >= 1 Hz"),
    ],
)
def test_bad_bases_are_one_line(tmp_path, rig_path, text, message):
    path = _write(tmp_path / "self.yaml", text.format(seed=rig_path))
    with pytest.raises(ConfigError, match=message) as err:
        load_config(path)
    assert "\n" not in str(err.value)


def test_a_cycle_of_two_files_is_refused(tmp_path):
    _write(tmp_path / "a.yaml", "base: b.yaml\n")
    _write(tmp_path / "b.yaml", "base: a.yaml\n")
    with pytest.raises(ConfigError, match="leads back to"):
        load_config(tmp_path / "a.yaml")


def test_cli_reads_a_variant(venv_bin, tmp_path, rig_path):
    variant = _write(tmp_path / "v.yaml", f"base: {rig_path}\ncontroller: {{rate_hz: 12345.0}}\n")
    out = subprocess.run(
        [str(venv_bin / "amb-dynamics"), "modes", "--config", str(variant), "--max-frequency", "1"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.returncode == 0, out.stderr
    assert "digital loop 12345 Hz" in out.stdout
