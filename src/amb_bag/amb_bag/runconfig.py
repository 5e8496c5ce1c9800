"""The run's rotor config recorded in a bag (/amb_plant/config, amb_ros.run_config), for the offline tools."""

from __future__ import annotations

from amb_ros.messages import RUN_CONFIG
from amb_ros.run_config import config_from_json

from .errors import BagError
from .reader import Bag


def recorded_config(bag: Bag):
    """The RotorConfig the run's plant published (its last message on /amb_plant/config), or None if the bag has
    none (recorded without that topic, or before plants published it)."""
    if RUN_CONFIG not in bag.topics:
        return None
    from rclpy.serialization import deserialize_message
    from std_msgs.msg import String

    text = None
    for _topic, _type, _log, _pub, data in bag.messages([RUN_CONFIG]):
        try:
            text = deserialize_message(data, String).data
        except Exception:  # rclpy raises plain errors for undecodable CDR
            raise BagError(f"{bag.dir}: a {RUN_CONFIG} message is not a std_msgs/String") from None
    return None if text is None else config_from_json(text, f"{bag.dir} ({RUN_CONFIG})")
