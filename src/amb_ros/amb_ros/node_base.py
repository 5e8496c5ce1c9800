"""Common skeleton of the rig's nodes: parameters, mode, time step, diagnostics, message accounting.

Time base: the sample period is a whole number of nanoseconds, ``Ts_ns = round(1e9 / rate_hz)``, and every node
uses ``Ts = Ts_ns / 1e9`` and stamps ``t_k = k Ts_ns`` (exact integers), so that the plant, the controller, the
base motion and the offline simulation all agree on t_k bit for bit.
"""

from __future__ import annotations

import time

from rclpy.duration import Duration
from rclpy.node import Node

from amb_dynamics.errors import InputError

from .diagnostics import Counters, Diagnostics
from .matches import PublisherMatches
from .messages import RUN_TOKEN_RE
from .params import NodeParams, ParamSpec
from .scheduling import set_realtime_priority

MODES = ("lockstep", "realtime")
ACK_TIMEOUT_S = 5.0  # longest wait at exit for slow readers to acknowledge the last samples


def sample_period_ns(rate_hz: float) -> int:
    """Sample period in whole ns for ``rate_hz``."""
    return max(1, round(1e9 / rate_hz))


def common_specs() -> list[ParamSpec]:
    return [
        ParamSpec("mode", "lockstep", "time mode: lockstep (plant is /clock master) or realtime", choices=MODES),
        ParamSpec(
            "rate_hz",
            None,
            "sample rate of the loop",
            "Hz",
            lo=1.0,
            hi=1.0e6,
            config_key="controller.rate_hz",
        ),
        ParamSpec(
            "qos_depth",
            1000,
            "history depth of the reliable lockstep topics (and of the monitor's realtime reader)",
            "samples",
            lo=1,
            hi=100000,
        ),
        ParamSpec(
            "rt_priority", 0, "SCHED_FIFO priority of every thread of the node (0 = normal scheduling)", "", 0, 99
        ),
        ParamSpec("diagnostics_period_s", 0.5, "wall time between /diagnostics messages", "s", lo=0.01, hi=60.0),
        ParamSpec(
            "min_diagnostics_readers",
            0,
            "readers of /diagnostics that the final report waits for (at most "
            "2 s; the plant also before starting; amb-rig: 1, its collector)",
            "",
            0,
            100,
        ),
        ParamSpec(
            "diagnostics_collector",
            "",
            "node name of amb-rig's collector: the final report (and the plant's start) also waits until it is "
            "matched (empty: only the count above)",
        ),
    ]


def run_token_spec() -> ParamSpec:
    """The run token of the loop's two topics (controller and plant): docs/topics.md."""
    return ParamSpec("run_token", "", "per-run token in header.frame_id of /amb/displacement and /amb/current; "
                     "messages with another token are rejected and counted as foreign (amb-rig sets a random one; "
                     "empty: none sent, any accepted)")  # fmt: skip


def run_token(node: RigNode) -> str | None:
    """The node's run token (None: accept any), checked: letters, digits, '_' and '-', at most 64."""
    token = node.p["run_token"]
    if not RUN_TOKEN_RE.fullmatch(token):
        raise InputError("run_token: only letters, digits, '_' and '-', at most 64 characters")
    return token or None


class RigNode(Node):
    """A node of the rig; subclasses declare their own ``specs()`` and implement ``run()`` -> exit code."""

    def __init__(self, name: str, stop, specs: list[ParamSpec]):
        super().__init__(name)
        self.stop = stop
        self.params = NodeParams(self)
        self.p = self.params.declare(common_specs() + specs)
        self.params.check_unknown()
        self.cfg = self.params.config
        self.mode = self.p["mode"]
        self.Ts_ns = sample_period_ns(self.p["rate_hz"])
        self.Ts = self.Ts_ns / 1e9
        self.counters = Counters()
        self.matches = PublisherMatches(self)  # publishers matched by the input subscriptions (matches.py)
        self.diag = Diagnostics(
            self, self.p["diagnostics_period_s"], self.p["min_diagnostics_readers"], self.p["diagnostics_collector"]
        )
        self.scheduling = "normal"  # SCHED_FIFO from enter_loop_scheduling(), once the node is built

    def enter_loop_scheduling(self) -> None:
        """SCHED_FIFO at ``rt_priority`` for every thread, from here on (0: normal scheduling stays).

        Called by :func:`amb_ros.runtime.run_node` between building the node and its loop, not at the start of
        the build: building a model and warming up a step (a second of CPU and more on a slow machine) at
        SCHED_FIFO would run ahead of everything at normal priority, and of the other nodes' loops at the same
        priority, which a realtime plant may already be ticking (it starts once its peers' topics are matched,
        before their own builds end).  The DDS threads that exist by then are included (every thread of the
        process); threads created later inherit the setting."""
        if self.p["rt_priority"] > 0:
            self.scheduling = set_realtime_priority(self.p["rt_priority"])

    def destroy_node(self) -> None:
        """Release first what rclpy does not track: the loop's wait set (it holds the subscriptions it last waited
        on) and the match-status event handles.  Each keeps its subscription, the node and the node's DDS
        participant alive past the shutdown, which amb_ros.runtime.exit_process relies on to delete the
        participant (tests/test_runtime_teardown.py)."""
        waiter = getattr(self, "waiter", None)
        if waiter is not None:
            waiter.close()
        self.matches.close()
        super().destroy_node()

    def deliver_pending(self, *pubs, timeout_s: float = ACK_TIMEOUT_S) -> None:
        """Before the node exits: wait (``timeout_s`` in all) until every reliable reader has acknowledged the
        last samples of ``pubs`` (None entries skipped).  A slow reader (recorder, monitor) still takes samples
        after the loop ends; when the process exits, its writer's history goes with it and they are lost."""
        deadline = time.monotonic() + timeout_s
        for pub in pubs:
            if pub is not None:
                pub.wait_for_all_acked(Duration(seconds=max(0.01, deadline - time.monotonic())))

    def common_values(self) -> dict[str, str]:
        return {
            "mode": self.mode,
            "scheduling": self.scheduling,
            "rate (Hz)": f"{1e9 / self.Ts_ns:.6g}",
            "sample period (ns)": str(self.Ts_ns),
            **self.counters.values(),
            **self.matches.values(),
        }
