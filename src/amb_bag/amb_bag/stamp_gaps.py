"""The recorder's own loss count on the per-step topics: gaps in header stamps that lie on a time grid.

/amb/displacement and /amb/current carry one message per controller sample, stamped t_k = k Ts (the plant's
and the controller's clocks are the run's /clock in lockstep and the sample clock in realtime).  The recorder
does not need anyone's /diagnostics to see that it missed some: between the first and the latest stamp it
received, the grid holds ``round((last - first) / Ts) + 1`` samples, and ``Ts`` is the smallest step between
two successive stamps.  What is missing before the first or after the last stamp received is not seen here
(the publishers' counts in /diagnostics cover that).  Duplicates and stamps older than the latest are not
counted as received samples.
"""

from __future__ import annotations

import struct

GRID_TOPICS = frozenset({"/amb/displacement", "/amb/current"})
_LE = struct.Struct("<iI")
_BE = struct.Struct(">iI")


def stamp_ns(cdr: bytes) -> int | None:
    """``header.stamp`` of a serialized message whose first field is a std_msgs/Header (ns), or None."""
    if len(cdr) < 12:
        return None
    sec, nanosec = (_LE if cdr[1] == 1 else _BE).unpack_from(cdr, 4)  # after the 4-byte encapsulation header
    return sec * 1_000_000_000 + nanosec


class StampGaps:
    """Per topic: first and latest stamp, samples received on the grid, and the grid step."""

    def __init__(self):
        self.first: dict[str, int] = {}
        self.last: dict[str, int] = {}
        self.count: dict[str, int] = {}
        self.step: dict[str, int] = {}

    def add(self, topic: str, cdr: bytes) -> None:
        ns = stamp_ns(cdr)
        if ns is None:
            return
        last = self.last.get(topic)
        if last is None:
            self.first[topic] = self.last[topic] = ns
            self.count[topic] = 1
            return
        if ns <= last:
            return  # a duplicate or a late sample: not a new point of the grid
        d = ns - last
        self.step[topic] = min(self.step.get(topic, d), d)
        self.last[topic] = ns
        self.count[topic] += 1

    def missing(self) -> dict[str, int]:
        """Samples missing between the first and the latest stamp, per topic (0 with fewer than 2 samples)."""
        out = {}
        for topic, n in self.count.items():
            step = self.step.get(topic)
            expected = round((self.last[topic] - self.first[topic]) / step) + 1 if step else n
            out[topic] = max(0, expected - n)
        return out
