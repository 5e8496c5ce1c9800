"""Fast CDR encoding and decoding of fixed-layout messages (the lockstep hot path).

A message whose strings and sequence lengths never change (a JointState with fixed channel names, an Imu with a
fixed frame id, a JointTrajectory block of a fixed number of points) has a fixed CDR layout: only the header stamp,
the float64 fields and (optionally) builtin Duration/Time fields vary.  ``TemplateCodec``
serializes one template message with rclpy, finds the byte offset of every varying float64 by writing unique
sentinel values, and then encodes by patching a copy of the template and decodes by gathering those bytes.
That is 3-5x cheaper than rclpy's message conversion, and exactly the bytes rclpy would produce.

Decoding is strict: a buffer whose fixed part differs from the template (other names, sizes, frame id or byte
order) is not decoded here; ``decode`` returns None and the caller falls back to ``rclpy`` deserialization and
full validation, so a foreign but valid message is still understood and a malformed one is rejected.
"""

from __future__ import annotations

import struct

import numpy as np
from rclpy.serialization import deserialize_message, serialize_message

CDR_HEADER = 4  # encapsulation header (byte order, options) before the payload
STAMP_OFFSET = CDR_HEADER  # std_msgs/Header comes first: int32 sec, uint32 nanosec
NS_PER_S = 1_000_000_000
TIME_DTYPE = np.dtype([("sec", "<i4"), ("nanosec", "<u4")])  # builtin_interfaces Time/Duration in CDR


def split_ns(ns: int) -> tuple[int, int]:
    """(sec, nanosec) of an integer time in ns, as builtin_interfaces/Time stores it."""
    return ns // NS_PER_S, ns % NS_PER_S


def stamp_ns(stamp) -> int:
    """Integer ns of a builtin_interfaces/Time."""
    return stamp.sec * NS_PER_S + stamp.nanosec


class TemplateCodec:
    """Encode/decode messages of one fixed layout whose only varying parts are the stamp and float64 fields.

    Parameters
    ----------
    msg_type : ROS message class
    template : instance of msg_type with the fixed content (names, frame id, sequence sizes)
    fields : list of (setter, count): ``setter(msg, values)`` writes ``count`` float64 values into the message.
        The varying values are the concatenation of all fields, in order.
    stamped : bool, the message starts with a std_msgs/Header whose stamp varies
    times : (setter, count) or None: ``setter(msg, pairs)`` writes ``count`` (sec, nanosec) pairs into
        builtin_interfaces Duration/Time fields that vary too (e.g. JointTrajectoryPoint.time_from_start)
    """

    def __init__(self, msg_type, template, fields, stamped: bool = True, times=None):
        self.msg_type, self.stamped = msg_type, stamped
        self.size = sum(count for _, count in fields)
        self.n_times = times[1] if times else 0
        sentinels = _sentinels(self.size)
        pos = 0
        for setter, count in fields:
            setter(template, sentinels[pos : pos + count])
            pos += count
        time_sentinels = [_time_sentinel(j) for j in range(self.n_times)]
        if times:
            times[0](template, time_sentinels)
        raw = serialize_message(template)
        if raw[:2] != b"\x00\x01":  # CDR little endian: the only byte order the offsets below are valid for
            raise RuntimeError("rmw serializes big-endian CDR; TemplateCodec supports little-endian only")
        fixed = np.zeros(len(raw), dtype=bool)
        end = _mark_used(template, fixed, CDR_HEADER)
        fixed[:CDR_HEADER] = True
        if end > len(raw):
            raise RuntimeError(f"CDR layout walk of {msg_type.__name__} disagrees with rclpy's serialization")
        # Padding and the buffer's tail are uninitialised memory, which may hold a sentinel of an earlier
        # serialization (seen once: a plant that failed to start): search the bytes the layout uses only.
        raw = np.where(fixed, np.frombuffer(raw, dtype=np.uint8), 0).astype(np.uint8).tobytes()
        offsets = []
        for value in sentinels:
            pattern = struct.pack("<d", value)
            at = raw.find(pattern)
            if at < 0 or raw.find(pattern, at + 1) >= 0:
                raise RuntimeError(f"cannot locate field bytes of {msg_type.__name__} in its CDR layout")
            offsets.append(at)
        self.gather = (np.asarray(offsets, dtype=np.intp)[:, None] + np.arange(8)).reshape(-1)
        time_offsets = []
        for pair in time_sentinels:
            pattern = struct.pack("<iI", *pair)
            at = raw.find(pattern)
            if at < 0 or raw.find(pattern, at + 1) >= 0:
                raise RuntimeError(f"cannot locate time field bytes of {msg_type.__name__} in its CDR layout")
            time_offsets.append(at)
        self.time_gather = (np.asarray(time_offsets, dtype=np.intp)[:, None] + np.arange(8)).reshape(-1)
        if not fixed[self.gather].all() or not fixed[self.time_gather].all():
            raise RuntimeError(f"CDR layout walk of {msg_type.__name__} disagrees with rclpy's serialization")
        fixed[self.gather] = False
        fixed[self.time_gather] = False
        if stamped:
            fixed[STAMP_OFFSET : STAMP_OFFSET + 8] = False
        # contiguous fixed byte ranges that a decodable buffer must reproduce exactly
        self._fixed_ranges = _ranges(fixed)
        zero = bytearray(raw)
        np.frombuffer(zero, dtype=np.uint8)[self.gather] = 0
        np.frombuffer(zero, dtype=np.uint8)[self.time_gather] = 0
        self.template = bytes(zero)
        self._fixed_parts = [self.template[a:b] for a, b in self._fixed_ranges]

    def encode(self, t_ns: int, values: np.ndarray, times_ns: np.ndarray | None = None) -> bytes:
        """CDR bytes of the message with stamp ``t_ns`` (int ns), the float64 ``values`` (self.size,) and, when the
        layout has time fields, their values ``times_ns`` (self.n_times,) in integer ns (non-negative)."""
        buf = bytearray(self.template)
        if self.stamped:
            struct.pack_into("<iI", buf, STAMP_OFFSET, *split_ns(t_ns))
        view = np.frombuffer(buf, dtype=np.uint8)
        view[self.gather] = np.ascontiguousarray(values, dtype="<f8").reshape(-1).view(np.uint8)
        if self.n_times:
            ns = np.asarray(times_ns, dtype=np.int64)
            pairs = np.empty(self.n_times, dtype=TIME_DTYPE)
            pairs["sec"], pairs["nanosec"] = np.divmod(ns, NS_PER_S)
            view[self.time_gather] = pairs.view(np.uint8)
        return bytes(buf)

    def decode(self, raw: bytes) -> tuple[int, np.ndarray] | None:
        """(stamp ns, values (self.size,)) if ``raw`` has exactly the template's layout, else None."""
        if len(raw) != len(self.template):
            return None
        for (a, b), part in zip(self._fixed_ranges, self._fixed_parts, strict=True):
            if raw[a:b] != part:
                return None
        t_ns = 0
        if self.stamped:
            sec, nsec = struct.unpack_from("<iI", raw, STAMP_OFFSET)
            t_ns = sec * NS_PER_S + nsec
        values = np.frombuffer(raw, dtype=np.uint8)[self.gather].view("<f8")
        return t_ns, values

    def times(self, raw: bytes) -> np.ndarray:
        """The time fields (int64 ns) of a buffer that :meth:`decode` accepted."""
        pairs = np.frombuffer(raw, dtype=np.uint8)[self.time_gather].view(TIME_DTYPE)
        return pairs["sec"].astype(np.int64) * NS_PER_S + pairs["nanosec"]

    def deserialize(self, raw: bytes):
        """Full rclpy deserialization (the slow path, for buffers that ``decode`` does not accept)."""
        return deserialize_message(raw, self.msg_type)


_PRIMITIVE_SIZES = {
    "boolean": 1, "octet": 1, "char": 1, "uint8": 1, "int8": 1, "int16": 2, "uint16": 2, "int32": 4,
    "uint32": 4, "float": 4, "int64": 8, "uint64": 8, "double": 8,
}  # fmt: skip


def _mark_used(msg, used: np.ndarray, pos: int) -> int:
    """Mark the bytes that classic (XCDR1) CDR uses for ``msg``'s values starting at ``pos``; return the end.

    Alignment is relative to the payload start (after the encapsulation header); everything not marked is padding.
    """

    def align(p: int, size: int) -> int:
        return CDR_HEADER + -(-(p - CDR_HEADER) // size) * size

    def mark(p: int, size: int) -> int:
        p = align(p, size)
        used[p : p + size] = True
        return p + size

    def value(p: int, tp, v) -> int:
        kind = type(tp).__name__
        if hasattr(v, "SLOT_TYPES"):
            return _mark_used(v, used, p)
        if kind == "BasicType":
            return mark(p, _PRIMITIVE_SIZES[tp.typename])
        if kind in ("UnboundedString", "BoundedString"):
            p = mark(p, 4)
            n = len(v.encode()) + 1
            used[p : p + n] = True
            return p + n
        if kind in ("UnboundedSequence", "BoundedSequence", "Array"):
            if kind != "Array":
                p = mark(p, 4)
            for item in v:
                p = value(p, tp.value_type, item)
            return p
        raise RuntimeError(f"unsupported field type {kind} in {type(msg).__name__}")

    for slot, tp in zip(msg.__slots__, msg.SLOT_TYPES, strict=False):
        pos = value(pos, tp, getattr(msg, slot))
    return pos


def _sentinels(n: int) -> list[float]:
    # distinct values whose 8-byte patterns cannot occur by accident in the rest of the buffer
    return [-1.2345678901234567e-300 * (k + 3) for k in range(n)]


def _time_sentinel(j: int) -> tuple[int, int]:
    # (sec, nanosec) patterns as unlikely as the float sentinels (nanosec beyond 1e9 is never a real time)
    return -1_987_654_321 + 7 * j, 3_987_654_321 - 11 * j


def _ranges(mask: np.ndarray) -> list[tuple[int, int]]:
    """Half-open index ranges where ``mask`` is True."""
    padded = np.concatenate([[False], mask, [False]])
    edges = np.flatnonzero(np.diff(padded.astype(np.int8)))
    return [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2], strict=True)]
