"""A run split across two amb-rig processes: which nodes each side starts, its gates and locks, and when it ends."""

from __future__ import annotations

import subprocess

import pytest

from amb_bringup import split
from amb_bringup.processes import node_parameters, node_specs
from amb_bringup.rig import parser
from amb_ros import messages as m


def parsed(*argv: str):
    args = parser().parse_args(["run", *argv])
    assert split.check(args) is None
    return args


@pytest.mark.parametrize(
    ("argv", "names", "sides"),
    [
        ((), ["base_motion", "controller", "plant"], ("plant", "host")),
        (("--only", "plant"), ["plant"], ("plant",)),
        (("--no-plant",), ["base_motion", "controller"], ("host",)),
        (("--no-plant", "--no-base-motion"), ["controller"], ("host",)),
    ],
)
def test_each_side_starts_its_own_nodes_and_holds_its_own_lock(tmp_path, argv, names, sides):
    args = parsed(*argv)
    assert [s.name for s in node_specs(args, tmp_path)] == names
    assert split.sides(args) == sides


def test_the_plant_side_waits_for_the_remote_controller_only():
    args = parsed("--only", "plant")
    assert args.no_monitor  # the monitor belongs to the host side
    _, per = node_parameters(args)
    assert per["plant"]["min_subscribers"] == 1 and per["plant"]["min_state_subscribers"] == 0
    _, per = node_parameters(parsed("--only", "plant", "--bag", "b"))
    assert per["plant"]["min_subscribers"] == 2  # + the recorder beside it


@pytest.mark.parametrize(
    "argv", [("--only", "plant", "--no-plant"), ("--no-base-motion",), ("--only", "plant", "--no-base-motion")]
)
def test_contradictions_are_refused_with_one_line_and_exit_2(venv_bin, argv):
    out = subprocess.run([str(venv_bin / "amb-rig"), "run", *argv], capture_output=True, text=True, timeout=60)
    lines = [ln for ln in (out.stdout + out.stderr).splitlines() if ln.strip()]
    assert out.returncode == 2 and len(lines) == 1 and lines[0].startswith("amb-rig: --"), out


class FakeGraph:
    def __init__(self):
        self.count, self.diag, self.others = 0, None, {}

    def get_publishers_info_by_topic(self, topic):
        return [object()] * self.count

    def get(self, node):
        return self.others.get(node, self.diag)


class Clock:
    """A monotonic clock the test moves by hand."""

    def __init__(self):
        self.t = 100.0

    def __call__(self):
        return self.t

    def advance(self, dt):
        self.t += dt


def test_the_plant_side_ends_when_the_controller_has_left():
    graph, clock = FakeGraph(), Clock()
    peer = split.PeerEnd(graph, graph, parsed("--only", "plant", "--mode", "realtime"), clock=clock)
    assert peer.active and not peer.owns_end and peer.topic == m.CURRENT
    assert not peer.ended()  # never there yet: still starting
    clock.advance(60.0)
    assert not peer.ended()  # however long: a controller that never came has not left
    graph.count = 1
    clock.advance(0.1)
    assert not peer.ended()
    graph.count = 0
    clock.advance(0.1)
    assert peer.ended() and "left" in peer.reason  # at once: the plant holds the last command only briefly
    errors = ["plant reported ERROR: commands stopped 1 time(s): held 10 samples, then zero current for 3 samples",
              "controller exited unexpectedly"]  # fmt: skip
    kept, notes = split.forgive_final_loss(errors, peer)
    assert kept == ["controller exited unexpectedly"] and len(notes) == 1 and "end of the run" in notes[0]
    # a loss in mid-run (more than the final one) stays an error
    many = ["plant reported ERROR: commands stopped 2 time(s): held 10 samples, then zero current for 3 samples"]
    assert split.forgive_final_loss(many, peer) == (many, [])


def test_the_host_side_in_lockstep_ends_when_the_plant_has_finished():
    graph, clock = FakeGraph(), Clock()
    peer = split.PeerEnd(graph, graph, parsed("--no-plant"), clock=clock)
    assert peer.active and peer.owns_end and peer.topic == m.DISPLACEMENT
    graph.count = 1
    graph.diag = {"final": False, "message": "running: 10 steps"}
    assert not peer.ended()
    graph.diag = {"final": True, "message": "finished: 500 steps"}
    clock.advance(0.1)
    assert peer.ended() and peer.reason == "the plant finished"
    assert split.forgive_final_loss(["plant reported ERROR: commands stopped 1 time(s)"], peer)[1] == []
    # realtime host side and full rigs: amb-rig's own --duration ends the run
    assert not split.PeerEnd(graph, graph, parsed("--no-plant", "--mode", "realtime")).active
    assert not split.PeerEnd(graph, graph, parsed()).active


def test_the_host_side_ends_when_a_plant_it_never_discovered_itself_has_gone():
    """A short lockstep run can end before amb-rig's own node discovers the remote plant, and its final report can be
    lost: the controller's answered samples prove the plant was there, so their end, with no publisher in sight for
    UNSEEN_GONE_AFTER_S, means it has gone."""
    graph, clock = FakeGraph(), Clock()
    peer = split.PeerEnd(graph, graph, parsed("--no-plant"), clock=clock)
    controller = {"final": False, "message": "running", "values": {"samples answered": "0"}}
    graph.others["amb_controller"] = controller
    assert not peer.ended()  # no plant yet, and nothing answered: still starting
    clock.advance(30.0)
    assert not peer.ended()
    controller["values"]["samples answered"] = "501"
    clock.advance(0.1)
    assert not peer.ended() and peer.seen and not peer.saw_publisher
    clock.advance(split.UNSEEN_GONE_AFTER_S - 0.2)
    assert not peer.ended()  # this process has not discovered the plant (yet): not gone
    controller["values"]["samples answered"] = "900"
    clock.advance(0.3)
    assert not peer.ended()  # the controller still answers it: the plant is there, whatever this graph says
    clock.advance(split.UNSEEN_GONE_AFTER_S - 0.2)
    assert not peer.ended()
    clock.advance(0.3)
    assert peer.ended() and "has no publisher" in peer.reason


def test_a_plant_seen_by_the_controller_first_is_not_taken_for_gone():
    """The race of the two-host lockstep run: the controller answers the remote plant before amb-rig's own node has
    discovered the plant's publisher; one poll later the plant must not be declared gone."""
    graph, clock = FakeGraph(), Clock()
    peer = split.PeerEnd(graph, graph, parsed("--no-plant"), clock=clock)
    graph.others["amb_controller"] = {"final": False, "message": "running", "values": {"samples answered": "40"}}
    for _ in range(20):
        clock.advance(split.PEER_POLL_S)
        assert not peer.ended()
    graph.count = 1  # discovered now
    clock.advance(split.PEER_POLL_S)
    assert not peer.ended() and peer.saw_publisher


def test_the_host_side_outlives_a_stale_plant_publisher_while_the_controller_answers():
    """A killed earlier run's /amb/displacement publisher lingers in the graph until its lease expires; when it
    vanishes, this run's plant (not yet discovered by amb-rig's own node) is still being answered: not an end.
    When the answers stop too, the plant has gone after ANSWERS_QUIET_S."""
    graph, clock = FakeGraph(), Clock()
    peer = split.PeerEnd(graph, graph, parsed("--no-plant"), clock=clock)
    controller = {"final": False, "message": "running", "values": {"samples answered": "0"}}
    graph.others["amb_controller"] = controller
    graph.count = 1  # the stale publisher
    assert not peer.ended()
    for answered in (300, 600, 900, 1200, 1500):
        controller["values"]["samples answered"] = str(answered)
        graph.count = 0  # the stale one has gone; this run's plant is not in this process's graph
        clock.advance(split.ANSWERS_QUIET_S / 2)
        assert not peer.ended()
    clock.advance(split.ANSWERS_QUIET_S - 0.2)  # the last answer was 0.2 s short of the quiet time ago
    assert not peer.ended()
    clock.advance(0.3)
    assert peer.ended() and "has no publisher" in peer.reason
