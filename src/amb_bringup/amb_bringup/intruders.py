"""Publishers joining the loop's topics during a run, reported by DDS as they appear (no polling gap).

amb-rig's collector node holds, for each loop topic (/amb/current, /amb/displacement), a subscription that requests
a deadline of 1 ns.  No publisher offers that (the offered deadline must not exceed the requested one), so the
subscription matches none and receives no data, but DDS reports every publisher it discovers on the topic as a
requested-incompatible-QoS event, with a running count.  A run has exactly one publisher per loop topic; a count
above one is another publisher, noticed as DDS discovers it rather than at the next 0.25 s graph poll of
``domain.Watch``.  The event handler names the topic's publishers at that moment.  Each participant discovers
endpoints on its own: a publisher that leaves within milliseconds of matching the plant may be gone before this
node has discovered it.  The loop itself does not depend on that: the plant and the controller reject every
message without the run's token and count it (docs/topics.md, "The run token"), and the verdict reports them.
"""

from __future__ import annotations

import threading
import time

from sensor_msgs.msg import JointState

from amb_ros import messages as m

LOOP_TOPICS = {m.CURRENT: JointState, m.DISPLACEMENT: JointState}
NAME_WAIT_S = 0.5  # for an intruder's node name, in the event handler (the collector's diagnostics wait meanwhile)


class PublisherEvents:
    """Counts the publishers DDS discovers on the loop's topics among ``topics`` (callbacks on ``node``'s executor)."""

    def __init__(self, node, topics):
        from rclpy.duration import Duration
        from rclpy.event_handler import SubscriptionEventCallbacks
        from rclpy.qos import QoSProfile

        self.node = node
        self.count = {t: 0 for t in topics if t in LOOP_TOPICS}
        self.names: dict[str, list[str]] = {}
        self._lock = threading.Lock()
        for topic in self.count:
            events = SubscriptionEventCallbacks(incompatible_qos=lambda info, t=topic: self._on_publisher(t, info))
            qos = QoSProfile(depth=1, deadline=Duration(nanoseconds=1))
            node.create_subscription(LOOP_TOPICS[topic], topic, _no_data, qos, event_callbacks=events, raw=True)

    def _on_publisher(self, topic: str, info) -> None:
        from .domain import UNNAMED, publishers

        # the endpoint is discovered before its node's name arrives (ros_discovery_info): wait briefly for it
        end = time.monotonic() + NAME_WAIT_S
        names = publishers(self.node, [topic]).get(topic, [])
        while UNNAMED in names and time.monotonic() < end:
            time.sleep(0.01)
            names = publishers(self.node, [topic]).get(topic, names)
        with self._lock:
            self.count[topic] = max(self.count[topic], int(info.total_count))
            if len(names) > len(self.names.get(topic, ())):
                self.names[topic] = names

    def extra(self) -> dict[str, list[str]]:
        """``{topic: [publishers named, "N more that left before ..."]}`` for loop topics that had more than one."""
        out = {}
        with self._lock:
            for topic, n in self.count.items():
                if n > 1:
                    names = list(self.names.get(topic, ()))
                    if len(names) < n:
                        names.append(f"{n - len(names)} more that left before it was named")
                    out[topic] = names
        return out


def _no_data(_msg) -> None:  # never called: the requested deadline matches no publisher
    pass
