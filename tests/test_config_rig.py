"""Real-rig config keys (issue 15): all off by default, round trip through to_dict, cross-field checks."""

import math
import re

import pytest

from amb_dynamics import cli
from amb_dynamics.config import config_from_dict, load_config, to_dict
from amb_dynamics.config_rig import disk_unbalance
from amb_dynamics.errors import ConfigError

EVERYTHING_ON = [
    "disks.0.unbalance=2.0e-4",
    "disks.0.unbalance_phase_deg=30",
    "bearings.force_law=nonlinear",
    "bearings.bias_current=19.5603157",
    "bearings.saturation_flux_density=1.2",
    "actuator={bandwidth_hz: 1000, coil_inductance: 0.01, supply_voltage: 150}",
    "sensor={filter_hz: 2000, filter_order: 2, noise_rms: 1.0e-6, runout: 2.0e-6, runout_phase_deg: 10}",
    "structural_damping={model: loss_factor, loss_factor: 0.01}",
    "gravity={enabled: true}",
    "disturbances={force_noise_rms_disk: 1.0, force_noise_rms_bearing: 0.5, seed: 7}",
    "touchdown={nodes: [1, 5], clearance: 1.0e-3, stiffness: 5.0e7, damping: 1000, friction: 0.1}",
    "spin={profile: ramp, start_rpm: 0, end_rpm: 3000, rate_rpm_s: 100}",
    "controller.bias_current_offset=[0, 1, 0, 9]",
]


def test_paper_config_has_every_effect_off(repo):
    cfg = load_config(repo / "config" / "seed_paper.yaml")
    assert cfg.disks[0].unbalance is None and cfg.disks[0].balance_grade is None
    assert cfg.bearings.force_law == "linear" and cfg.bearings.saturation_flux_density is None
    assert cfg.actuator.bandwidth_hz is None and cfg.actuator.supply_voltage is None
    assert cfg.sensor.filter_hz is None and cfg.sensor.noise_rms == 0.0 and cfg.sensor.runout == 0.0
    assert cfg.structural_damping.model == "none" and not cfg.gravity.enabled
    assert cfg.disturbances.force_noise_rms_disk == 0.0 and cfg.disturbances.force_noise_rms_bearing == 0.0
    assert cfg.touchdown.nodes == () and cfg.spin.profile == "constant"
    assert cfg.controller.bias_current_offset == ()


def test_everything_on_round_trips(repo):
    cfg = load_config(repo / "config" / "seed_paper.yaml", EVERYTHING_ON)
    assert cfg.touchdown.nodes == (1, 5) and cfg.actuator.coil_inductance == 0.01
    assert cfg.controller.bias_current_offset == (0.0, 1.0, 0.0, 9.0)
    again = config_from_dict(to_dict(cfg), cfg.source)
    assert again == cfg


def test_balance_grade_gives_iso_unbalance(repo):
    cfg = load_config(repo / "config" / "seed_paper.yaml", ["disks.0.balance_grade=2.5", "max_speed_rpm=3000"])
    U, phase = disk_unbalance(cfg.disks[0], cfg.shaft.density, cfg.max_speed_rpm)
    mass = 7810.0 * math.pi * 0.25 * 0.07 / 4  # 107.3 kg solid steel disk
    assert U == pytest.approx(mass * 2.5e-3 / (3000 * math.pi / 30), rel=1e-12)  # e = G/Omega
    assert phase == 0.0


@pytest.mark.parametrize(
    ("override", "message"),
    [
        (["touchdown={nodes: [5], clearance: 2.5e-3, stiffness: 1e7}"], "'touchdown.clearance' (0.0025 m) must be"),
        (["touchdown={nodes: [9], clearance: 1e-3, stiffness: 1e7}"], "'touchdown.nodes': node 9 does not exist"),
        (["touchdown={nodes: [5]}"], "'touchdown' with nodes needs clearance and stiffness"),
        (["disks.1.unbalance=1e-4"], "disks.1: index 1 out of range"),
        (["actuator.bandwidth_hz=-100"], "'actuator.bandwidth_hz' must be > 0 Hz"),
        (["sensor.filter_hz=-1"], "'sensor.filter_hz' must be > 0 Hz"),
        (["sensor.filter_order=3"], "'sensor.filter_order' must be <= 2"),
        (["disks.0.unbalance=-1e-4"], "'disks[0].unbalance' must be >= 0 kg m"),
        (["disks.0.unbalance=1e-4", "disks.0.balance_grade=2.5"], "unbalance or balance_grade, not both"),
        (["disks.0.balance_grade=2.5"], "needs 'max_speed_rpm'"),
        (["bearings.force_law=nonlinear"], "'bearings.air_gap' must be bias_current*current_stiffness"),
        (["actuator.coil_inductance=0.01"], "go together"),
        (["spin.profile=ramp"], "ramp needs rate_rpm_s > 0"),
        (["controller.bias_current_offset=[1, 2]"], "must list 4 currents"),
        (["structural_damping.model=hysteretic"], "must be one of none, rayleigh, loss_factor"),
        (["gravity.enabled=1"], "'gravity.enabled' must be true or false"),
    ],
)
def test_bad_rig_keys_one_line(repo, override, message):
    with pytest.raises(ConfigError, match=re.escape(message)) as e:
        load_config(repo / "config" / "seed_paper.yaml", override)
    assert "\n" not in str(e.value)


@pytest.mark.parametrize(
    "setting",
    ["touchdown={nodes: [5], clearance: 3e-3, stiffness: 1e7}", "actuator.bandwidth_hz=-1", "disks.3.unbalance=1"],
)
def test_cli_rejects_bad_rig_key_with_exit_2(repo, capsys, setting):
    code = cli.main(["modes", "--config", str(repo / "config" / "seed_paper.yaml"), "--set", setting])
    err = capsys.readouterr().err
    assert code == 2
    assert len(err.strip().splitlines()) == 1 and "error" in err
