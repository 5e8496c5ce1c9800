"""The one table of every node parameter, as the nodes declare them, and the check amb-rig runs against it.

The table is built from the nodes' own ``specs()`` (plus the common parameters of every rig node and the
``config_file``/``set`` pair of :class:`amb_ros.params.NodeParams`), so that amb-rig, the launch files and the
docs can never disagree with what a node accepts.  ``check_parameters`` validates a run's parameters before any
process starts: an unknown key fails with the node, the key and the closest valid key (difflib), a value out of
range or of the wrong kind with the range.
"""

from __future__ import annotations

import difflib
import importlib
import math

from amb_dynamics.errors import InputError

NODE_MODULES = {  # amb-rig name -> module whose specs() the node declares
    "base_motion": "base_motion.node",
    "controller": "amb_controller.node",
    "plant": "amb_plant.node",
    "monitor": "stability_monitor.node",
}
ROS_BUILTIN = ("use_sim_time",)  # declared by rclpy for every node


def node_specs(name: str) -> dict:
    """{parameter: ParamSpec} of node ``name`` (amb-rig name), common parameters included."""
    from rclpy.parameter import Parameter

    from amb_ros.node_base import common_specs
    from amb_ros.params import ParamSpec

    own = importlib.import_module(NODE_MODULES[name]).specs()
    base = [ParamSpec("config_file", "", "rotor config YAML; empty = the seed rotor"),
            ParamSpec("set", Parameter.Type.STRING_ARRAY, "config overrides key=value")]  # fmt: skip
    return {s.name: s for s in [*base, *common_specs(), *own]}


def table() -> dict[str, dict]:
    """{amb-rig node name: {parameter: ParamSpec}} for every node amb-rig can start."""
    return {name: node_specs(name) for name in NODE_MODULES}


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
