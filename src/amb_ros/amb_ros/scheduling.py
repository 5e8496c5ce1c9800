"""Scheduling of every thread of a process (Linux policy and niceness are per thread; ROS-free).

The DDS threads that receive each message exist before a node changes its priority, so each helper walks
/proc/self/task instead of changing the calling thread only; threads created later inherit the caller's setting.
"""

from __future__ import annotations

import os


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


PRIORITIES = ("idle", "low", "normal")  # a consumer beside the loop: SCHED_IDLE, niceness +LOW_NICENESS, unchanged
LOW_NICENESS = 5


def consumer_priority(priority: str) -> str:
    """Schedule every thread of a consumer beside the loop (monitor, recorder) as ``priority`` (PRIORITIES)."""
    if priority == "idle":
        return idle_priority()
    if priority == "low":
        return lower_priority(LOW_NICENESS)
    if priority != "normal":
        raise ValueError(f"unknown priority {priority!r} (choose {', '.join(PRIORITIES)})")
    return "normal"


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
