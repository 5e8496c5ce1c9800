"""Message definitions as rosbag2 stores them: full concatenated ``.msg`` text, type hashes, Python classes.

rosbag2 (``rosbag2_cpp/message_definitions/local_message_definition_source.cpp``) stores the root ``.msg``
file unchanged, then, depth first, for each dependency not seen yet (dependencies parsed by a regex and sorted,
as in a ``std::set``): ``"\\n" + "=" * 80 + "\\n" + "MSG: " + <type as written> + "\\n" + <its text>``.  A type
written without a package belongs to the package of the file that names it.  The MCAP schema is then
``name = "pkg/msg/Type"``, ``encoding = "ros2msg"``.  This module re-implements that, reading the ``.msg``
files of the ament prefixes (``AMENT_PREFIX_PATH``, then this interpreter's prefix).
"""

from __future__ import annotations

import functools
import importlib
import json
import os
import re
import sys
from pathlib import Path

from .errors import BagError

SCHEMA_ENCODING = "ros2msg"
MESSAGE_ENCODING = "cdr"
DELIMITER = "=" * 80 + "\n"
MAX_DEPTH = 50  # rosbag2's ROSBAG2_CPP_LOCAL_MESSAGE_DEFINITION_SOURCE_MAX_RECURSION_DEPTH

# The regex of rosbag2: a field type at the start of a line ("foo_msgs/Bar" in "foo_msgs/Bar[] bar").
MSG_FIELD_TYPE_REGEX = re.compile(r"(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+")
PRIMITIVE_TYPES = frozenset(
    "bool byte char float32 float64 int8 uint8 int16 uint16 int32 uint32 int64 uint64 string".split()
)
_ROS_NAME = r"[a-zA-Z][a-zA-Z0-9_]*"
_NO_NAMESPACE = re.compile(rf"^({_ROS_NAME})/({_ROS_NAME})$")
_WITH_NAMESPACE = re.compile(rf"^({_ROS_NAME})/({_ROS_NAME})/({_ROS_NAME})$")


def split_type(type_name: str) -> tuple[str, str, str]:
    """``'sensor_msgs/msg/Imu'`` or ``'sensor_msgs/Imu'`` -> ``('sensor_msgs', 'msg', 'Imu')``."""
    if m := _NO_NAMESPACE.match(type_name):
        return m.group(1), "msg", m.group(2)
    if m := _WITH_NAMESPACE.match(type_name):
        return m.group(1), m.group(2), m.group(3)
    raise BagError(f"message type {type_name!r} is not of the form package/msg/Type")


def share_prefixes() -> list[Path]:
    """Install prefixes searched for ``share/<pkg>``: AMENT_PREFIX_PATH entries, then ``sys.prefix``."""
    prefixes = [Path(p) for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    prefixes.append(Path(sys.prefix))
    return prefixes


@functools.cache
def _interface_file(package: str, namespace: str, name: str, suffix: str) -> Path:
    for prefix in share_prefixes():
        path = prefix / "share" / package / namespace / f"{name}{suffix}"
        if path.is_file():
            return path
    raise BagError(f"no {suffix} file for {package}/{namespace}/{name} under any ament prefix")


def msg_dependencies(text: str, package: str) -> list[str]:
    """Non-primitive field types of a ``.msg`` text, as written (package added if missing), sorted."""
    deps = set()
    for m in MSG_FIELD_TYPE_REGEX.finditer(text):
        field_type = m.group(1)
        if field_type in PRIMITIVE_TYPES:
            continue
        deps.add(field_type if "/" in field_type else f"{package}/{field_type}")
    return sorted(deps)


@functools.cache
def _msg_text(type_name: str) -> tuple[str, str]:
    package, namespace, name = split_type(type_name)
    return _interface_file(package, namespace, name, ".msg").read_text(), package


@functools.cache
def full_text(type_name: str) -> str:
    """The concatenated definition rosbag2 writes into the MCAP schema of ``type_name``.

    Parameters
    ----------
    type_name : str
        ROS 2 type, e.g. ``'sensor_msgs/msg/Imu'``.
    """
    seen: set[str] = set()

    def append(type_written: str, depth: int) -> str:
        if depth <= 0:
            raise BagError(f"reached max recursion depth resolving definition of {type_name}")
        text, package = _msg_text(type_written)
        result = text
        for dep in msg_dependencies(text, package):
            if dep not in seen:
                seen.add(dep)
                result += "\n" + DELIMITER + "MSG: " + dep + "\n" + append(dep, depth - 1)
        return result

    return append(type_name, MAX_DEPTH)


@functools.cache
def type_hash(type_name: str) -> str:
    """RIHS01 type description hash of ``type_name`` from its installed ``.json`` (empty if unknown)."""
    package, namespace, name = split_type(type_name)
    try:
        data = json.loads(_interface_file(package, namespace, name, ".json").read_text())
    except (BagError, ValueError):
        return ""
    canonical = f"{package}/{namespace}/{name}"
    return next((h["hash_string"] for h in data.get("type_hashes", []) if h.get("type_name") == canonical), "")


@functools.cache
def message_class(type_name: str):
    """The rclpy message class of ``type_name`` (imports ``<pkg>.<namespace>``)."""
    package, namespace, name = split_type(type_name)
    try:
        cls = getattr(importlib.import_module(f"{package}.{namespace}"), name)
    except (ImportError, AttributeError):
        raise BagError(f"message type {type_name} is not installed in this environment") from None
    return cls
