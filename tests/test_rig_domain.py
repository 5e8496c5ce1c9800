"""One rig per DDS domain: a second amb-rig, a player or any other publisher of the rig's topics is refused.

Without the guards a second run on the same ROS_DOMAIN_ID matched the first one's readers: the plant stepped on
the other rig's commands (measured before the fix: 1,034 rejected commands, zero displacement, and the summary
still said OK).
"""

from __future__ import annotations

import os
import re
import time
from pathlib import Path

import pytest

from amb_bringup.domain import WATCH_PERIOD_S, Watch, describe, topics_of
from amb_ros import messages as m
from helpers import rig_json
from procs import spawn

pytestmark = pytest.mark.ros
PAPER = ["--config", str(Path(__file__).resolve().parents[1] / "config" / "seed_paper.yaml")]  # a fast plant


def test_second_rig_on_the_same_domain_is_refused_and_the_first_is_untouched(tmp_path, venv_bin):
    rig = str(venv_bin / "amb-rig")
    # long enough to outlast the second one's start and its wait for the domain (--lock-wait 2 s): about 10 s of
    # wall time on the paper's plant (the lock is the point here, not the physics)
    first = [rig, "run", "--duration", "4", "--no-monitor", "--json", "--log-dir", str(tmp_path / "first"), *PAPER]
    with spawn(first, tmp_path / "first.log") as proc:
        assert proc.wait_for("started plant", 60), proc.text()
        second_cmd = [rig, "run", "--duration", "1", "--no-monitor", "--lock-wait", "2"]
        with spawn(second_cmd, tmp_path / "second.log") as second:
            code = second.wait(60)
            text = second.text()
        assert code == 1, text
        assert proc.popen.poll() is None, proc.text()
        assert "waiting up to 2 s for the domain's other run" in text
        assert f"ROS_DOMAIN_ID={os.environ['ROS_DOMAIN_ID']} is used by another amb-rig run" in text
        assert re.search(rf"amb-rig pid {proc.popen.pid}\b", text), text
        assert "started" not in text and "Traceback" not in text  # refused before any node was spawned
        assert proc.wait(120) == 0, proc.text()
        s = rig_json(proc.text())
    assert s["ok"]
    plant = s["nodes"]["plant"]["values"]
    assert int(plant["steps"]) == 4 * s["rate_hz"]  # every step of the first run, none from the refused one
    assert plant["rejected total"] == "0"


def test_a_player_on_the_domain_fails_the_run_with_the_reason(tmp_path, venv_bin, repo):
    player = [str(venv_bin / "amb-bag"), "play", "--loop", "--rate", "0.1", str(repo / "bags" / "sample_pitch")]
    with spawn(player, tmp_path / "player.log") as play:
        time.sleep(2.0)  # the player is publishing
        assert play.popen.poll() is None, play.text()
        rig = [str(venv_bin / "amb-rig"), "run", "--duration", "2", "--no-monitor", "--log-dir", str(tmp_path / "l")]
        with spawn(rig, tmp_path / "rig.log") as proc:
            code = proc.wait(120)
            text = proc.text()
    assert code == 1, text
    assert "[OK]" not in text and "Traceback" not in text
    # found before the start (discovery was quick) or while running (the watch): the same reason either way
    line = next(ln for ln in text.splitlines() if "is in use:" in ln)
    assert f"ROS_DOMAIN_ID={os.environ['ROS_DOMAIN_ID']} is in use:" in line
    assert any(topic in line for topic in topics_of(["base_motion", "controller", "plant"])), line


@pytest.fixture
def two_nodes():
    import rclpy

    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    nodes = [rclpy.create_node(name, context=ctx) for name in ("watch_a", "watch_b")]
    yield nodes
    for node in nodes:
        node.destroy_node()
    rclpy.shutdown(context=ctx)


def test_watch_counts_publishers_per_topic(two_nodes):
    """Watch reports a topic only once it has a second publisher, naming both nodes."""
    from sensor_msgs.msg import JointState

    a, b = two_nodes
    watch = Watch(a, [m.CURRENT, m.DISPLACEMENT], "7")
    a.create_publisher(JointState, m.CURRENT, 10)
    a.create_publisher(JointState, m.DISPLACEMENT, 10)
    time.sleep(1.0)
    assert watch.check() is None  # one publisher per topic: this run's own
    b.create_publisher(JointState, m.CURRENT, 10)
    end, message = time.monotonic() + 10, None
    while message is None and time.monotonic() < end:
        time.sleep(WATCH_PERIOD_S)
        message = watch.check()
    assert message == describe({m.CURRENT: ["/watch_a", "/watch_b"]}, "7", "joined this run")
    assert m.DISPLACEMENT not in message


def test_topics_of_the_spawned_nodes():
    assert topics_of(["plant"]) == sorted([m.DISPLACEMENT, m.STATE, m.CLOCK])
    # --no-plant: a real rig's /amb/displacement is expected, not an intruder
    assert m.DISPLACEMENT not in topics_of(["base_motion", "controller", "recorder"])


class _Graph:
    """A stand-in for a node's graph: ``publishers[topic]`` is a list of (namespace, name)."""

    def __init__(self):
        self.publishers: dict[str, list[tuple[str, str]]] = {}

    def get_publishers_info_by_topic(self, topic):
        from types import SimpleNamespace

        return [SimpleNamespace(node_namespace=ns, node_name=n) for ns, n in self.publishers.get(topic, [])]


def _watch_until(watch, seconds: float) -> tuple[str | None, float]:
    t0 = time.monotonic()
    while time.monotonic() < t0 + seconds:
        if message := watch.check():
            return message, time.monotonic() - t0
        time.sleep(0.02)
    return None, time.monotonic() - t0


@pytest.mark.parametrize("then", ["named", "never named", "gone"])
def test_watch_waits_briefly_for_an_intruders_node_name(then):
    """The graph shows a new endpoint before its node's name (seen in CI: "by /amb_plant, a node not yet
    named"): the report waits up to NAME_GRACE_S for the name; a name never known, or an intruder that has left,
    is still reported when the grace ends."""
    from amb_bringup.domain import NAME_GRACE_S
    from amb_ros.matches import UNKNOWN_NAME

    graph = _Graph()
    graph.publishers[m.DISPLACEMENT] = [("/", "amb_plant"), ("/", UNKNOWN_NAME)]
    watch = Watch(graph, [m.DISPLACEMENT], "7")
    assert watch.check() is None  # held: not named yet
    named_after = 0.4
    time.sleep(named_after)
    if then == "named":
        graph.publishers[m.DISPLACEMENT] = [("/", "amb_plant"), ("/", "intruder")]
    elif then == "gone":
        graph.publishers[m.DISPLACEMENT] = [("/", "amb_plant")]
    message, waited = _watch_until(watch, 3.0)
    # gone: reported as it was seen, with what was known of it
    who = "/amb_plant, /intruder" if then == "named" else "/amb_plant, a node not yet named"
    assert message == describe({m.DISPLACEMENT: who.split(", ")}, "7", "joined this run")
    if then == "named":  # reported at the first look after the name arrived, not at the end of the grace
        assert waited < NAME_GRACE_S - named_after
    else:
        assert NAME_GRACE_S - named_after - 0.05 < waited < NAME_GRACE_S - named_after + 2 * WATCH_PERIOD_S
