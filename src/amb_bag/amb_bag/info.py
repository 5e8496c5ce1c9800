"""``amb-bag info``: what ``ros2 bag info`` prints (files, size, duration, topics, types, counts) plus loss and
the ISO 14839-2 vibration zones of the run's end (from the plant's last /diagnostics report in the bag)."""

from __future__ import annotations

import datetime as dt

from amb_ros.diag_keys import read_vibration

from .loss import CUSTOM_KEY, DIAGNOSTICS_TOPIC, format_table
from .metadata import custom_json
from .reader import Bag

BYTE_UNITS = ("B", "KiB", "MiB", "GiB", "TiB")
PLANT_STATUS = "amb_plant"  # the plant node's /diagnostics status name


def bag_info(path) -> dict:
    """The bag summary as a JSON-able dict (times in ns since the epoch, durations in s)."""
    bag = Bag(path)
    meta = bag.metadata or {}
    duration = (bag.end_ns - bag.start_ns) * 1e-9 if bag.message_count else 0.0
    return {
        "path": str(bag.dir if bag.metadata is not None else bag.files[0]),
        "files": [f.name for f in bag.files],
        "size_bytes": bag.size_bytes,
        "storage_identifier": "mcap",
        "ros_distro": meta.get("ros_distro"),
        "compression": sorted(bag.compression),
        "duration_s": duration,
        "start_ns": bag.start_ns,
        "end_ns": bag.end_ns,
        "message_count": bag.message_count,
        "topics": [
            {
                "name": t.name,
                "type": t.type,
                "message_count": t.message_count,
                "serialization_format": t.serialization_format,
                "offered_qos_profiles": t.offered_qos_profiles,
            }
            for t in sorted(bag.topics.values(), key=lambda t: t.name)
        ],
        "loss": custom_json(meta, CUSTOM_KEY),
        "custom_data": meta.get("custom_data"),
        "vibration": recorded_vibration(bag),
    }


def recorded_vibration(bag: Bag) -> dict | None:
    """The ISO 14839-2 grade of the run's last second, from the plant's last report on /diagnostics in the bag
    (amb_ros.diag_keys); None if the bag has no such report."""
    last = None
    for values in reports(bag, PLANT_STATUS):
        if (vib := read_vibration(values)) is not None:
            last = {**vib, "final_report": values.get("final") == "true"}
    return last


def last_report(bag: Bag, name: str) -> dict[str, str] | None:
    """The key/value pairs of node ``name``'s last /diagnostics status in the bag (its final report when it
    wrote one); None if there is none."""
    last = None
    for values in reports(bag, name):
        last = values
    return last


def reports(bag: Bag, name: str):
    """Every /diagnostics status of node ``name`` in the bag, in order, as {key: value}."""
    if DIAGNOSTICS_TOPIC not in bag.topics:
        return
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.serialization import deserialize_message

    for _topic, _type, _log, _pub, data in bag.messages([DIAGNOSTICS_TOPIC]):
        try:
            msg = deserialize_message(data, DiagnosticArray)
        except Exception:  # an undecodable report is recorded anyway; it is not a node's
            continue
        for status in msg.status:
            if status.name == name:
                yield {kv.key: kv.value for kv in status.values}


def _size(n: float) -> str:
    for unit in BYTE_UNITS:
        if n < 1024 or unit == BYTE_UNITS[-1]:
            return f"{n:.1f} {unit}"
        n /= 1024
    return ""


def _stamp(ns: int | None) -> str:
    if ns is None:
        return "-"
    t = dt.datetime.fromtimestamp(ns / 1e9, tz=dt.UTC)
    return f"{t:%b %d %Y %H:%M:%S}.{(ns // 1_000_000) % 1000:03d} UTC ({ns // 10**9}.{ns % 10**9:09d})"


def format_info(info: dict) -> str:
    """Human-readable text in the layout of ``ros2 bag info``."""
    width = max((len(t["name"]) for t in info["topics"]), default=0)
    tw = max((len(t["type"]) for t in info["topics"]), default=0)
    lines = [
        f"Files:             {', '.join(info['files'])}",
        f"Bag size:          {_size(info['size_bytes'])}",
        f"Storage id:        {info['storage_identifier']}",
        f"ROS Distro:        {info['ros_distro'] or '-'}",
        f"Compression:       {', '.join(info['compression']) or '-'}",
        f"Duration:          {info['duration_s']:.9f}s",
        f"Start:             {_stamp(info['start_ns'])}",
        f"End:               {_stamp(info['end_ns'])}",
        f"Messages:          {info['message_count']}",
        f"Topic information: {len(info['topics'])} topics",
    ]
    for t in info["topics"]:
        lines.append(f"  Topic: {t['name']:<{width}} | Type: {t['type']:<{tw}} | Count: {t['message_count']:>8} | "
                     f"Serialization Format: {t['serialization_format']}")  # fmt: skip
    if vib := info.get("vibration"):
        axes = ", ".join(f"{c} {a['m']:.3g} m zone {a['zone']}" for c, a in vib["axes"].items())
        lines.append(f"Vibration (ISO 14839-2 vs C_min, last {vib['window_s']:.3g} s, the plant's report): {axes}")
    if info["loss"]:
        lines.append("Loss (received vs published counts reported on /diagnostics):")
        lines.append(format_table(info["loss"]))
    return "\n".join(lines)
