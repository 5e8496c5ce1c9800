"""The rig's topic mix (docs/topics.md), deterministic per step, serialized to CDR independently of rclpy.

rclpy's ``serialize_message`` returns a buffer with trailing bytes in these wheels (JointState: 108 bytes where
the wire message has 100), which a strict reader (rosbags) rejects; the rosbags typestore serializes exactly what
DDS puts on the wire, so the publisher publishes those bytes raw and logs them.

``step_messages(k)`` gives ``[(topic, type, message)]`` for lockstep step k; ``values(type, msg)`` extracts the
compared fields from a rosbags, mcap_ros2 or rclpy message object alike.
"""

from __future__ import annotations

import math

import numpy as np
from rosbags.typesys import Stores, get_typestore

TS = get_typestore(Stores.ROS2_JAZZY)
T = TS.types
STEP_S = 2e-4  # simulated step (5 kHz lockstep)
CHANNELS = ["amb1_y", "amb1_z", "amb5_y", "amb5_z"]
DOFS = [f"n{n}_{d}" for n in range(1, 8) for d in ("v", "w", "ty", "tz")]  # 28 generalised coordinates
MULTIPLIER_EVERY = 50
STATE_BLOCK = 5  # /amb_plant/state: a block of the samples since the last one, every STATE_BLOCK steps
TOPICS = {
    "/clock": "rosgraph_msgs/msg/Clock",
    "/base/imu": "sensor_msgs/msg/Imu",
    "/base/angular_acceleration": "geometry_msgs/msg/Vector3Stamped",
    "/amb/displacement": "sensor_msgs/msg/JointState",
    "/amb/current": "sensor_msgs/msg/JointState",
    "/amb_plant/state": "trajectory_msgs/msg/JointTrajectory",
    "/stability/multipliers": "std_msgs/msg/Float64MultiArray",
    "/stability/unstable": "std_msgs/msg/Bool",
    "/diagnostics": "diagnostic_msgs/msg/DiagnosticArray",
}
EMPTY = np.zeros(0)


def _time(k: int):
    ns = round(k * STEP_S * 1e9)
    return T["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)


def _header(k: int, frame: str):
    return T["std_msgs/msg/Header"](stamp=_time(k), frame_id=frame)


def _joint_state(k, names, position=EMPTY, velocity=EMPTY, effort=EMPTY):
    return T["sensor_msgs/msg/JointState"](header=_header(k, ""), name=list(names), position=position,
                                           velocity=velocity, effort=effort)  # fmt: skip


def _state_block(steps: range):
    point = T["trajectory_msgs/msg/JointTrajectoryPoint"]
    t0 = round(steps[0] * STEP_S * 1e9)
    points = []
    for j in steps:
        dt = round(j * STEP_S * 1e9) - t0
        points.append(
            point(
                positions=1e-6 * np.sin(np.arange(28) + j),
                velocities=1e-4 * np.cos(np.arange(28) + j),
                accelerations=EMPTY,
                effort=EMPTY,
                time_from_start=T["builtin_interfaces/msg/Duration"](sec=dt // 10**9, nanosec=dt % 10**9),
            )
        )
    return T["trajectory_msgs/msg/JointTrajectory"](header=_header(steps[0], ""), joint_names=DOFS, points=points)


def step_messages(k: int) -> list[tuple[str, str, object]]:
    """Messages of lockstep step ``k`` (multipliers every MULTIPLIER_EVERY steps)."""
    t = k * STEP_S
    a = 0.3 * math.sin(24.5 * t)
    v3 = T["geometry_msgs/msg/Vector3"]
    imu = T["sensor_msgs/msg/Imu"](
        header=_header(k, "base"),
        orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=math.sin(a / 2), w=math.cos(a / 2)),
        orientation_covariance=np.zeros(9),
        angular_velocity=v3(x=0.0, y=0.0, z=7.35 * math.cos(24.5 * t)),  # pitch: about Z (docs/physics.md#base-motion)
        angular_velocity_covariance=np.zeros(9),
        linear_acceleration=v3(x=0.0, y=0.0, z=9.81),
        linear_acceleration_covariance=np.zeros(9),
    )
    phase = np.arange(1, 5) * 0.1 + k * 1e-3
    out = [
        ("/clock", TOPICS["/clock"], T["rosgraph_msgs/msg/Clock"](clock=_time(k))),
        ("/base/imu", TOPICS["/base/imu"], imu),
        ("/base/angular_acceleration", TOPICS["/base/angular_acceleration"],
         T["geometry_msgs/msg/Vector3Stamped"](header=_header(k, "base"), vector=v3(x=0.0, y=0.0, z=-180.0 * a))),
        ("/amb/displacement", TOPICS["/amb/displacement"], _joint_state(k, CHANNELS, position=1e-5 * np.sin(phase))),
        ("/amb/current", TOPICS["/amb/current"], _joint_state(k, CHANNELS, effort=0.5 * np.cos(phase))),
    ]  # fmt: skip
    if k % STATE_BLOCK == 0:
        out.append(
            ("/amb_plant/state", TOPICS["/amb_plant/state"], _state_block(range(max(0, k - STATE_BLOCK + 1), k + 1)))
        )
    if k % MULTIPLIER_EVERY == 0:
        dim = T["std_msgs/msg/MultiArrayDimension"]
        layout = T["std_msgs/msg/MultiArrayLayout"](dim=[dim(label="k", size=2, stride=4), dim(label="re_im", size=2,
                                                     stride=2)], data_offset=0)  # fmt: skip
        data = np.array([0.9 + 1e-4 * k, 0.1, 0.5, -0.2])
        out.append(("/stability/multipliers", TOPICS["/stability/multipliers"],
                    T["std_msgs/msg/Float64MultiArray"](layout=layout, data=data)))  # fmt: skip
    return out


def unstable_message(flag: bool):
    return T["std_msgs/msg/Bool"](data=flag)


def diagnostics_message(k: int, published: dict[str, int], name: str = "bag_test_publisher"):
    """DiagnosticArray with one status carrying ``published <topic>`` counts (the loss convention)."""
    kv = T["diagnostic_msgs/msg/KeyValue"]
    status = T["diagnostic_msgs/msg/DiagnosticStatus"](
        level=0, name=name, message="ok", hardware_id="",
        values=[kv(key=f"published {topic}", value=str(n)) for topic, n in sorted(published.items())],
    )  # fmt: skip
    return T["diagnostic_msgs/msg/DiagnosticArray"](header=_header(k, ""), status=[status])


def serialize(msg, type_name: str) -> bytes:
    """Exact CDR, zero-padded to a multiple of 4 bytes as DDS (RTPS serialized payloads) carries it."""
    data = bytes(TS.serialize_cdr(msg, type_name))
    return data + b"\0" * (-len(data) % 4)


def values(type_name: str, msg) -> tuple:
    """The compared fields of a message (works on rosbags, mcap_ros2 and rclpy objects)."""

    def stamp(m):
        return (m.header.stamp.sec, m.header.stamp.nanosec)

    if type_name == "rosgraph_msgs/msg/Clock":
        return (msg.clock.sec, msg.clock.nanosec)
    if type_name == "sensor_msgs/msg/Imu":
        q, w = msg.orientation, msg.angular_velocity
        return (*stamp(msg), msg.header.frame_id, q.x, q.y, q.z, q.w, w.x, w.y, w.z, msg.linear_acceleration.z)
    if type_name == "geometry_msgs/msg/Vector3Stamped":
        return (*stamp(msg), msg.vector.x, msg.vector.y, msg.vector.z)
    if type_name == "sensor_msgs/msg/JointState":
        return (*stamp(msg), tuple(msg.name), *map(float, msg.position), *map(float, msg.velocity),
                *map(float, msg.effort))  # fmt: skip
    if type_name == "trajectory_msgs/msg/JointTrajectory":
        return (*stamp(msg), tuple(msg.joint_names), *((p.time_from_start.sec, p.time_from_start.nanosec,
                *map(float, p.positions), *map(float, p.velocities)) for p in msg.points))  # fmt: skip
    if type_name == "std_msgs/msg/Float64MultiArray":
        return (tuple((d.label, d.size, d.stride) for d in msg.layout.dim), *map(float, msg.data))
    if type_name == "std_msgs/msg/Bool":
        return (bool(msg.data),)
    if type_name == "diagnostic_msgs/msg/DiagnosticArray":
        return tuple((s.name, tuple((kv.key, kv.value) for kv in s.values)) for s in msg.status)
    raise KeyError(type_name)


RELIABLE_OFFER = {
    "history": "unknown",
    "depth": 0,
    "reliability": "reliable",
    "durability": "volatile",
    "deadline": {"sec": 9223372036, "nsec": 854775807},
    "lifespan": {"sec": 9223372036, "nsec": 854775807},
    "liveliness": "automatic",
    "liveliness_lease_duration": {"sec": 9223372036, "nsec": 854775807},
    "avoid_ros_namespace_conventions": False,
}  # fmt: skip  (what discovery reports for an rclpy reliable publisher)


def write_bag(path, steps: int, t0_ns: int = 1_700_000_000_000_000_000, **writer_options) -> list[tuple]:
    """Write ``steps`` steps of the mix with the in-process BagWriter (1 ms log-time spacing per step).

    Returns the written ``(topic, type, log_time_ns, data)`` list in write order.
    """
    from amb_bag.writer import BagWriter

    writer = BagWriter(path, **writer_options)
    ids = {t: writer.add_topic(t, ty, [RELIABLE_OFFER]) for t, ty in TOPICS.items()}
    written = []
    for k in range(steps):
        for i, (topic, type_name, msg) in enumerate(step_messages(k)):
            log = t0_ns + k * 1_000_000 + i
            data = serialize(msg, type_name)
            writer.write(ids[topic], log, data, log - 500)
            written.append((topic, type_name, log, data))
    writer.close()
    return written
