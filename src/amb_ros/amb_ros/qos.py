"""QoS profiles of the rig, each with its reason (docs/topics.md#qos).

- Lockstep data (/clock, /base/*, /amb/*, /amb_plant/state): RELIABLE so that no sample is lost, KEEP_LAST with a
  depth that covers a slow reader's lag (a recorder or monitor; plant and controller alternate, so they need 1),
  TRANSIENT_LOCAL so that a reader that matches a little late (discovery is asymmetric) still gets the first
  samples instead of the lockstep loop waiting forever for an answer that was published before the match.
- Realtime data: sensor-data QoS (best effort, shallow): a rig uses the latest sample, a late one is useless.
- /diagnostics: reliable and volatile, like diagnostic_updater.
"""

from __future__ import annotations

from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
    qos_profile_sensor_data,
)

LOCKSTEP_DEPTH = 1000  # samples a slow reader may lag behind before KEEP_LAST drops the oldest for it
DIAGNOSTICS_DEPTH = 100


def reliable_qos(depth: int, durability: DurabilityPolicy) -> QoSProfile:
    """RELIABLE, KEEP_LAST ``depth``: every profile of the project that must not lose messages."""
    return QoSProfile(depth=depth, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.RELIABLE,
                      durability=durability)  # fmt: skip


def lockstep_qos(depth: int = LOCKSTEP_DEPTH) -> QoSProfile:
    # transient local: a reader matched a little late still gets the history (nothing lost in lockstep)
    return reliable_qos(depth, DurabilityPolicy.TRANSIENT_LOCAL)


def realtime_qos() -> QoSProfile:
    return qos_profile_sensor_data


def data_qos(mode: str, depth: int = LOCKSTEP_DEPTH) -> QoSProfile:
    """QoS of the data topics for ``mode`` (lockstep or realtime)."""
    return lockstep_qos(depth) if mode == "lockstep" else realtime_qos()


def consumer_qos(mode: str, depth: int = LOCKSTEP_DEPTH) -> QoSProfile:
    """A reader beside the loop that takes in batches (the monitor): in lockstep the data QoS; in realtime best
    effort as offered, but with a ``depth``-deep history of its own, which holds the samples while the reader is
    busy (a refit takes longer than the sensor-data profile's 5 messages last: 62 ms of state blocks at 2 kHz)."""
    if mode == "lockstep":
        return lockstep_qos(depth)
    return QoSProfile(depth=depth, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.BEST_EFFORT,
                      durability=DurabilityPolicy.VOLATILE)  # fmt: skip


def diagnostics_qos() -> QoSProfile:
    return reliable_qos(DIAGNOSTICS_DEPTH, DurabilityPolicy.VOLATILE)


def latched_qos() -> QoSProfile:
    """Verdicts (/stability/unstable): a late subscriber (the controller's safe-gain switch, a recorder) must
    still get the current value."""
    return reliable_qos(1, DurabilityPolicy.TRANSIENT_LOCAL)
