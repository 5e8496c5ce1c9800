"""amb-rig's own process watch: a node's death is noticed at the next poll (50 ms) and named as the cause.

Without it a dead controller showed only when the plant's command timeout (10 s) ran out, and a dead
base_motion was reported through the plant's message about missing base samples, which reads like a
configuration problem.  The watch prints one line as soon as a required process exits on its own, gives the
survivors ``NOTICE_S`` to report what they saw (a realtime plant applies its command policy meanwhile), and
then the run stops with the death as its first error.
"""

from __future__ import annotations

import sys
import time

from .supervisor import Supervisor, describe_exit

NOTICE_S = 1.0  # after a death: time for the plant to report it before amb-rig stops the run (s)


class DeathWatch:
    """Polls a :class:`Supervisor` for required children that died; remembers the first cause."""

    def __init__(self, sup: Supervisor, notice_s: float = NOTICE_S):
        self.sup, self.notice_s = sup, notice_s
        self.first: str | None = None
        self.deadline: float | None = None
        self._seen: set[int] = set()

    def poll(self) -> bool:
        """True once the run should stop (a death was seen ``notice_s`` ago, or at once without a plant)."""
        for c in self.sup.died_early():
            if c.pid in self._seen:
                continue
            self._seen.add(c.pid)
            cause = f"{c.spec.name} died ({describe_exit(c.popen.returncode)})"
            last = c.last_line()
            if last and c.popen.returncode and c.popen.returncode > 0:
                cause += f": {last}"
            print(f"amb-rig: {cause}; stopping the run", file=sys.stderr, flush=True)
            if self.first is None:
                self.first = cause
                plant = self.sup.find("plant")
                wait = plant is not None and plant.poll() is None  # a living plant reports what it saw first
                self.deadline = time.monotonic() + (self.notice_s if wait else 0.0)
        return self.deadline is not None and time.monotonic() >= self.deadline
