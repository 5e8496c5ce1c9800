"""metadata.yaml of a rosbag2 bag, version 9, written the way rosbag2 (yaml-cpp) writes it, and read back.

Layout (``rosbag2_storage/yaml.hpp``): ``rosbag2_bagfile_information`` with version, storage_identifier,
duration, starting_time, message_count, ``topics_with_message_count`` (singular ``count``: rosbags needs that
key), compression_format, compression_mode, relative_file_paths, files, custom_data (string -> string),
ros_distro.  QoS profiles are a list of dicts (v9).  MCAP chunk compression is internal to the storage, so
compression_format/mode stay empty, as rosbag2 writes them for the MCAP plugin.
"""

from __future__ import annotations

import json
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from .errors import BagFormatError

VERSION = 9
STORAGE_ID = "mcap"
ROS_DISTRO = "jazzy"
METADATA_FILE = "metadata.yaml"
ROOT_KEY = "rosbag2_bagfile_information"
TIME_MAX_NS = 2**63 - 1  # rosbag2's starting_time of a bag without messages (time_point::max)
_PLAIN = re.compile(r"^[A-Za-z0-9_/.][A-Za-z0-9_/.\-]*$")


@dataclass
class TopicRecord:
    """One topic of a bag: name, ROS type, offered QoS dicts (v9), RIHS01 type hash, message count."""

    name: str
    type: str
    offered_qos_profiles: list[dict] = field(default_factory=list)
    type_description_hash: str = ""
    message_count: int = 0


@dataclass
class FileRecord:
    """One storage file of a bag with its first log time, duration (ns) and message count."""

    path: str
    starting_time_ns: int = TIME_MAX_NS
    duration_ns: int = 0
    message_count: int = 0


def build_metadata(topics: list[TopicRecord], files: list[FileRecord], custom_data: dict | None = None) -> dict:
    """The ``rosbag2_bagfile_information`` dict (inner, without the root key) of a bag."""
    start = min((f.starting_time_ns for f in files if f.message_count), default=TIME_MAX_NS)
    end = max((f.starting_time_ns + f.duration_ns for f in files if f.message_count), default=start)
    custom = {str(k): str(v) for k, v in (custom_data or {}).items()}
    return {
        "version": VERSION,
        "storage_identifier": STORAGE_ID,
        "duration": {"nanoseconds": max(0, end - start)},
        "starting_time": {"nanoseconds_since_epoch": start},
        "message_count": sum(f.message_count for f in files),
        "topics_with_message_count": [
            {
                "topic_metadata": {
                    "name": t.name,
                    "type": t.type,
                    "serialization_format": "cdr",
                    "offered_qos_profiles": t.offered_qos_profiles,
                    "type_description_hash": t.type_description_hash,
                },
                "message_count": t.message_count,
            }
            for t in topics
        ],
        "compression_format": "",
        "compression_mode": "",
        "relative_file_paths": [f.path for f in files],
        "files": [
            {
                "path": f.path,
                "starting_time": {"nanoseconds_since_epoch": f.starting_time_ns},
                "duration": {"nanoseconds": f.duration_ns},
                "message_count": f.message_count,
            }
            for f in files
        ],
        "custom_data": custom or None,
        "ros_distro": ROS_DISTRO,
    }


def _scalar(value) -> str:
    if value is None:
        return "~"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    text = str(value)
    if text and _PLAIN.match(text) and yaml.safe_load(text) == text:
        return text
    return json.dumps(text)  # a JSON string is a valid double-quoted YAML scalar


def _emit(obj, indent: int, lines: list[str], first_prefix: str | None = None) -> None:
    """Block-style YAML like yaml-cpp: 2-space indent, sequences indented under their key."""
    pad = " " * indent
    if isinstance(obj, dict):
        for i, (key, value) in enumerate(obj.items()):
            head = (first_prefix if (i == 0 and first_prefix is not None) else pad) + f"{key}:"
            if isinstance(value, (dict, list)) and value:
                lines.append(head)
                _emit(value, indent + 2, lines)
            elif isinstance(value, dict):
                lines.append(head + " {}")
            elif isinstance(value, list):
                lines.append(head + " []")
            else:
                lines.append(f"{head} {_scalar(value)}")
    else:
        for item in obj:
            if isinstance(item, dict) and item:
                _emit(item, indent + 2, lines, first_prefix=pad + "- ")
            else:
                lines.append(f"{pad}- {_scalar(item)}")


def dump_yaml(inner: dict, root_key: str | None = ROOT_KEY) -> str:
    """YAML text of the metadata (with the root key, as in metadata.yaml, or without, as in the MCAP record)."""
    obj = {root_key: inner} if root_key else inner
    lines: list[str] = []
    _emit(obj, 0, lines)
    text = "\n".join(lines) + "\n"
    if yaml.safe_load(text) != obj:  # the emitter is ours: never write what does not read back identically
        raise AssertionError("metadata YAML does not round-trip")
    return text


def write_metadata(bag_dir: Path, inner: dict) -> Path:
    """Write ``metadata.yaml`` atomically (temporary file, then rename)."""
    path = Path(bag_dir) / METADATA_FILE
    tmp = path.with_suffix(".yaml.tmp")
    tmp.write_text(dump_yaml(inner))
    os.replace(tmp, path)
    return path


def _need(mapping: dict, key: str, kind, where: str):
    value = mapping.get(key) if isinstance(mapping, dict) else None
    if not isinstance(value, kind) or (kind is int and isinstance(value, bool)):
        raise BagFormatError(f"{where}: key {key!r} is missing or not a {getattr(kind, '__name__', kind)}")
    return value


def load_metadata(bag_dir: Path) -> dict:
    """Read and check metadata.yaml of ``bag_dir``; returns the inner dict. Raises BagFormatError."""
    path = Path(bag_dir) / METADATA_FILE
    try:
        doc = yaml.safe_load(path.read_text())
    except FileNotFoundError:
        raise BagFormatError(f"{bag_dir} has no {METADATA_FILE} (not a finished bag; try `amb-bag check`)") from None
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise BagFormatError(f"{path} is not readable YAML ({type(exc).__name__})") from None
    inner = _need(doc, ROOT_KEY, dict, str(path))
    version = _need(inner, "version", int, str(path))
    if version > VERSION:
        raise BagFormatError(f"{path}: metadata version {version} is newer than the supported {VERSION}")
    storage = _need(inner, "storage_identifier", str, str(path))
    if storage != STORAGE_ID:
        raise BagFormatError(f"{path}: storage {storage!r} is not supported (only mcap)")
    for key in ("relative_file_paths", "topics_with_message_count"):
        _need(inner, key, list, str(path))
    for entry in inner["topics_with_message_count"]:
        topic = _need(entry, "topic_metadata", dict, f"{path}: topics_with_message_count")
        for key in ("name", "type"):
            _need(topic, key, str, f"{path}: topic_metadata")
        _need(entry, "message_count", int, f"{path}: topics_with_message_count")
    _need(inner, "message_count", int, str(path))
    return inner


def custom_json(inner: dict, key: str):
    """A JSON value stored as a string in custom_data (None if absent or not JSON)."""
    text = (inner.get("custom_data") or {}).get(key)
    try:
        return json.loads(text) if isinstance(text, str) else None
    except ValueError:
        return None
