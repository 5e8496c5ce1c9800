"""A run split across two amb-rig processes (two hosts, or a host and a real rig): options, locks, the peer's end.

``amb-rig run --only plant`` is the rig side alone (a stand-in for a real rig's I/O computer: it publishes
/amb/displacement and takes /amb/current); ``amb-rig run --no-plant`` is the host side (base_motion, controller,
monitor).  ``--discovery`` says how far DDS discovery reaches (``amb_ros.discovery``; localhost by default).

Who ends the run: in lockstep the plant (the clock master) after --duration of simulated time, and the host side
ends when the plant has finished (its final /diagnostics, or its /amb/displacement publisher gone); in realtime
the host side after --duration of wall time, and the plant side when the controller has left (its /amb/current
publisher gone) or after its own --duration, whichever comes first.  The plant then has seen the commands stop
once, at the end, and reports it (held, then zero current: what a real rig must do); amb-rig does not count that
one final loss as a failure when the controller had left, and says so in the summary.
"""

from __future__ import annotations

import secrets
import time

from amb_ros import messages as m
from amb_ros.discovery import CHOICES

SIDES = ("plant", "host")
PEER_POLL_S = 0.1
UNSEEN_GONE_AFTER_S = 6.0  # two of Fast DDS's 3 s participant announcement periods
ANSWERS_QUIET_S = 2.0  # host side: no publisher and no newly answered sample for this long (10 reports at 0.2 s)
PLANT_NODE = "amb_plant"
CONTROLLER_NODE = "amb_controller"


def add_arguments(r) -> None:
    """``--discovery`` and ``--only`` on the ``run`` subparser."""
    r.add_argument("--discovery", metavar="RANGE", help=f"DDS discovery: {CHOICES} (default: the environment's "
                   "ROS_AUTOMATIC_DISCOVERY_RANGE / ROS_STATIC_PEERS, LOCALHOST when unset)")  # fmt: skip
    r.add_argument("--only", choices=("plant",), help="only the rig side (the plant): the counterpart of --no-plant "
                   "on another host")  # fmt: skip
    r.add_argument("--no-base-motion", action="store_true", help="do not start base_motion: a real rig publishes "
                   "/base/imu (and /base/angular_acceleration) from its own IMU")  # fmt: skip
    r.add_argument("--run-token", metavar="TOKEN", help="the run token in header.frame_id of /amb/displacement and "
                   "/amb/current (letters, digits, _ and -; docs/topics.md): the plant and the controller reject "
                   "messages with another; default a random one, none in a split run unless both sides give "
                   "it")  # fmt: skip


def check(args) -> str | None:
    """An error message for contradictory options, else None (``--only plant`` implies --no-monitor; sets the
    run token: the given one, none in a split run without one, else a random one)."""
    token = getattr(args, "run_token", None)
    if token is not None and not m.RUN_TOKEN_RE.fullmatch(token):
        return "--run-token: only letters, digits, '_' and '-', at most 64 characters"
    if token is None:
        split_run = getattr(args, "only", None) == "plant" or args.no_plant
        args.run_token = "" if split_run else secrets.token_hex(8)
    if getattr(args, "only", None) == "plant":
        if args.no_plant:
            return "--only plant and --no-plant contradict each other (one side each)"
        if args.no_base_motion:
            return "--only plant starts no base_motion anyway: drop --no-base-motion"
        args.no_monitor = True  # the monitor runs on the host side, beside the controller
    elif args.no_base_motion and not args.no_plant:
        return "--no-base-motion needs --no-plant (the rig that measures the base motion also measures the rotor)"
    return None


def sides(args) -> tuple[str, ...]:
    """The sides of a run this amb-rig holds: both, or the plant's (--only plant) or the host's (--no-plant)."""
    if getattr(args, "only", None) == "plant":
        return ("plant",)
    return ("host",) if args.no_plant else SIDES


def hold_locks(hold_run_lock, domain: str, args, wait_s: float, on_wait) -> list:
    """The run locks of this run's sides (closed again if one of them is held by another run)."""
    held = []
    try:
        for side in sides(args):
            held.append(hold_run_lock(domain, wait_s, on_wait, side=side))
    except Exception:
        for fh in held:
            fh.close()
        raise
    return held


class PeerEnd:
    """Has the other side of a split run ended?  The host side watches the plant, the plant side the controller.

    A controller whose publisher the plant side has seen has gone when that publisher leaves this process's graph
    (at once: a realtime plant holds the last command only briefly).  On the host side a plant has gone when no
    /amb/displacement publisher is in the graph and the controller's count of answered samples has not grown for
    ANSWERS_QUIET_S: the publisher that vanished may be a killed earlier run's, lingering until its lease expired,
    while this run's plant, which this process has not discovered yet, is being answered.  A plant known only from
    the answered samples (this process's own discovery can lag the controller's by an announcement period) has
    gone when no publisher has appeared and the count has not grown for UNSEEN_GONE_AFTER_S."""

    def __init__(self, node, collector, args, clock=time.monotonic):
        self.node, self.collector, self.clock = node, collector, clock
        only_plant = getattr(args, "only", None) == "plant"
        self.active = (only_plant and args.mode == "realtime") or (args.no_plant and args.mode == "lockstep")
        self.owns_end = args.no_plant and args.mode == "lockstep"  # no wall-time end: the plant's end is the end
        self.topic = m.CURRENT if only_plant else m.DISPLACEMENT
        self.seen = False  # the peer was there: its publisher, or (host side) samples the controller answered
        self.saw_publisher = False
        self.reason = ""
        self._next = 0.0
        self._present_at: float | None = None  # when the peer last showed it was there
        self._answered = 0

    def ended(self) -> bool:
        """True once the peer was there and has gone (or, for a plant, reported that it finished)."""
        if not self.active or self.reason:
            return bool(self.reason)
        now = self.clock()
        if now < self._next:
            return False
        self._next = now + PEER_POLL_S
        count = len(self.node.get_publishers_info_by_topic(self.topic))
        diag = self.collector.get(PLANT_NODE) if self.topic == m.DISPLACEMENT else None
        answered = self._controller_answered()
        if count > 0 or answered != self._answered or self._present_at is None:
            self._present_at = now
        self._answered = answered
        self.saw_publisher = self.saw_publisher or count > 0
        self.seen = self.seen or count > 0 or answered > 0
        quiet = now - self._present_at
        if not self.saw_publisher:
            gone = quiet >= UNSEEN_GONE_AFTER_S
        else:
            gone = count == 0 and (self.topic == m.CURRENT or quiet >= ANSWERS_QUIET_S)
        if diag is not None and diag["final"] and diag["message"].startswith("finished"):
            self.reason = "the plant finished"
        elif self.seen and gone:
            self.reason = f"the other side left ({self.topic} has no publisher)"
        return bool(self.reason)

    def _controller_answered(self) -> int:
        """The samples the host side's controller has answered (0 on the plant side, or before its first report):
        proof that the plant was there, even if this process has not discovered its publisher (yet)."""
        if self.topic != m.DISPLACEMENT:
            return 0
        diag = self.collector.get(CONTROLLER_NODE)
        try:
            return int(float(diag["values"].get("samples answered", 0))) if diag is not None else 0
        except (KeyError, TypeError, ValueError):
            return 0


def forgive_final_loss(errors: list[str], peer: PeerEnd) -> tuple[list[str], list[str]]:
    """(errors, notes): the plant side's one loss of commands at the end, after the controller left, is a note."""
    if not (peer.active and peer.reason and peer.topic == m.CURRENT):
        return errors, []
    kept, notes = [], []
    for err in errors:
        if err.startswith("plant reported ERROR: commands stopped 1 time(s)"):
            notes.append(f"{err[len('plant reported ERROR: ') :]} (after {peer.reason}: the end of the run)")
        else:
            kept.append(err)
    return kept, notes
