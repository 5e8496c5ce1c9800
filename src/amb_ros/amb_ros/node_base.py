"""Common skeleton of the rig's nodes: parameters, mode, time step, diagnostics, message accounting.

Time base: the sample period is a whole number of nanoseconds, ``Ts_ns = round(1e9 / rate_hz)``, and every node
uses ``Ts = Ts_ns / 1e9`` and stamps ``t_k = k Ts_ns`` (exact integers), so that the plant, the controller, the
base motion and the offline simulation all agree on t_k bit for bit.
"""

from __future__ import annotations

import os

from rclpy.node import Node

from .diagnostics import Counters, Diagnostics
from .params import NodeParams, ParamSpec

MODES = ("lockstep", "realtime")


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
        ParamSpec("qos_depth", 1000, "history depth of the reliable lockstep topics", "samples", lo=1, hi=100000),
        ParamSpec(
            "rt_priority", 0, "SCHED_FIFO priority of every thread of the node (0 = normal scheduling)", "", 0, 99
        ),
        ParamSpec("diagnostics_period_s", 0.5, "wall time between /diagnostics messages", "s", lo=0.01, hi=60.0),
    ]


def _thread_ids() -> list[int]:
    try:
        return [int(t) for t in os.listdir("/proc/self/task")]
    except OSError:
        return [0]


def lower_priority(increment: int) -> str:
    """Add ``increment`` to the niceness of every thread of this process.

    ``os.nice`` changes the calling thread only (Linux niceness is per thread), and the DDS threads that receive
    every message were created before; a consumer beside the lockstep loop (monitor, recorder) must yield the CPU
    with all of them, or their wake-ups still compete with the loop.
    """
    tids = _thread_ids()
    for tid in tids:
        try:
            os.setpriority(os.PRIO_PROCESS, tid, min(19, os.getpriority(os.PRIO_PROCESS, tid) + increment))
        except OSError:  # a thread that has just ended
            continue
    return f"nice +{increment} ({len(tids)} threads)"


def idle_priority() -> str:
    """SCHED_IDLE for every thread of this process: it runs only on CPU time that no other thread wants.

    For a consumer that must not slow the lockstep loop (the recorder): besides yielding the CPU it makes its
    DDS receive threads wake later, so one wake-up takes several samples.  Threads created later inherit it.
    """
    tids = _thread_ids()
    for tid in tids:
        try:
            os.sched_setscheduler(tid, os.SCHED_IDLE, os.sched_param(0))
        except OSError:  # a thread that has just ended
            continue
    return f"SCHED_IDLE ({len(tids)} threads)"


def set_realtime_priority(priority: int) -> str:
    """SCHED_FIFO for every thread of this process: the node's loop and the DDS threads that deliver to it.

    A HIL loop needs it on a loaded machine: a timed wait is ~100 us late at the median and much more at the
    99th percentile under load, and a DDS receive thread at normal priority adds its own scheduling delay.
    The loops block between samples, so they do not starve the machine.  Returns a description for
    diagnostics; not permitted -> normal scheduling.
    """
    tids = _thread_ids()
    try:
        for tid in tids:
            os.sched_setscheduler(tid, os.SCHED_FIFO, os.sched_param(priority))
    except (PermissionError, OSError) as exc:
        return f"normal (SCHED_FIFO {priority} refused: {exc.strerror})"
    return f"SCHED_FIFO {priority} ({len(tids)} threads)"


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
        self.diag = Diagnostics(self, self.p["diagnostics_period_s"])
        self.scheduling = "normal"
        if self.p["rt_priority"] > 0:
            self.scheduling = set_realtime_priority(self.p["rt_priority"])

    def common_values(self) -> dict[str, str]:
        return {
            "mode": self.mode,
            "scheduling": self.scheduling,
            "rate (Hz)": f"{1e9 / self.Ts_ns:.6g}",
            "sample period (ns)": str(self.Ts_ns),
            **self.counters.values(),
        }
