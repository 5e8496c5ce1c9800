"""Rotor configuration: YAML -> frozen, validated dataclasses, with dotted overrides.

Every field carries its unit and allowed range in its metadata; unknown keys are an error that names the
key and the file.  ``load_config(path, overrides=["controller.rate_hz=5000"])`` is the one entry point.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import re
import types
import typing
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import yaml

from .config_control import FilterConfig, StateSpaceConfig, check_control
from .config_fields import spec as _f
from .config_layers import read_layered
from .config_rig import (
    ActuatorConfig,
    DisturbanceConfig,
    GravityConfig,
    SensorConfig,
    SpinConfig,
    StructuralDampingConfig,
    TouchdownConfig,
    check_rig,
)
from .errors import ConfigError

SEED_CONFIG_NAME = "seed_rotor.yaml"
PAPER_CONFIG_NAME = "seed_paper.yaml"  # the paper's idealised model (every paper comparison)
_FLOAT_RE = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?")


@dataclass(frozen=True)
class ShaftConfig:
    length: float = _f("m", 0.0, open_lo=True)
    diameter: float = _f("m", 0.0, open_lo=True)
    elements: int = _f("", 1, 400)
    youngs_modulus: float = _f("Pa", 0.0, open_lo=True)
    density: float = _f("kg/m^3", 0.0, open_lo=True)
    shear_modulus: float = _f("Pa", 0.0, open_lo=True, default=81.2e9)
    model: str = _f(choices=("euler_bernoulli", "timoshenko"), default="euler_bernoulli")
    rotary_inertia: bool = _f(default=True, doc="Rayleigh beam (rotary inertia and gyroscopics)")


@dataclass(frozen=True)
class DiskConfig:
    node: int = _f("", 1)
    diameter: float = _f("m", 0.0, open_lo=True)
    thickness: float = _f("m", 0.0, open_lo=True)
    bore: float = _f("m", 0.0, default=0.0, doc="inner diameter of an annular disk")
    unbalance: float | None = _f("kg m", 0.0, default=None, doc="m_u e at the disk node; null = none")
    unbalance_phase_deg: float = _f("deg", default=0.0, doc="angle of the heavy spot from +Y toward +Z at phi = 0")
    balance_grade: float | None = _f(
        "mm/s", 0.0, open_lo=True, default=None, doc="ISO 21940-11 G: U = m_disk G/Omega(max_speed_rpm)"
    )


@dataclass(frozen=True)
class BearingConfig:
    nodes: tuple[int, ...] = _f("", 1)
    current_stiffness: float = _f("N/A", 0.0, open_lo=True)
    displacement_stiffness: float = _f("N/m")
    bias_current: float = _f("A", 0.0, default=5.0)
    air_gap: float = _f("m", 0.0, open_lo=True, default=2.5e-3)
    pole_area: float = _f("m^2", 0.0, default=5.0e-4)
    force_law: str = _f(
        choices=("linear", "nonlinear"), default="linear", doc="nonlinear: differential law about (i0, g0)"
    )
    pole_angle_deg: float = _f("deg", 0.0, 89.0, default=22.5, doc="half-angle between a magnet's two poles")
    saturation_flux_density: float | None = _f(
        "T", 0.0, open_lo=True, default=None, doc="nonlinear: magnet force <= cos(alpha) A_p B_sat^2/mu0; null = off"
    )


@dataclass(frozen=True)
class ControllerConfig:
    rate_hz: float = _f("Hz", 1.0, 1.0e6)
    proportional_gain: float = _f("A/m", 0.0)
    derivative_gain: float = _f("A s/m", 0.0)
    integral_gain: float = _f("A/(m s)", 0.0, default=0.0)
    derivative_filter_hz: float | None = _f("Hz", 0.0, open_lo=True, default=None)
    current_limit: float = _f("A", 0.0, open_lo=True, default=10.0)
    delay_samples: int = _f("", 0, 1, default=0)
    bias_current_offset: tuple[float, ...] = _f(
        "A", default=(), doc="static control current per AMB axis (amb1_y, amb1_z, amb5_y, amb5_z); empty = none"
    )
    filters: tuple[FilterConfig, ...] = _f(default=(), doc="notch / lead-lag filters in series after the PID")
    state_space: StateSpaceConfig | None = _f(default=None, doc="the user's controller instead of the PID")  # noqa: RUF009


@dataclass(frozen=True)
class HarmonicConfig:
    axis: str = _f(choices=("roll", "pitch", "yaw"))
    amplitude: float = _f("rad", 0.0, 1.5)
    frequency: float = _f("rad/s", 0.0)
    phase: float = _f("rad", default=0.0)


@dataclass(frozen=True)
class BaseMotionConfig:
    kind: str = _f(choices=("none", "roll", "pitch", "yaw", "combined"), default="none")
    amplitude: float = _f("rad", 0.0, 1.5, default=0.0)
    frequency: float = _f("rad/s", 0.0, default=0.0)
    harmonics: tuple[HarmonicConfig, ...] = _f(default=(), doc="kind: combined only")


@dataclass(frozen=True)
class ISO14839Config:
    """ISO 14839 zone boundaries [A/B, B/C, C/D] (docs/commissioning.md: sources and what is confirmed)."""

    sensitivity_zone_limits: tuple[float, ...] = _f("", 1.0, default=(3.0, 4.0, 5.0), doc="peak |S| (absolute)")
    vibration_zone_limits: tuple[float, ...] = _f("", 0.0, open_lo=True, default=(0.3, 0.4, 0.5), doc="x C_min")
    vibration_measure: str = _f(choices=("zero_peak", "peak_to_peak"), default="zero_peak")
    touchdown_clearance: float | None = _f("m", 0.0, open_lo=True, default=None, doc="C_min; null: no zone")


@dataclass(frozen=True)
class RotorConfig:
    shaft: ShaftConfig
    disks: tuple[DiskConfig, ...]
    bearings: BearingConfig
    controller: ControllerConfig
    spin_speed_rpm: float = _f("rpm", default=1000.0)
    formulation: str = _f(choices=("derived", "seed"), default="derived")
    drive_model: str = _f(choices=("body_axis", "cardan"), default="body_axis")
    seed_disk_H: str = _f(choices=("literal", "consistent"), default="literal")
    axial_stiffening: bool = _f(default=False)
    base_forcing: bool = _f(default=False, doc="load of the base rotation (docs/physics.md#forcing), time runs")
    modal_cutoff: float | None = _f("rad/s", 0.0, open_lo=True, default=None)
    base_motion: BaseMotionConfig = field(default_factory=BaseMotionConfig)
    max_speed_rpm: float | None = _f("rpm", 0.0, open_lo=True, default=None, doc="maximum service speed")
    actuator: ActuatorConfig = field(default_factory=ActuatorConfig)
    sensor: SensorConfig = field(default_factory=SensorConfig)
    structural_damping: StructuralDampingConfig = field(default_factory=StructuralDampingConfig)
    gravity: GravityConfig = field(default_factory=GravityConfig)
    disturbances: DisturbanceConfig = field(default_factory=DisturbanceConfig)
    touchdown: TouchdownConfig = field(default_factory=TouchdownConfig)
    spin: SpinConfig = field(default_factory=SpinConfig)
    iso14839: ISO14839Config = field(default_factory=ISO14839Config)
    source: str = field(default="<memory>", compare=False, metadata={"internal": True})

    @property
    def n_nodes(self) -> int:
        return self.shaft.elements + 1

    @property
    def spin_rad_s(self) -> float:
        """Spin relative to the base, phi_dot (rad/s)."""
        return self.spin_speed_rpm * math.pi / 30.0


def seed_config_path() -> Path:
    """Path of the packaged default, the real rig (a link to config/seed_rotor.yaml in the repository)."""
    return Path(str(resources.files("amb_dynamics") / "data" / SEED_CONFIG_NAME))


def paper_config_path() -> Path:
    """Path of the packaged paper rotor (a link to config/seed_paper.yaml): the idealised model of the paper."""
    return Path(str(resources.files("amb_dynamics") / "data" / PAPER_CONFIG_NAME))


def load_config(path: str | Path | None = None, overrides: list[str] | tuple[str, ...] = ()) -> RotorConfig:
    """Read, override and validate a rotor file; raises ConfigError with one clear line."""
    path = Path(path) if path is not None else seed_config_path()
    data = read_layered(path)  # with its chain of ``base:`` files merged (config_layers)
    if not overrides:
        return config_from_dict(data, str(path))
    config_from_dict(copy.deepcopy(data), str(path))  # the file alone: its errors are the file's
    for i, item in enumerate(overrides):  # the first override after which the config is invalid takes the blame
        apply_override(data, item, str(path))
        try:
            cfg = config_from_dict(copy.deepcopy(data), str(path))
        except ConfigError as exc:
            if i == len(overrides) - 1 or _invalid_after_all(data, overrides[i + 1 :], path):
                raise ConfigError(f"--set {item} (on {path}): {_strip_source(exc, path)}") from None
            continue
    return cfg


def _invalid_after_all(data: dict, rest: list[str] | tuple[str, ...], path: Path) -> bool:
    """True when the remaining overrides do not repair what an earlier one broke."""
    trial = copy.deepcopy(data)
    for item in rest:
        apply_override(trial, item, str(path))
    try:
        config_from_dict(trial, str(path))
    except ConfigError:
        return True
    return False


def _strip_source(exc: ConfigError, path: Path) -> str:
    text = str(exc)
    prefix = f"{path}: "
    return text[len(prefix) :] if text.startswith(prefix) else text


def config_from_dict(data: dict, source: str = "<memory>") -> RotorConfig:
    cfg = _build(RotorConfig, data, "", source)
    cfg = dataclasses.replace(cfg, source=source)
    _check_topology(cfg, source)
    return cfg


def apply_override(data: dict, item: str, source: str = "<override>") -> None:
    """Apply ``a.b.c=value`` (value parsed as YAML) to a nested dict in place."""
    key, sep, raw = item.partition("=")
    if not sep or not key.strip():
        raise ConfigError(f"--set {item!r}: expected key=value, e.g. controller.rate_hz=5000")
    try:
        value = yaml.safe_load(raw) if raw.strip() else None
    except yaml.YAMLError:
        raise ConfigError(f"--set {item!r}: value is not valid YAML") from None
    parts = key.strip().split(".")
    node: Any = data
    for i, part in enumerate(parts[:-1]):
        if isinstance(node, list):
            node = _list_item(node, part, parts[: i + 1], source)
            continue
        if part not in node or node[part] is None:
            node[part] = {}
        node = node[part]
        if not isinstance(node, dict | list):
            raise ConfigError(f"--set {key}: {'.'.join(parts[: i + 1])} is not a mapping")
    last = parts[-1]
    if isinstance(node, list):
        idx = _index(last, parts, source)
        if idx >= len(node):
            raise ConfigError(f"--set {key}: index {idx} out of range")
        node[idx] = value
    else:
        node[last] = value


def _index(part: str, parts: list[str], source: str) -> int:
    if not part.isdigit():
        raise ConfigError(f"{source}: --set {'.'.join(parts)}: '{part}' must be a list index")
    return int(part)


def _list_item(node: list, part: str, parts: list[str], source: str) -> Any:
    idx = _index(part, parts, source)
    if idx >= len(node):
        raise ConfigError(f"{source}: --set {'.'.join(parts)}: index {idx} out of range")
    return node[idx]


def to_dict(cfg: Any) -> Any:
    """Plain-data view (for JSON output and parameter defaults)."""
    if dataclasses.is_dataclass(cfg):
        return {
            f.name: to_dict(getattr(cfg, f.name)) for f in dataclasses.fields(cfg) if not f.metadata.get("internal")
        }
    if isinstance(cfg, tuple | list):
        return [to_dict(v) for v in cfg]
    return cfg


def _build(cls: type, data: Any, prefix: str, source: str):
    if not isinstance(data, dict):
        raise ConfigError(f"{source}: {prefix.rstrip('.') or 'top level'} must be a mapping")
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls) if not f.metadata.get("internal")}
    unknown = sorted(set(data) - set(fields))
    if unknown:
        raise ConfigError(f"{source}: unknown key '{prefix}{unknown[0]}' (allowed: {', '.join(sorted(fields))})")
    kwargs = {}
    for name, f in fields.items():
        key = prefix + name
        if name not in data:
            if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
                raise ConfigError(f"{source}: missing key '{key}'")
            continue
        kwargs[name] = _convert(hints[name], data[name], f.metadata, key, source)
    return cls(**kwargs)


def _convert(tp: Any, value: Any, meta: dict, key: str, source: str):
    origin = typing.get_origin(tp)
    if origin in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        if value is None:
            return None
        tp, origin = args[0], typing.get_origin(args[0])
    if dataclasses.is_dataclass(tp):
        return _build(tp, value, key + ".", source)
    if origin is tuple:
        item_tp = typing.get_args(tp)[0]
        if not isinstance(value, list | tuple):
            raise ConfigError(f"{source}: '{key}' must be a list")
        items = [_convert(item_tp, v, meta, f"{key}[{i}]", source) for i, v in enumerate(value)]
        if meta.get("lo") is not None and item_tp is int and not items:
            raise ConfigError(f"{source}: '{key}' must not be empty")
        return tuple(items)
    if tp is bool:
        if not isinstance(value, bool):
            raise ConfigError(f"{source}: '{key}' must be true or false (got {value!r})")
        return value
    if tp is str:
        if not isinstance(value, str):
            raise ConfigError(f"{source}: '{key}' must be a string (got {value!r})")
        choices = meta.get("choices")
        if choices and value not in choices:
            raise ConfigError(f"{source}: '{key}' must be one of {', '.join(choices)} (got {value!r})")
        return value
    if tp in (int, float):
        if isinstance(value, str) and _FLOAT_RE.fullmatch(value.strip()):
            value = float(value)  # PyYAML (YAML 1.1) reads 211.0e9 as a string
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ConfigError(f"{source}: '{key}' must be a number (got {value!r})")
        if tp is int and (not isinstance(value, int) and not float(value).is_integer()):
            raise ConfigError(f"{source}: '{key}' must be an integer (got {value!r})")
        value = tp(value)
        if not math.isfinite(value):
            raise ConfigError(f"{source}: '{key}' must be finite (got {value!r})")
        _check_range(value, meta, key, source)
        return value
    raise ConfigError(f"{source}: '{key}': unsupported type {tp}")  # pragma: no cover


def _check_range(value: float, meta: dict, key: str, source: str) -> None:
    lo, hi, unit = meta.get("lo"), meta.get("hi"), meta.get("unit", "")
    unit = f" {unit}" if unit else ""
    if lo is not None and (value < lo or (meta.get("open_lo") and value <= lo)):
        op = ">" if meta.get("open_lo") else ">="
        raise ConfigError(f"{source}: '{key}' must be {op} {lo:g}{unit} (got {value:g})")
    if hi is not None and value > hi:
        raise ConfigError(f"{source}: '{key}' must be <= {hi:g}{unit} (got {value:g})")


def _check_topology(cfg: RotorConfig, source: str) -> None:
    n = cfg.n_nodes
    for i, disk in enumerate(cfg.disks):
        if disk.node > n:
            raise ConfigError(f"{source}: 'disks[{i}].node' = {disk.node} does not exist (the shaft has nodes 1..{n})")
        if disk.bore >= disk.diameter:
            raise ConfigError(f"{source}: 'disks[{i}].bore' must be smaller than its diameter")
    nodes = cfg.bearings.nodes
    if len(nodes) != 2:
        raise ConfigError(f"{source}: 'bearings.nodes' must list exactly 2 AMB nodes (got {len(nodes)})")
    for node in nodes:
        if node > n:
            raise ConfigError(f"{source}: bearing node {node} does not exist (nodes 1..{n})")
    if len(set(nodes)) != len(nodes):
        raise ConfigError(f"{source}: 'bearings.nodes' must be distinct")
    for key in ("sensitivity_zone_limits", "vibration_zone_limits"):
        lim = getattr(cfg.iso14839, key)
        if len(lim) != 3 or any(lim[i + 1] <= lim[i] for i in range(len(lim) - 1)):
            raise ConfigError(f"{source}: 'iso14839.{key}' must be three ascending numbers [A/B, B/C, C/D]")
    bm = cfg.base_motion
    if bm.kind == "combined" and not bm.harmonics:
        raise ConfigError(f"{source}: 'base_motion.harmonics' must list at least one harmonic for kind combined")
    if bm.kind in ("roll", "pitch", "yaw") and bm.amplitude > 0 and bm.frequency <= 0:
        raise ConfigError(f"{source}: 'base_motion.frequency' must be > 0 rad/s for a moving base")
    check_rig(cfg, source)
    check_control(cfg, source)
