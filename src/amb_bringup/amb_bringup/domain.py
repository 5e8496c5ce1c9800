"""Is the DDS domain free for a rig?  Publishers already on the topics this run's nodes will publish.

Two rigs on one ROS_DOMAIN_ID (a second ``amb-rig run`` in another shell, an orphaned node of a crashed run, an
``amb-bag play`` of a recorded run) would match each other's readers and mix their samples: the plant would
integrate the other rig's commands, the monitor would fit two rotors' data, the recorder would record both.
Three guards, each naming who is in the way: another ``amb-rig`` holds the domain's run lock
(``amb_ros.env.hold_run_lock``, immediate and certain); before anything starts, a publisher already on a topic
this run will publish (``foreign_publishers``); during the run, a second publisher on one of them (``Watch``).
The graph checks depend on discovery, which on localhost took under 40 ms in 14 of 20 probes and 0.7-2.6 s in
the other 6 (measured): the start probe catches most intruders, the watch catches the rest within a few seconds,
and the run then fails with that reason instead of producing mixed numbers.
"""

from __future__ import annotations

import time

from amb_ros import messages as m
from amb_ros.diag_keys import per_topic, topics_with
from amb_ros.matches import UNKNOWN_NAME, full_name

PROBE_S = 0.3  # graph watch before a run starts
POLL_S = 0.05
WATCH_PERIOD_S = 0.25
NAME_GRACE_S = 1.0  # an intruder seen before its node's name: wait this long for the name before reporting

PUBLISHES = {  # amb-rig process name -> data topics its node publishes
    "base_motion": (m.BASE_RATES, m.IMU, m.ANGULAR_ACCELERATION),
    "controller": (m.CURRENT,),
    "plant": (m.DISPLACEMENT, m.STATE, m.CLOCK),
    "monitor": (m.MULTIPLIERS, m.UNSTABLE),
}


def topics_of(names) -> list[str]:
    """The data topics published by the processes ``names`` (amb-rig names; others publish no data)."""
    return sorted({topic for name in names for topic in PUBLISHES.get(name, ())})


def publishers(node, topics, more_than: int = 0) -> dict[str, list[str]]:
    """``{topic: [publishing node, ...]}`` for those ``topics`` that have more than ``more_than`` publishers."""
    found = {}
    for topic in topics:
        infos = node.get_publishers_info_by_topic(topic)
        if len(infos) > more_than:
            found[topic] = sorted({full_name(i.node_namespace, i.node_name) for i in infos})
    return found


def foreign_publishers(node, topics, probe_s: float = PROBE_S) -> dict[str, list[str]]:
    """Publishers already on ``topics`` (before this run starts any), watched for up to ``probe_s``."""
    deadline = time.monotonic() + probe_s
    while not (found := publishers(node, topics)) and time.monotonic() < deadline:
        time.sleep(POLL_S)
    return found


def describe(found: dict[str, list[str]], domain: str, when: str = "already published") -> str:
    """One error message for the publishers ``found`` on domain ``domain`` (topics grouped by who publishes)."""
    by_who: dict[str, list[str]] = {}
    for topic, nodes in sorted(found.items()):
        by_who.setdefault(", ".join(nodes), []).append(topic)
    who = "; ".join(f"{', '.join(topics)} by {nodes}" for nodes, topics in by_who.items())
    return (
        f"ROS_DOMAIN_ID={domain} is in use: {who} {when}. A second rig or player on the same domain mixes its "
        "samples with this run's: stop it, or run this one with another ROS_DOMAIN_ID"
    )


class Watch:
    """During a run: a second publisher on one of this run's topics means an intruder (or a second rig).

    Two sources: this process's graph, polled every WATCH_PERIOD_S (every topic of the run), and the plant's and
    the controller's own counts of the publishers their input subscriptions matched (``amb_ros.matches``: from
    DDS match status, so a publisher that lived between two polls is found too), read from their /diagnostics."""

    LOOP_NODES = ("amb_plant", "amb_controller")

    def __init__(self, node, topics, domain: str, collector=None):
        self.node, self.topics, self.domain, self.collector = node, list(topics), domain, collector
        self._next = 0.0
        self.reported = False
        self._pending: dict[str, list[str]] = {}  # found, but a node not yet named: waiting for its name
        self._pending_since = 0.0

    def check(self) -> str | None:
        """An error message if an intruder is publishing, else None (graph looked at every WATCH_PERIOD_S).

        The graph can show a new endpoint before its node's name (ros_discovery_info comes separately): such a
        finding is held for up to NAME_GRACE_S until the name is known, then reported with what is known (also
        when the intruder has left meanwhile)."""
        now = time.monotonic()
        if now < self._next:
            return None
        self._next = now + WATCH_PERIOD_S
        found = {**self.matched(), **publishers(self.node, self.topics, more_than=1)}
        if found:
            if not self._pending:
                self._pending_since = now
            self._pending = found
        if not self._pending:
            return None
        if _unnamed(self._pending) and now < self._pending_since + NAME_GRACE_S:
            return None
        return self._report(self._pending)

    def final(self) -> list[str]:
        """After the run: the nodes' final counts (an intruder of the last moments), unless already reported."""
        msg = None if self.reported else self._report(self.matched() or self._pending)
        return [msg] if msg else []

    def matched(self) -> dict[str, list[str]]:
        """``{topic: [publisher seen, ...]}`` of the foreign publishers that the loop's nodes have matched."""
        found = {}
        for name in self.LOOP_NODES if self.collector is not None else ():
            values = (self.collector.get(name) or {}).get("values") or {}
            for topic in topics_with(values, "foreign publishers"):
                if per_topic("foreign publishers", topic).read(values):
                    seen = per_topic("publishers seen", topic).read(values) or "none left to name"
                    found[topic] = seen.split(", ")
        return found

    def _report(self, found: dict[str, list[str]]) -> str | None:
        if not found:
            return None
        self.reported = True
        return describe(found, self.domain, "joined this run")


def _unnamed(found: dict[str, list[str]]) -> bool:
    return any(full_name("", UNKNOWN_NAME) in nodes for nodes in found.values())
