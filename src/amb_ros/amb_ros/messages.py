"""The topics of the rig (docs/topics.md), their message layouts and the checks applied on receipt.

Every topic has a fast fixed-layout codec (:mod:`amb_ros.codec`) and a slow path that deserializes a foreign
layout with rclpy and validates it.  ``Decoder.__call__`` returns ``(stamp_ns, values)`` or raises
:class:`Rejected` with a one-line reason; nothing that is not finite and of the right size and channel names
ever reaches the physics.

Layouts (documented for users in docs/topics.md):

- /amb/displacement  sensor_msgs/JointState   name = channels, position = displacement (m)
- /amb/current       sensor_msgs/JointState   name = channels, effort = current (A)
- /amb_plant/state   trajectory_msgs/JointTrajectory   blocks of consecutive samples (q, dq/dt): amb_ros.state_block
- /base/rates        trajectory_msgs/JointTrajectory   lockstep: every base sample in blocks, joint_names =
                     BASE_RATE_NAMES, positions = Omega, velocities = dOmega/dt (the plant's input; amb_ros.state_block)
- /base/imu          sensor_msgs/Imu          orientation = base->inertial quaternion, angular_velocity = Omega
- /base/angular_acceleration  geometry_msgs/Vector3Stamped  vector = dOmega/dt (rad/s^2, base axes)
- /clock             rosgraph_msgs/Clock      simulated time t_k = k Ts (lockstep)
"""

from __future__ import annotations

import math
import re

import numpy as np
from geometry_msgs.msg import Vector3Stamped
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu, JointState

from .codec import TemplateCodec, stamp_ns

CLOCK = "/clock"
IMU = "/base/imu"
ANGULAR_ACCELERATION = "/base/angular_acceleration"
BASE_RATES = "/base/rates"
BASE_RATE_NAMES = ("omega_x", "omega_y", "omega_z")  # /base/rates joints: Omega in base axes, velocities = dOmega/dt
DISPLACEMENT = "/amb/displacement"
CURRENT = "/amb/current"
STATE = "/amb_plant/state"
AUX_STATE = "/amb_plant/aux_state"  # amplifier and sensor-filter states, spin angle (blocks, as STATE)
SPIN_SPEED = "/amb/spin_speed"  # tachometer: JointState name ["spin"], position = angle, velocity = speed
TOUCHDOWN = "/amb_plant/touchdown"  # std_msgs/String, one JSON object per backup-bearing contact
RUN_CONFIG = "/amb_plant/config"  # std_msgs/String, latched: the run's effective rotor config as one JSON object
MULTIPLIERS = "/stability/multipliers"
UNSTABLE = "/stability/unstable"
DIAGNOSTICS = "/diagnostics"
BASE_FRAME = "base"


class Rejected(Exception):
    """A received message that must not be used; ``str(exc)`` is the reason (one line)."""


class Foreign(Rejected):
    """A well-formed message that carries another run's token (``header.frame_id``): not this run's."""


RUN_TOKEN_RE = re.compile(r"[A-Za-z0-9_-]{0,64}")


def _set_seq(attr: str):
    def setter(msg, values):
        setattr(msg, attr, [float(v) for v in values])

    return setter


def _set_attrs(path: str, names: str):
    def setter(msg, values):
        obj = msg
        for part in path.split("."):
            obj = getattr(obj, part)
        for name, v in zip(names, values, strict=True):
            setattr(obj, name, float(v))

    return setter


class Decoder:
    """Fast decode with a slow, validating fallback; raises :class:`Rejected`."""

    def __init__(self, codec: TemplateCodec, slow):
        self.codec, self._slow = codec, slow

    def __call__(self, raw: bytes) -> tuple[int, np.ndarray]:
        out = self.codec.decode(raw)
        if out is None:
            try:
                msg = self.codec.deserialize(raw)
            except Exception as exc:  # a buffer rclpy cannot parse is a rejected message, not a crash
                raise Rejected(f"undecodable {self.codec.msg_type.__name__} ({exc})") from None
            out = self._slow(msg)
        t_ns, values = out
        if not all(map(math.isfinite, values.tolist())):  # 5x cheaper than np.isfinite for a few values
            raise Rejected("non-finite value")
        if t_ns < 0:
            raise Rejected("negative stamp")
        return t_ns, values


def joint_state_codec(names: tuple[str, ...], fields: tuple[str, ...], token: str = "") -> TemplateCodec:
    """JointState with ``names`` and the float arrays ``fields`` (subset of position, velocity, effort); ``token``
    is the run token in ``header.frame_id`` (/amb/displacement and /amb/current: docs/topics.md)."""
    msg = JointState()
    msg.header.frame_id = token
    msg.name = list(names)
    n = len(names)
    return TemplateCodec(JointState, msg, [(_set_seq(f), n) for f in fields])


def joint_state_decoder(names: tuple[str, ...], fields: tuple[str, ...], token: str | None = None) -> Decoder:
    """Decoder of :func:`joint_state_codec`'s messages; with ``token`` (not None) a message whose
    ``header.frame_id`` differs is :class:`Foreign` (another run's, or an intruder's)."""
    codec = joint_state_codec(names, fields, token or "")
    expected = list(names)

    def slow(msg: JointState):
        if token is not None and msg.header.frame_id != token:
            raise Foreign("another run token in header.frame_id")
        got = list(msg.name)
        if sorted(got) != sorted(expected) or len(got) != len(expected):
            raise Rejected(f"channel names {got} (expected {expected})")
        order = [got.index(nm) for nm in expected]  # JointState names identify the channels: reorder
        parts = []
        for f in fields:
            arr = np.asarray(getattr(msg, f), dtype=float)
            if arr.size != len(got):
                raise Rejected(f"{f} has {arr.size} values for {len(got)} names")
            parts.append(arr[order])
        return stamp_ns(msg.header.stamp), np.concatenate(parts)

    return Decoder(codec, slow)


def imu_codec() -> TemplateCodec:
    msg = Imu()
    msg.header.frame_id = BASE_FRAME
    # orientation is exact (covariance all zeros = unknown per Imu.msg); no linear acceleration: -1 marks it absent
    msg.linear_acceleration_covariance[0] = -1.0
    fields = [(_set_attrs("orientation", "xyzw"), 4), (_set_attrs("angular_velocity", "xyz"), 3)]
    return TemplateCodec(Imu, msg, fields)


def imu_decoder() -> Decoder:
    def slow(msg: Imu):
        q, w = msg.orientation, msg.angular_velocity
        values = np.array([q.x, q.y, q.z, q.w, w.x, w.y, w.z])
        return stamp_ns(msg.header.stamp), values

    return Decoder(imu_codec(), slow)


def vector3_codec() -> TemplateCodec:
    msg = Vector3Stamped()
    msg.header.frame_id = BASE_FRAME
    return TemplateCodec(Vector3Stamped, msg, [(_set_attrs("vector", "xyz"), 3)])


def vector3_decoder() -> Decoder:
    def slow(msg: Vector3Stamped):
        v = msg.vector
        return stamp_ns(msg.header.stamp), np.array([v.x, v.y, v.z])

    return Decoder(vector3_codec(), slow)


def clock_codec() -> TemplateCodec:
    return TemplateCodec(Clock, Clock(), [])


def clock_decoder() -> Decoder:
    def slow(msg: Clock):
        return stamp_ns(msg.clock), np.zeros(0)

    return Decoder(clock_codec(), slow)
