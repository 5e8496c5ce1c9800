"""Node parameters: declared up front with description and range, defaults from the rotor config.

Every node has ``config_file`` (a rotor YAML, '' = the seed rotor) and ``set`` (dotted overrides, as ``--set``
on the CLIs).  Parameters that mirror a config key (``ParamSpec.config_key``) take their default from the
loaded config and are written back into it, so that ``-p rate_hz:=1000`` and ``-p set:=[controller.rate_hz=1000]``
mean the same and the core sees one validated config.  Out-of-range values, unknown choices and undeclared
parameter overrides raise :class:`ParamError` with one line; the node exits with it.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from typing import Any

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.parameter import Parameter

from amb_dynamics.config import RotorConfig, load_config
from amb_dynamics.errors import AmbError

INT_MAX = 2**62


class ParamError(AmbError):
    """A node parameter that cannot be used."""


@dataclass(frozen=True)
class ParamSpec:
    """One declared parameter; ``default`` None means: take it from ``config_key`` of the rotor config."""

    name: str
    default: Any
    description: str
    unit: str = ""
    lo: float | None = None
    hi: float | None = None
    choices: tuple[str, ...] | None = None
    config_key: str | None = None
    none_value: Any = None  # parameter value that stands for a null config value
    runtime: bool = False  # may change while the node runs (amb_ros.live_params); read-only otherwise

    def descriptor(self, value) -> ParameterDescriptor:
        text = self.description + (f" ({self.unit})" if self.unit else "")
        if self.choices:
            text += f"; one of: {', '.join(self.choices)}"
        d = ParameterDescriptor(description=text, read_only=not self.runtime)
        if isinstance(value, bool) or (self.lo is None and self.hi is None):
            return d
        if isinstance(value, float):
            lo = -sys.float_info.max if self.lo is None else float(self.lo)
            hi = sys.float_info.max if self.hi is None else float(self.hi)
            d.floating_point_range = [FloatingPointRange(from_value=lo, to_value=hi, step=0.0)]
        elif isinstance(value, int):
            lo = -INT_MAX if self.lo is None else int(self.lo)
            hi = INT_MAX if self.hi is None else int(self.hi)
            d.integer_range = [IntegerRange(from_value=lo, to_value=hi, step=0)]
        return d


def _config_value(cfg: RotorConfig, key: str):
    obj: Any = cfg
    for part in key.split("."):
        obj = getattr(obj, part)
    return obj


def _yaml(value) -> str:
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    return repr(value) if isinstance(value, float) else str(value)


class NodeParams:
    """Declares a node's parameters and resolves them against the rotor config."""

    def __init__(self, node):
        self.node = node
        self._overrides = getattr(node, "_parameter_overrides", {})  # rclpy keeps -p/params-file values here
        self.config_file = self._declare(ParamSpec("config_file", "", "rotor config YAML; empty = the seed rotor"))
        sets = self._declare(
            ParamSpec("set", Parameter.Type.STRING_ARRAY, "config overrides key=value, e.g. controller.rate_hz=1000")
        )
        self.sets = [s for s in (sets or []) if s]
        self.extra: list[str] = []  # overrides that come from config-linked parameters
        self.config = load_config(self.config_file or None, self.sets)

    def declare(self, specs: list[ParamSpec]) -> dict[str, Any]:
        """Declare ``specs``; return their values and fold config-linked ones into ``self.config``."""
        values, extra = {}, []
        for spec in specs:
            default = spec.default
            if spec.config_key is not None:
                default = _config_value(self.config, spec.config_key)
                if default is None:
                    default = spec.none_value
                elif isinstance(spec.none_value, float):
                    default = float(default)
            value = self._declare(spec, default)
            values[spec.name] = value
            if spec.config_key is not None:
                cfg_value = None if (spec.none_value is not None and value == spec.none_value) else value
                extra.append(f"{spec.config_key}={_yaml(cfg_value)}")
        if extra:
            self.override(*extra)
        return values

    def override(self, *items: str) -> RotorConfig:
        """Fold ``key=value`` items into the config (after ``set``); the core validates the result."""
        self.extra.extend(items)
        self.config = load_config(self.config_file or None, [*self.sets, *self.extra])
        return self.config

    def _declare(self, spec: ParamSpec, default: Any = None):
        default = spec.default if default is None else default
        override = self._overrides.get(spec.name)
        if override is not None and isinstance(default, float) and override.type_ == Parameter.Type.INTEGER:
            # -p rate_hz:=1000 is an integer to rclpy; accept it for a float parameter
            self._overrides[spec.name] = Parameter(spec.name, Parameter.Type.DOUBLE, float(override.value))
        try:
            value = self.node.declare_parameter(spec.name, default, spec.descriptor(default)).value
        except InvalidParameterValueException:
            raise ParamError(self._range_message(spec, override.value if override else default)) from None
        except InvalidParameterTypeException:
            got = override.value if override is not None else default
            raise ParamError(
                f"parameter '{spec.name}' = {got!r} has the wrong type ({type(default).__name__})"
            ) from None
        if isinstance(value, int | float) and not isinstance(value, bool):
            if value != value or (spec.lo is not None and value < spec.lo) or (spec.hi is not None and value > spec.hi):
                raise ParamError(self._range_message(spec, value))
        if spec.choices and value not in spec.choices:
            shown = ", ".join(c for c in spec.choices if c)
            raise ParamError(f"parameter '{spec.name}' = {value!r} is not one of {shown}")
        return value

    @staticmethod
    def _range_message(spec: ParamSpec, value) -> str:
        lo = "-inf" if spec.lo is None else f"{spec.lo:g}"
        hi = "inf" if spec.hi is None else f"{spec.hi:g}"
        unit = f" {spec.unit}" if spec.unit else ""
        return f"parameter '{spec.name}' = {value} is out of range [{lo}, {hi}]{unit}"

    def check_unknown(self) -> None:
        """Refuse parameter overrides that no declaration used (a typo would otherwise pass silently)."""
        declared = set(self.node._parameters) if hasattr(self.node, "_parameters") else set()
        unknown = sorted(set(self._overrides) - declared)
        if unknown:
            known = ", ".join(sorted(declared - {"use_sim_time", "start_type_description_service"}))
            raise ParamError(f"unknown parameter '{unknown[0]}' (known: {known})")
