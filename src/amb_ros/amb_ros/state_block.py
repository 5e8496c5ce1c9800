"""Blocks of consecutive samples per message: /amb_plant/state (the plant's state) and /base/rates (lockstep).

Layout (trajectory_msgs/JointTrajectory, documented for users in docs/topics.md):

- ``header.stamp`` = stamp of the block's first sample (lockstep t_k = k Ts; realtime: the sample's system time)
- ``joint_names`` = generalised coordinates of the core's model (``mode1..modeN`` or FE DOFs)
- ``points[i]``: ``positions`` = q, ``velocities`` = dq/dt of sample i, ``time_from_start`` = its stamp minus the
  header stamp (integer ns, strictly increasing); ``accelerations`` and ``effort`` empty

One message per ``state_block`` samples instead of one per sample: every extra reader of a per-step topic (the
monitor, the recorder) costs the lockstep loop a DDS delivery and a wake-up per step, which on a small machine is
most of what they cost (measured in ``make bench``); a block costs that once per ``state_block`` steps.  The last
block of a run (or of a failed run) holds the samples that are left, so that no sample is ever missing.

/base/rates has the same layout with ``joint_names`` = ``omega_x, omega_y, omega_z``: positions = the base's
angular velocity Omega, velocities = its derivative dOmega/dt (base axes), one point per lockstep sample.
"""

from __future__ import annotations

import numpy as np
from builtin_interfaces.msg import Duration
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from .codec import TemplateCodec, stamp_ns
from .messages import Rejected


def state_block_codec(names: tuple[str, ...], count: int) -> TemplateCodec:
    """Fixed-layout codec of a block of ``count`` samples of ``names``: values = rows [q_i, dq_i] flattened,
    time fields = time_from_start of each point."""
    n = len(names)
    template = JointTrajectory(joint_names=list(names))
    template.points = [JointTrajectoryPoint(positions=[0.0] * n, velocities=[0.0] * n) for _ in range(count)]

    def set_values(msg, values):
        for i, point in enumerate(msg.points):
            row = values[2 * n * i : 2 * n * (i + 1)]
            point.positions = [float(v) for v in row[:n]]
            point.velocities = [float(v) for v in row[n:]]

    def set_times(msg, pairs):
        for point, (sec, nanosec) in zip(msg.points, pairs, strict=True):
            point.time_from_start = Duration(sec=sec, nanosec=nanosec)

    return TemplateCodec(JointTrajectory, template, [(set_values, 2 * n * count)], times=(set_times, count))


class StateBlockWriter:
    """Collects the plant's samples and returns the CDR bytes of a block when ``count`` samples are in."""

    def __init__(self, names: tuple[str, ...], count: int):
        self.names, self.count = tuple(names), count
        self.codec = state_block_codec(self.names, count)
        self.rows = np.zeros((count, 2 * len(self.names)))
        self.stamps = np.zeros(count, dtype=np.int64)
        self.filled = 0

    def reset(self) -> None:
        """Drop the samples collected so far (the sequence restarts)."""
        self.filled = 0

    def add(self, t_ns: int, x: np.ndarray) -> bytes | None:
        """Store sample (t_ns, x = [q; dq]); the block's bytes when it is full, else None."""
        self.rows[self.filled] = x
        self.stamps[self.filled] = t_ns
        self.filled += 1
        return self.flush() if self.filled == self.count else None

    def flush(self) -> bytes | None:
        """The bytes of the samples collected so far (a shorter block at the end of a run), or None if none."""
        k = self.filled
        if k == 0:
            return None
        self.filled = 0
        codec = self.codec if k == self.count else state_block_codec(self.names, k)
        t0 = int(self.stamps[0])
        return codec.encode(t0, self.rows[:k], self.stamps[:k] - t0)


class StateBlockDecoder:
    """Decode a block into (stamps ns (N,), rows (N, 2n) = [q, dq]) or raise :class:`Rejected`.

    ``names`` = the expected coordinates (a permutation is reordered; JointTrajectory names identify the columns);
    blocks of ``count`` samples take the fixed-layout fast path, any other valid block the rclpy slow path.
    """

    def __init__(self, names: tuple[str, ...], count: int):
        self.names = tuple(names)
        self.codec = state_block_codec(self.names, count)

    def __call__(self, raw: bytes) -> tuple[np.ndarray, np.ndarray]:
        n = len(self.names)
        out = self.codec.decode(raw)
        if out is not None:
            t0, flat = out
            stamps, rows = t0 + self.codec.times(raw), flat.reshape(-1, 2 * n)
        else:
            try:
                msg = self.codec.deserialize(raw)
            except Exception as exc:  # a buffer rclpy cannot parse is a rejected message, not a crash
                raise Rejected(f"undecodable JointTrajectory ({exc})") from None
            stamps, rows = block_of(msg, self.names)
        if rows.shape[0] == 0:  # a decoder learnt from an empty block decodes empty blocks
            raise Rejected("block without points")
        if not np.isfinite(rows).all():
            raise Rejected("non-finite value")
        if stamps[0] < 0:
            raise Rejected("negative stamp")
        if rows.shape[0] > 1 and not (np.diff(stamps) > 0).all():
            raise Rejected("time_from_start not strictly increasing")
        return stamps, rows


def block_of(msg: JointTrajectory, names: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray]:
    """(stamps, rows) of a deserialized block, checked against ``names``; raises :class:`Rejected`."""
    got = list(msg.joint_names)
    if sorted(got) != sorted(names) or len(got) != len(names):
        raise Rejected(f"joint names {got[:4]}{'...' if len(got) > 4 else ''} (expected {len(names)}: "
                       f"{list(names[:4])}...)")  # fmt: skip
    if not msg.points:
        raise Rejected("block without points")
    order = [got.index(nm) for nm in names]
    n = len(names)
    rows = np.empty((len(msg.points), 2 * n))
    stamps = np.empty(len(msg.points), dtype=np.int64)
    t0 = stamp_ns(msg.header.stamp)
    for i, point in enumerate(msg.points):
        if len(point.positions) != n or len(point.velocities) != n:
            raise Rejected(f"point {i} has {len(point.positions)} positions and {len(point.velocities)} velocities "
                           f"for {n} names")  # fmt: skip
        rows[i, :n] = np.asarray(point.positions)[order]
        rows[i, n:] = np.asarray(point.velocities)[order]
        stamps[i] = t0 + stamp_ns(point.time_from_start)
    return stamps, rows
