"""Message glue of the monitor: the inputs whose channel names are learnt, and the multiplier array.

The monitor does not assume the plant's configuration: the first message fixes the channel names (and so the
layout); later messages are decoded with ``amb_ros``'s fast fixed-layout codecs, reordered by name if needed, and
rejected (never used) if they are not finite or have other names or sizes.  Both inputs return the samples of a
message as ``(stamps ns (N,), values (N, channels))``: one sample per JointState (/amb/displacement, or
/amb_plant/state in bags recorded before it carried blocks), ``state_block`` samples per JointTrajectory
(/amb_plant/state, :mod:`amb_ros.state_block`).
"""

from __future__ import annotations

import numpy as np
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, MultiArrayDimension
from trajectory_msgs.msg import JointTrajectory

import amb_ros.messages as m
from amb_ros.state_block import StateBlockDecoder

STATE_BLOCK_TYPE = "trajectory_msgs/msg/JointTrajectory"


def _first_message(raw: bytes, msg_type, names_field: str):
    """The first message of an input, deserialized, and its (non-empty) names; raises Rejected."""
    try:
        msg = deserialize_message(raw, msg_type)
    except Exception as exc:  # an unparsable buffer is a rejected message
        raise m.Rejected(f"undecodable {msg_type.__name__} ({exc})") from None
    names = tuple(getattr(msg, names_field))
    if not names:
        raise m.Rejected(f"{msg_type.__name__} without {names_field}")
    return msg, names


class JointStateInput:
    """Decoder of JointState samples with the float arrays ``fields`` (position, or position and velocity)."""

    def __init__(self, fields: tuple[str, ...]):
        self.fields = fields
        self.names: tuple[str, ...] | None = None
        self._decoder: m.Decoder | None = None

    def __call__(self, raw: bytes) -> tuple[int, np.ndarray]:
        """(stamp ns, concatenated fields) or :class:`amb_ros.messages.Rejected`."""
        if self._decoder is None:
            msg, names = _first_message(raw, JointState, "name")
            for f in self.fields:
                if len(getattr(msg, f)) != len(names):
                    raise m.Rejected(f"{f} has {len(getattr(msg, f))} values for {len(names)} names")
            self.names = names
            # the first message's run token too (header.frame_id): later samples of another run are foreign
            self._decoder = m.joint_state_decoder(names, self.fields, msg.header.frame_id)
            try:
                return self._decoder(raw)
            except m.Rejected:
                self.names = self._decoder = None  # learn the layout from a usable message only
                raise
        return self._decoder(raw)

    def samples(self, raw: bytes) -> tuple[np.ndarray, np.ndarray]:
        """The message's one sample as (stamps (1,), values (1, channels))."""
        t_ns, values = self(raw)
        return np.array([t_ns], dtype=np.int64), values[None, :]

    def scale_groups(self) -> tuple[int, ...] | None:
        return scale_groups(self.names, self.fields)


def scale_groups(names: tuple[str, ...] | None, fields: tuple[str, ...]) -> tuple[int, ...] | None:
    """Row-scale groups for the estimator: positions as one group, velocities as another (None: 1 field)."""
    if names is None or len(fields) == 1:
        return None
    return tuple(g for g in range(len(fields)) for _ in range(len(names)))


class StateBlockInput:
    """Decoder of /amb_plant/state blocks (JointTrajectory) whose coordinate names and block size are learnt."""

    def __init__(self):
        self.names: tuple[str, ...] | None = None
        self._decoder: StateBlockDecoder | None = None

    def samples(self, raw: bytes) -> tuple[np.ndarray, np.ndarray]:
        """(stamps ns (N,), values (N, 2n) = [q, dq]) or :class:`amb_ros.messages.Rejected`."""
        if self._decoder is None:
            msg, names = _first_message(raw, JointTrajectory, "joint_names")
            decoder = StateBlockDecoder(names, len(msg.points))
            out = decoder(raw)  # learn the layout from a usable message only
            self.names, self._decoder = names, decoder
            return out
        return self._decoder(raw)

    def scale_groups(self) -> tuple[int, ...] | None:
        return scale_groups(self.names, ("position", "velocity"))


def multipliers_message(mu, count: int) -> Float64MultiArray:
    """Float64MultiArray with layout dims [k, 2] (re, im) of the ``count`` largest multipliers (sorted)."""
    mu = np.asarray(mu, dtype=complex)[:count]
    k = int(mu.size)
    msg = Float64MultiArray()
    msg.layout.dim = [
        MultiArrayDimension(label="multiplier", size=k, stride=2 * k),
        MultiArrayDimension(label="re_im", size=2, stride=2),
    ]
    msg.layout.data_offset = 0
    msg.data = np.column_stack([mu.real, mu.imag]).ravel().tolist()
    return msg


def multipliers_from_message(msg) -> np.ndarray:
    """Complex multipliers of a /stability/multipliers message (checks the [k, 2] layout)."""
    dims = list(msg.layout.dim)
    if len(dims) != 2 or dims[1].size != 2 or len(msg.data) != 2 * dims[0].size:
        raise ValueError("not a [k, 2] multiplier array")
    d = np.asarray(msg.data, dtype=float).reshape(-1, 2)
    return d[:, 0] + 1j * d[:, 1]
