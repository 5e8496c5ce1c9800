"""QoS profiles as rosbag2 stores them (metadata v9), and the QoS the recorder and player use.

rosbag2 (``rosbag2_storage/src/rosbag2_storage/qos.cpp``) stores, per topic, the list of profiles offered by the
publishers it found, each as a dict with string enums (``history: keep_last``) and ``{sec, nsec}`` durations
(``RMW_DURATION_INFINITE`` = 2**63-1 ns = ``{sec: 9223372036, nsec: 854775807}``).  The same list goes
into metadata.yaml (a YAML list of dicts) and, as a YAML string, into the MCAP channel metadata
``offered_qos_profiles``; readers such as rosbags match the two, so they must be identical.

The dict helpers are ROS-free; the ``QoSProfile`` helpers import rclpy when called.
"""

from __future__ import annotations

import yaml

from .errors import BagFormatError

# rmw_qos_*_policy_to_str, indexed by the rmw enum value (rclpy's enums carry the same values).
HISTORY = {0: "system_default", 1: "keep_last", 2: "keep_all", 3: "unknown"}
RELIABILITY = {0: "system_default", 1: "reliable", 2: "best_effort", 3: "unknown", 4: "best_available"}
DURABILITY = {0: "system_default", 1: "transient_local", 2: "volatile", 3: "unknown", 4: "best_available"}
LIVELINESS = {0: "system_default", 1: "automatic", 3: "manual_by_topic", 4: "unknown", 5: "best_available"}
NS_PER_S = 1_000_000_000
PLAY_DEPTH = 1000  # history depth of the player's publishers: deep enough that a replay drops nothing
RECORD_DEPTH = 1000  # depth given with the recorder's KEEP_ALL subscriptions (as the benchmark's bare subscriber)


def _duration(ns: int) -> dict:
    return {"sec": int(ns) // NS_PER_S, "nsec": int(ns) % NS_PER_S}


def profile_to_dict(qos) -> dict:
    """An rclpy ``QoSProfile`` as the v9 rosbag2 dict (key order as rosbag2 writes it)."""
    return {
        "history": HISTORY.get(int(qos.history), "unknown"),
        "depth": int(qos.depth),
        "reliability": RELIABILITY.get(int(qos.reliability), "unknown"),
        "durability": DURABILITY.get(int(qos.durability), "unknown"),
        "deadline": _duration(qos.deadline.nanoseconds),
        "lifespan": _duration(qos.lifespan.nanoseconds),
        "liveliness": LIVELINESS.get(int(qos.liveliness), "unknown"),
        "liveliness_lease_duration": _duration(qos.liveliness_lease_duration.nanoseconds),
        "avoid_ros_namespace_conventions": bool(qos.avoid_ros_namespace_conventions),
    }


def profiles_to_yaml(profiles: list[dict]) -> str:
    """The MCAP channel metadata string: the YAML block sequence of the profiles (no trailing newline)."""
    if not profiles:
        return ""
    return yaml.safe_dump(profiles, sort_keys=False, default_flow_style=False).rstrip("\n")


def profiles_from_yaml(text: str) -> list[dict]:
    """Inverse of :func:`profiles_to_yaml`; raises BagFormatError on anything but a list of dicts."""
    if not text:
        return []
    try:
        profiles = yaml.safe_load(text)
    except yaml.YAMLError:
        raise BagFormatError("offered_qos_profiles is not valid YAML") from None
    if not isinstance(profiles, list) or not all(isinstance(p, dict) for p in profiles):
        raise BagFormatError("offered_qos_profiles is not a list of QoS dicts")
    return profiles


def request_for_offers(profiles: list[dict], keep_all: bool = True, depth: int = RECORD_DEPTH):
    """Subscription QoS compatible with every offered profile (rosbag2's ``adapt_request_to_offers``).

    Reliable only if every publisher is reliable, transient-local only if every publisher is (so latched
    messages are received).  History: KEEP_ALL by default, so that a reliable publisher is slowed down rather
    than a sample dropped when the recorder falls behind; ``keep_all=False`` gives KEEP_LAST ``depth``.
    """
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    reliable = bool(profiles) and all(p.get("reliability") == "reliable" for p in profiles)
    latched = bool(profiles) and all(p.get("durability") == "transient_local" for p in profiles)
    return QoSProfile(
        history=HistoryPolicy.KEEP_ALL if keep_all else HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE,
    )


def offer_for_playback(profiles: list[dict], depth: int = PLAY_DEPTH):
    """Publisher QoS for replay (rosbag2's ``adapt_offer_to_recorded_offers``, with a deep history).

    If every recorded profile has the same reliability, durability and liveliness, that is offered; otherwise
    (or without profiles) the rosbag2 default offer: reliable, volatile.
    """
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    reliability, durability = ReliabilityPolicy.RELIABLE, DurabilityPolicy.VOLATILE
    keys = {(p.get("reliability"), p.get("durability"), p.get("liveliness")) for p in profiles}
    if len(keys) == 1:
        rel, dur, _ = keys.pop()
        reliability = ReliabilityPolicy.BEST_EFFORT if rel == "best_effort" else ReliabilityPolicy.RELIABLE
        durability = DurabilityPolicy.TRANSIENT_LOCAL if dur == "transient_local" else DurabilityPolicy.VOLATILE
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth, reliability=reliability, durability=durability)
