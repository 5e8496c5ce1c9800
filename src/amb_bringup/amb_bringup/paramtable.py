"""The one table of every node parameter, as the nodes declare them, and the check amb-rig runs against it.

The table is built from the nodes' own ``specs()`` (plus the common parameters of every rig node and the
``config_file``/``set`` pair of :class:`amb_ros.params.NodeParams`), so that amb-rig, the launch files and the
docs can never disagree with what a node accepts.  ``check_parameters`` validates a run's parameters before any
process starts: an unknown key fails with the node, the key and the closest valid key (difflib), a value out of
range or of the wrong kind with the range.

Importing the four node modules (and the numerical stack behind them) takes ~1.2 s of CPU, most of the time a
typo would take to fail, so the table is cached (``~/.cache/amb-rig/param-table-<hash>.json``, or under
``$XDG_CACHE_HOME``) under a hash of every source file of the packages that declare parameters: any edit to them
means a new hash and a fresh table, so the cache cannot go stale; an unwritable cache only costs the time.
"""

from __future__ import annotations

import difflib
import hashlib
import importlib
import importlib.util
import json
import math
import os
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import Any

from amb_dynamics.errors import InputError

NODE_MODULES = {  # amb-rig name -> module whose specs() the node declares
    "base_motion": "base_motion.node",
    "controller": "amb_controller.node",
    "plant": "amb_plant.node",
    "monitor": "stability_monitor.node",
}
ROS_BUILTIN = ("use_sim_time",)  # declared by rclpy for every node
SOURCE_PACKAGES = ("amb_dynamics", "amb_ros", "base_motion", "amb_controller", "amb_plant", "stability_monitor")


@dataclass(frozen=True)
class Spec:
    """A node parameter as the table keeps it (the fields of amb_ros.params.ParamSpec, without rclpy types: a
    typed default without a value, such as a string array, is None)."""

    name: str
    default: Any
    description: str
    unit: str = ""
    lo: float | None = None
    hi: float | None = None
    choices: tuple[str, ...] | None = None
    config_key: str | None = None
    none_value: Any = None
    runtime: bool = False

    @classmethod
    def of(cls, spec) -> Spec:
        values = {f.name: getattr(spec, f.name) for f in fields(cls)}
        if not isinstance(values["default"], bool | int | float | str | list | tuple | type(None)):
            values["default"] = None  # Parameter.Type.STRING_ARRAY and the like
        if values["choices"] is not None:
            values["choices"] = tuple(values["choices"])
        return cls(**values)


def node_specs(name: str) -> dict:
    """{parameter: ParamSpec} of node ``name`` (amb-rig name), common parameters included."""
    from rclpy.parameter import Parameter

    from amb_ros.node_base import common_specs
    from amb_ros.params import ParamSpec

    own = importlib.import_module(NODE_MODULES[name]).specs()
    base = [ParamSpec("config_file", "", "rotor config YAML; empty = the seed rotor"),
            ParamSpec("set", Parameter.Type.STRING_ARRAY, "config overrides key=value")]  # fmt: skip
    return {s.name: Spec.of(s) for s in [*base, *common_specs(), *own]}


def source_hash() -> str:
    """sha256 of every .py file of the packages whose code declares node parameters (paths and contents)."""
    h = hashlib.sha256()
    for pkg in SOURCE_PACKAGES:
        spec = importlib.util.find_spec(pkg)
        if spec is None or not spec.submodule_search_locations:
            continue
        for root in spec.submodule_search_locations:
            for f in sorted(Path(root).rglob("*.py")):
                h.update(f"{pkg}/{f.relative_to(root).as_posix()}".encode())
                h.update(f.read_bytes())
    return h.hexdigest()[:16]


def cache_dir() -> Path:
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "amb-rig"


def table(use_cache: bool = True) -> dict[str, dict[str, Spec]]:
    """{amb-rig node name: {parameter: Spec}} for every node amb-rig can start."""
    path = cache_dir() / f"param-table-{source_hash()}.json" if use_cache else None
    if path is not None:
        try:
            doc = json.loads(path.read_text())
            return {node: {k: Spec(**{**v, "choices": None if v["choices"] is None else tuple(v["choices"])})
                           for k, v in specs.items()} for node, specs in doc.items()}  # fmt: skip
        except (OSError, ValueError, TypeError, KeyError):
            pass  # no cache yet (or unreadable): build it
    out = {name: node_specs(name) for name in NODE_MODULES}
    if path is not None:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            tmp = path.with_suffix(f".{os.getpid()}.tmp")
            tmp.write_text(json.dumps({n: {k: asdict(v) for k, v in s.items()} for n, s in out.items()}))
            tmp.replace(path)  # atomic: a concurrent amb-rig reads the old file or the new one
            week_ago = path.stat().st_mtime - 7 * 86400
            for old in path.parent.glob("param-table-*.json"):  # tables of sources unused for a week
                if old.stat().st_mtime < week_ago:
                    old.unlink(missing_ok=True)
        except OSError:
            pass
    return out


def closest(key: str, valid) -> str:
    """'; did you mean 'x'?' for the closest valid key, or '' when nothing is close."""
    match = difflib.get_close_matches(key, sorted(valid), n=1, cutoff=0.6)
    return f"; did you mean '{match[0]}'?" if match else ""


def check_value(node: str, spec, value) -> None:
    """Raise InputError (one line) when ``value`` cannot be the value of ``spec``; a cheap first check, the node
    still validates everything (types of config-linked parameters come from the rotor config)."""
    where = f"{node}:{spec.name}"
    default = spec.default
    if value is None:
        raise InputError(f"parameter {where} has no value")
    if isinstance(default, bool) and not isinstance(value, bool):
        raise InputError(f"parameter {where} = {value!r} must be true or false")
    if spec.choices is not None:
        if value not in spec.choices:
            raise InputError(f"parameter {where} = {value!r} is not one of {', '.join(c for c in spec.choices if c)}")
        return
    if spec.lo is not None or spec.hi is not None:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise InputError(f"parameter {where} = {value!r} must be a number")
        lo = -math.inf if spec.lo is None else spec.lo
        hi = math.inf if spec.hi is None else spec.hi
        if not (lo <= value <= hi):  # NaN fails too
            raise InputError(f"parameter {where} = {value} is out of range [{lo:g}, {hi:g}]"
                             + (f" {spec.unit}" if spec.unit else ""))  # fmt: skip


def check_parameters(common: dict, per: dict[str, dict], nodes, specs: dict[str, dict] | None = None) -> None:
    """Validate the parameters every started node (``nodes``, amb-rig names) would get; raise InputError."""
    specs = table() if specs is None else specs
    for node in nodes:
        valid = specs[node]
        for key, value in {**common, **per.get(node, {})}.items():
            if key in ROS_BUILTIN:
                continue
            if key not in valid:
                raise InputError(f"{node} has no parameter '{key}'{closest(key, list(valid) + list(ROS_BUILTIN))}")
            check_value(node, valid[key], value)
