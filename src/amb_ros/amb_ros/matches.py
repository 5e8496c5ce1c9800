"""Publishers matched by a node's input subscriptions, from DDS match status: a foreign one is never missed.

A subscription's matched status (rmw's SUBSCRIPTION_MATCHED event) carries ``total_count``, the number of
publishers it has ever matched, so a publisher that lives for a few milliseconds between two looks is still
counted when the status is next taken, however late.  The status is taken directly (``poll``: from the loop's
``serve`` and before every report), not through an executor callback: the nodes' loops run no executor that would
reach it (rclpy's ``spin_once`` serves subscriptions first, and the loop's nearly always have data).

The loop's input topics have one publisher each in a run (the plant publishes /amb/displacement, the controller
/amb/current, or a rig bridge in their place): every further publisher matched during the run is foreign.  The
nodes report the counts in /diagnostics (``publishers matched <topic>``, ``foreign publishers <topic>``, and the
publishers seen), and amb-rig fails the run naming them (``amb_bringup.domain``).  A publisher that left before
the next poll cannot be named any more; it is counted all the same.
"""

from __future__ import annotations

from rclpy.event_handler import QoSSubscriptionEventType
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy

from .diag_keys import per_topic

UNKNOWN_NAME = "_NODE_NAME_UNKNOWN_"  # rmw's node name of an endpoint whose node is not known yet


def full_name(namespace: str, name: str) -> str:
    """``/namespace/name`` of a graph endpoint's node (its name may not have been discovered yet)."""
    if name == UNKNOWN_NAME:  # the endpoint is discovered before its node's name (ros_discovery_info) arrives
        return "a node not yet named"
    return f"{namespace.rstrip('/')}/{name}"


class PublisherMatches:
    """Publishers matched per input topic of ``node``: ``watch(subscription)`` each, then ``poll()`` now and then."""

    def __init__(self, node):
        self.node = node
        self.total: dict[str, int] = {}
        self.expected: dict[str, int] = {}
        self.names: dict[str, list[str]] = {}
        self.own: dict[str, set] = {}  # endpoint GIDs of the run's own publishers (matched up to ``expected``)
        self._events: dict[str, object] = {}

    def watch(self, subscription, expected: int = 1) -> None:
        """Count the publishers ``subscription`` matches; a run has ``expected`` of them on its topic."""
        topic = subscription.topic_name
        self.total[topic], self.expected[topic], self.names[topic], self.own[topic] = 0, expected, [], set()
        with subscription.handle:
            self._events[topic] = _rclpy.EventHandle(
                subscription.handle, QoSSubscriptionEventType.RCL_SUBSCRIPTION_MATCHED
            )

    def poll(self) -> None:
        """Take every watched subscription's matched status (cheap: no graph query unless a count grew)."""
        for topic, event in self._events.items():
            with event:
                info = event.take_event()
            if info is not None and int(info.total_count) > self.total[topic]:
                self.on_matched(topic, info)

    def on_matched(self, topic: str, info) -> None:
        self.total[topic] = max(self.total[topic], int(info.total_count))
        endpoints = self.node.get_publishers_info_by_topic(topic)
        if self.total[topic] <= self.expected[topic]:  # the run's own: remembered by GID, never named as foreign
            self.own[topic].update(bytes(e.endpoint_gid) for e in endpoints)
            return
        for endpoint in endpoints:  # name who is there now (the intruder may have left)
            if bytes(endpoint.endpoint_gid) in self.own[topic]:
                continue
            name = full_name(endpoint.node_namespace, endpoint.node_name)
            if name not in self.names[topic]:
                self.names[topic].append(name)

    def close(self) -> None:
        """Destroy the event handles: each holds its subscription (and through it the node and its DDS
        participant) alive past the node's destruction.  The counts stay readable."""
        for event in self._events.values():
            event.destroy_when_not_in_use()
        self._events = {}

    def foreign(self, topic: str) -> int:
        """Publishers of ``topic`` matched beyond the expected ones."""
        return max(0, self.total.get(topic, 0) - self.expected.get(topic, 0))

    def values(self) -> dict[str, str]:
        self.poll()
        out = {}
        for topic, total in sorted(self.total.items()):
            out[per_topic("publishers matched", topic).text] = str(total)
            if extra := self.foreign(topic):
                out[per_topic("foreign publishers", topic).text] = str(extra)
                out[per_topic("publishers seen", topic).text] = ", ".join(self.names[topic]) or "none left to name"
        return out
