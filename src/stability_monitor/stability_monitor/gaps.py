"""Samples missing from a stream stamped on a grid of period Ts: what the monitor reports as ``samples lost``.

In lockstep the stamps are exact, t_k = k Ts_ns.  In realtime they are the plant's (or a real rig's) clock when
each sample went out: a late tick moves one stamp by up to a period without any sample being missing, and that
clock may run a little faster or slower than Ts says (NTP slews the system clock by up to 500 ppm).  Counting
round(gap / Ts) - 1 per gap turns a single tick 0.86 Ts late into "1 lost" (seen in 1 kHz realtime runs, which
then withheld their stability verdict).  Here each segment of the stream (a plant restart starts a new one) has a
grid origin; a sample's index is round((t - origin) / Ts), and the loss is the newest index + 1 minus the samples
received: a late sample is followed by one on time and the count comes back, a lost block stays lost.  The
origin follows the clock's drift by ``TRACK`` of each sample's phase error (a slow phase-locked loop; white
jitter averages out over 1 / TRACK samples).
"""

from __future__ import annotations

TRACK = 0.01  # fraction of each sample's phase error (in periods) taken into the grid origin


class SampleGaps:
    """Missing samples of one stream of period ``Ts_ns`` (ns), over all its segments."""

    def __init__(self, Ts_ns: int):
        if Ts_ns <= 0:
            raise ValueError("sample period must be positive")
        self.Ts_ns = Ts_ns
        self._before = 0  # lost in the segments that ended
        self._origin: float | None = None  # ns, grid origin of this segment
        self._last: int | None = None
        self._index = 0  # grid index of the newest sample
        self._count = 0  # samples received in this segment

    def add(self, t_ns: int) -> None:
        """One sample stamped ``t_ns``; a stamp not after the previous one starts a new segment (a restart)."""
        if self._last is None or t_ns <= self._last:
            self._before = self.lost
            self._origin, self._index, self._count = float(t_ns), 0, 1
            self._last = t_ns
            return
        position = (t_ns - self._origin) / self.Ts_ns
        index = max(self._index, round(position))  # a late stamp and the next, on time, may share an index
        self._origin += TRACK * (position - round(position)) * self.Ts_ns
        self._index, self._last = index, t_ns
        self._count += 1

    @property
    def lost(self) -> int:
        """Samples missing so far (the current segment's count can go back down after a late sample)."""
        if self._origin is None:
            return 0
        return self._before + max(0, self._index + 1 - self._count)
