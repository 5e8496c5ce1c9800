"""amb-live serves the rig's topics to Foxglove: a WebSocket client (the Foxglove protocol) sees the channels
advertised with ROS 2 schemas, subscribes, and decodes the CDR messages it gets.

This test publishes plant state blocks of a known state (the full FE model, ``modal_cutoff=null``, so that the
AMB displacements are the bearing nodes' own v, w coordinates: an independent check of y = Ba^T q) and the
monitor's flag; amb-live runs as its own process, as ``amb-rig run --live`` starts it.
"""

from __future__ import annotations

import json
import math
import os
import socket
import struct
import time

import numpy as np
import pytest

from procs import spawn

pytestmark = pytest.mark.ros

TS_NS = 200_000
BLOCK = 25
GAP = 2.5e-3  # the seed config's air gap (m)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def state_block(names, k0: int, q: np.ndarray):
    from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

    msg = JointTrajectory(joint_names=list(names))
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(k0 * TS_NS, 10**9)
    for i in range(BLOCK):
        p = JointTrajectoryPoint(positions=(q * (i + 1)).tolist(), velocities=[0.0] * len(names))
        p.time_from_start.nanosec = i * TS_NS
        msg.points.append(p)
    return msg


def test_foxglove_client_gets_ros2_channels_and_decodes_messages(venv_bin, tmp_path):
    import rclpy
    from rclpy.serialization import deserialize_message
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Bool, Float64, Float64MultiArray
    from trajectory_msgs.msg import JointTrajectory
    from websockets.sync.client import connect

    from amb_dynamics.config import load_config
    from amb_dynamics.structure import build_structure
    from amb_ros.qos import latched_qos, lockstep_qos

    names = build_structure(load_config(None, ["modal_cutoff=null"])).dof_names
    q = np.arange(1, len(names) + 1) * 1e-6  # distinct per coordinate
    last = q * BLOCK  # the block's last point
    expected_y = np.array([last[names.index(d)] for d in ("n1_v", "n1_w", "n5_v", "n5_w")])

    port = free_port()
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    node = rclpy.create_node("live_test_pub", context=ctx)
    state_pub = node.create_publisher(JointTrajectory, "/amb_plant/state", lockstep_qos())
    flag_pub = node.create_publisher(Bool, "/stability/unstable", latched_qos())
    mult_pub = node.create_publisher(Float64MultiArray, "/stability/multipliers", latched_qos())
    cmd = [str(venv_bin / "amb-live"), "--port", str(port), "--set", "modal_cutoff=null"]
    try:
        with spawn(cmd, tmp_path / "live.log") as live:
            assert live.wait_for(f"ws://127.0.0.1:{port}", 60), live.text()
            tids = [int(t) for t in os.listdir(f"/proc/{live.popen.pid}/task")]
            policies = {os.sched_getscheduler(t) for t in tids}  # every thread: DDS's and the WebSocket server's
            assert policies == {os.SCHED_IDLE}, (policies, len(tids))  # it takes only the CPU the loop leaves
            flag_pub.publish(Bool(data=True))
            with connect(f"ws://127.0.0.1:{port}", subprotocols=["foxglove.sdk.v1", "foxglove.websocket.v1"],
                         open_timeout=20) as ws:  # fmt: skip
                channels = {}
                end = time.monotonic() + 20
                while not {"/live/displacement", "/stability/unstable", "/live/orbit/amb1"} <= set(channels):
                    assert time.monotonic() < end, channels
                    frame = ws.recv(timeout=10)
                    if isinstance(frame, str) and json.loads(frame)["op"] == "advertise":
                        channels.update({c["topic"]: c for c in json.loads(frame)["channels"]})
                for topic, type_name in (("/amb_plant/state", "trajectory_msgs/msg/JointTrajectory"),
                                         ("/live/displacement", "sensor_msgs/msg/JointState"),
                                         ("/stability/unstable", "std_msgs/msg/Bool"),
                                         ("/diagnostics", "diagnostic_msgs/msg/DiagnosticArray")):  # fmt: skip
                    c = channels[topic]
                    assert (c["encoding"], c["schemaName"], c["schemaEncoding"]) == ("cdr", type_name, "ros2msg")
                schema = channels["/live/displacement"]["schema"]
                assert "float64[] position" in schema and "MSG: std_msgs/Header" in schema  # rosbag2's concatenation
                subs = {1: "/live/displacement", 2: "/stability/unstable", 3: "/live/orbit/amb1", 4: "/live/rho"}
                ws.send(json.dumps({"op": "subscribe", "subscriptions": [
                    {"id": i, "channelId": channels[t]["id"]} for i, t in subs.items()]}))  # fmt: skip
                got: dict[str, list] = {t: [] for t in subs.values()}
                k0, end = 0, time.monotonic() + 30
                while not all(got.values()):
                    assert time.monotonic() < end, {t: len(v) for t, v in got.items()}
                    state_pub.publish(state_block(names, k0, q))
                    mult_pub.publish(Float64MultiArray(data=[0.6 * 1.05, 0.8 * 1.05, 0.5, 0.0]))  # |mu| 1.05, 0.5
                    k0 += BLOCK
                    try:
                        frame = ws.recv(timeout=0.2)
                    except TimeoutError:
                        continue
                    if isinstance(frame, bytes) and frame[0] == 0x01:  # MessageData
                        sub_id, _log_time = struct.unpack_from("<IQ", frame, 1)
                        got[subs[sub_id]].append(frame[13:])
    finally:
        node.destroy_node()
        rclpy.shutdown(context=ctx)
    disp = deserialize_message(got["/live/displacement"][0], JointState)
    assert list(disp.name) == ["amb1_y", "amb1_z", "amb5_y", "amb5_z"]
    np.testing.assert_allclose(disp.position, expected_y, rtol=1e-15)
    # stamped with the block's last sample
    assert (disp.header.stamp.sec * 10**9 + disp.header.stamp.nanosec) % (BLOCK * TS_NS) == (BLOCK - 1) * TS_NS
    assert deserialize_message(got["/stability/unstable"][0], Bool).data is True
    assert deserialize_message(got["/live/rho"][0], Float64).data == pytest.approx(1.05, rel=1e-15)
    orbit = deserialize_message(got["/live/orbit/amb1"][0], JointState)
    cut = next(i for i, v in enumerate(orbit.position) if math.isnan(v))
    np.testing.assert_allclose(orbit.position[:cut], [expected_y[0]] * cut, rtol=1e-15)
    np.testing.assert_allclose(orbit.velocity[:cut], [expected_y[1]] * cut, rtol=1e-15)
    circle = np.hypot(orbit.position[cut + 1 :], orbit.velocity[cut + 1 :])
    np.testing.assert_allclose(circle, GAP, rtol=1e-12)  # the clearance circle, radius = the air gap


def test_layout_uses_only_channels_the_live_view_serves(repo):
    """Every message path of docs/foxglove/amb-rig.layout.json names a topic amb-live advertises (with
    --currents), and each panel of the layout's tree is configured."""
    from amb_bringup import live

    layout = json.loads((repo / "docs" / "foxglove" / "amb-rig.layout.json").read_text())
    served = {*live.FORWARDED, live.CURRENT[0], "/live/displacement", "/live/rho", "/live/orbit/amb1",
              "/live/orbit/amb5"}  # fmt: skip
    paths = []
    for cfg in layout["configById"].values():
        paths += [p["value"] for p in cfg.get("paths", [])] + [cfg[k]["value"] for k in ("xAxisPath",) if k in cfg]
        paths += [cfg[k] for k in ("path", "topicToRender") if k in cfg]
    topics = {p.split(".")[0] for p in paths}
    assert topics and topics <= served, topics - served

    def leaves(node):
        return [node] if isinstance(node, str) else leaves(node["first"]) + leaves(node["second"])

    assert sorted(leaves(layout["layout"])) == sorted(layout["configById"])
