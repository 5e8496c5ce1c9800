"""Config sections of the real-rig effects (issue 15): every one switchable, all OFF by default.

A config without these keys (config/seed_paper.yaml, the paper's idealised model) behaves exactly as before:
no unbalance, linear bearing force, ideal current source and sensor, no structural damping, no gravity, no
noise, no touchdown bearings, constant spin.  The sections live here so that config.py stays small; the
cross-field checks (``check_rig``) run after the per-field checks of config.py.  Units are SI unless the key
says otherwise (``_deg``, ``_hz``, ``_rpm``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from .config_fields import spec as _f
from .errors import ConfigError

AMB_AXES = 4  # amb<node>_y, amb<node>_z for the two AMBs, in that order


@dataclass(frozen=True)
class ActuatorConfig:
    """Power amplifier driving each AMB axis: a current loop, first order, with a voltage (slew-rate) limit."""

    bandwidth_hz: float | None = _f(
        "Hz", 0.0, open_lo=True, default=None, doc="current-loop bandwidth: i' = 2 pi f (i_cmd - i); null = ideal"
    )
    coil_inductance: float | None = _f("H", 0.0, open_lo=True, default=None, doc="L of one control axis")
    supply_voltage: float | None = _f(
        "V", 0.0, open_lo=True, default=None, doc="|di/dt| <= V/L (set with coil_inductance); null = no slew limit"
    )

    @property
    def slew_limit(self) -> float | None:
        """The largest |di/dt| (A/s), V/L; None without a voltage limit."""
        return None if self.coil_inductance is None else self.supply_voltage / self.coil_inductance


@dataclass(frozen=True)
class SensorConfig:
    """Displacement sensor at each AMB node: anti-alias low-pass, white noise, synchronous runout."""

    filter_hz: float | None = _f("Hz", 0.0, open_lo=True, default=None, doc="low-pass corner; null = ideal sensor")
    filter_order: int = _f("", 1, 2, default=2, doc="1: first order; 2: Butterworth (zeta = 1/sqrt 2)")
    noise_rms: float = _f("m", 0.0, default=0.0, doc="white noise per sample and axis (seeded: disturbances.seed)")
    runout: float = _f("m", 0.0, default=0.0, doc="0-peak once-per-revolution runout of the sensor target")
    runout_phase_deg: float = _f("deg", default=0.0, doc="runout = r (cos, sin)(phi + phase) on (y, z)")


@dataclass(frozen=True)
class StructuralDampingConfig:
    """Viscous damping of the shaft's bending, non-rotating (the circulatory term of rotating damping is not
    modelled).  rayleigh: D = alpha M + beta K_shaft; loss_factor: every flexural mode of the free-free shaft
    (M, K_shaft) gets damping ratio eta/2 (equivalent viscous at the mode's own frequency), rigid-body modes none.
    """

    model: str = _f(choices=("none", "rayleigh", "loss_factor"), default="none")
    alpha: float = _f("1/s", 0.0, default=0.0, doc="rayleigh: mass-proportional coefficient")
    beta: float = _f("s", 0.0, default=0.0, doc="rayleigh: stiffness-proportional coefficient (K_shaft only)")
    loss_factor: float = _f("", 0.0, 1.0, default=0.0, doc="loss_factor: eta, modal damping ratio eta/2")


@dataclass(frozen=True)
class GravityConfig:
    """Gravity g_B = R^T (0, -g, 0) in the base frame (Y up at rest), so that pitch and roll turn it."""

    enabled: bool = _f(default=False)
    g: float = _f("m/s^2", 0.0, default=9.81)


@dataclass(frozen=True)
class DisturbanceConfig:
    """Process noise: white forces, one sample per controller period, on (y, z) of the disk and AMB nodes."""

    force_noise_rms_disk: float = _f("N", 0.0, default=0.0, doc="per axis, at every disk node")
    force_noise_rms_bearing: float = _f("N", 0.0, default=0.0, doc="per axis, at every AMB node")
    seed: int = _f("", 0, 2**63 - 1, default=0, doc="seeds every noise of a run (force and sensor): bit-for-bit")


@dataclass(frozen=True)
class TouchdownConfig:
    """Backup (touchdown) bearings: radial contact with penalty stiffness, damping and Coulomb friction."""

    nodes: tuple[int, ...] = _f(
        "", default=(), doc="nodes with a backup bearing; empty = none (the run stops at the gap)"
    )
    clearance: float | None = _f("m", 0.0, open_lo=True, default=None, doc="radial clearance, < bearings.air_gap")
    stiffness: float | None = _f("N/m", 0.0, open_lo=True, default=None, doc="radial contact stiffness")
    damping: float = _f("N s/m", 0.0, default=0.0, doc="radial contact damping (the force never pulls)")
    friction: float = _f("", 0.0, 2.0, default=0.0, doc="Coulomb coefficient of the tangential force")


@dataclass(frozen=True)
class SpinConfig:
    """Spin profile: constant (spin_speed_rpm) or a ramp from start_rpm to end_rpm at rate_rpm_s, then held."""

    profile: str = _f(choices=("constant", "ramp"), default="constant")
    start_rpm: float = _f("rpm", default=0.0)
    end_rpm: float = _f("rpm", default=0.0)
    rate_rpm_s: float = _f("rpm/s", 0.0, default=0.0, doc="ramp: |d speed/dt| (> 0)")


def disk_mass(disk: Any, density: float) -> float:
    """Mass of a disk (kg) of the shaft's density, as fe.disk_props computes it."""
    return density * math.pi * (disk.diameter**2 - disk.bore**2) * disk.thickness / 4.0


def disk_unbalance(disk: Any, density: float, max_speed_rpm: float | None) -> tuple[float, float]:
    """(U kg m, phase rad) of one disk: ``unbalance``, or ISO 21940-11 ``balance_grade`` G (mm/s).

    From a grade, the permissible specific unbalance e = G / Omega_max (m) at the maximum service speed
    ``max_speed_rpm``, times the disk's own mass (the shaft's share of the rotor mass is not added).
    """
    phase = math.radians(disk.unbalance_phase_deg)
    if disk.balance_grade is not None:
        omega_max = max_speed_rpm * math.pi / 30.0
        return disk_mass(disk, density) * disk.balance_grade * 1e-3 / omega_max, phase
    return (disk.unbalance or 0.0), phase


def check_rig(cfg: Any, source: str) -> None:
    """Cross-field checks of the real-rig keys; raises ConfigError with one line naming the key."""
    n = cfg.n_nodes
    for i, disk in enumerate(cfg.disks):
        if disk.unbalance is not None and disk.balance_grade is not None:
            raise ConfigError(f"{source}: 'disks[{i}]': give unbalance or balance_grade, not both")
        if disk.balance_grade is not None and cfg.max_speed_rpm is None:
            raise ConfigError(f"{source}: 'disks[{i}].balance_grade' needs 'max_speed_rpm' (ISO 21940-11 e = G/Omega)")
    _check_bearings(cfg, source)
    act = cfg.actuator
    if (act.coil_inductance is None) != (act.supply_voltage is None):
        raise ConfigError(f"{source}: 'actuator.coil_inductance' and 'actuator.supply_voltage' go together")
    td = cfg.touchdown
    for node in td.nodes:
        if not 1 <= node <= n:
            raise ConfigError(f"{source}: 'touchdown.nodes': node {node} does not exist (nodes 1..{n})")
    if len(set(td.nodes)) != len(td.nodes):
        raise ConfigError(f"{source}: 'touchdown.nodes' must be distinct")
    if td.nodes and (td.clearance is None or td.stiffness is None):
        raise ConfigError(f"{source}: 'touchdown' with nodes needs clearance and stiffness")
    if td.clearance is not None and td.clearance >= cfg.bearings.air_gap:
        raise ConfigError(
            f"{source}: 'touchdown.clearance' ({td.clearance:g} m) must be smaller than "
            f"'bearings.air_gap' ({cfg.bearings.air_gap:g} m)"
        )
    sp = cfg.spin
    if sp.profile == "ramp" and (sp.rate_rpm_s <= 0 or sp.start_rpm == sp.end_rpm):
        raise ConfigError(f"{source}: 'spin' ramp needs rate_rpm_s > 0 and start_rpm != end_rpm")
    offset = cfg.controller.bias_current_offset
    if offset and len(offset) != AMB_AXES:
        raise ConfigError(
            f"{source}: 'controller.bias_current_offset' must list {AMB_AXES} currents (A) or none (got {len(offset)})"
        )


NONLINEAR_RATIO_RTOL = 1e-6


def _check_bearings(cfg: Any, source: str) -> None:
    b = cfg.bearings
    if b.force_law != "nonlinear":
        return
    if b.displacement_stiffness >= 0 or b.bias_current <= 0:
        raise ConfigError(
            f"{source}: 'bearings.force_law' nonlinear needs displacement_stiffness < 0, bias_current > 0"
        )
    g0 = b.bias_current * b.current_stiffness / -b.displacement_stiffness
    if abs(b.air_gap - g0) > NONLINEAR_RATIO_RTOL * g0:
        raise ConfigError(
            f"{source}: 'bearings.air_gap' must be bias_current*current_stiffness/|displacement_stiffness| = "
            f"{g0:.9g} m for the nonlinear law (got {b.air_gap:g})"
        )
