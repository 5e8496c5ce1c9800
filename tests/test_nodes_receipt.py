"""Messages are checked on receipt: the fast codec equals rclpy's CDR, and bad messages never reach the physics.

Unit level: ``TemplateCodec`` encodes exactly the bytes rclpy serializes (up to CDR padding) and decodes
rclpy-serialized buffers; the slow path reorders channel names and rejects NaN, unknown names and wrong sizes.
Over DDS: a lockstep controller fed one good sample, then a NaN, wrong names, a wrong size and an off-grid stamp,
answers only the good one, with the current the core's DiscretePID computes, and counts four rejections; a
lockstep plant fed bad /base/rates blocks rejects them and steps with the good block's rates exactly.
"""

from __future__ import annotations

import struct
import time
from pathlib import Path

import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import Imu, JointState

from amb_dynamics.amb import DiscretePID, DiscretePIDCoefficients
from amb_dynamics.config import load_config
from amb_dynamics.structure import AMBGains
from amb_ros import messages as m
from helpers import DdsRecorder
from procs import spawn

CHANNELS = ("amb1_y", "amb1_z", "amb5_y", "amb5_z")


def joint_state(names, position, t_ns=0) -> JointState:
    msg = JointState()
    msg.name = list(names)
    msg.position = [float(v) for v in position]
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(t_ns, 10**9)
    return msg


def test_codec_bytes_match_rclpy_and_decode_foreign_buffers():
    codec = m.joint_state_codec(CHANNELS, ("position",))
    y = np.array([1e-5, -2e-5, 3.5e-6, 0.0])
    raw = codec.encode(1_234_567_891_000, y)
    back = deserialize_message(raw, JointState)
    assert list(back.name) == list(CHANNELS) and np.array_equal(back.position, y)
    assert (back.header.stamp.sec, back.header.stamp.nanosec) == (1234, 567891000)
    ref = serialize_message(joint_state(CHANNELS, y, 1_234_567_891_000))
    t_ns, values = codec.decode(ref)  # rclpy's own buffer (its padding bytes differ) takes the fast path
    assert t_ns == 1_234_567_891_000 and np.array_equal(values, y)
    imu = m.imu_decoder()
    v = np.array([0.1, 0.2, 0.3, 0.9, 1.0, 2.0, 3.0])
    msg = deserialize_message(imu.codec.encode(5, v), Imu)
    assert (msg.orientation.w, msg.angular_velocity.z, msg.linear_acceleration_covariance[0]) == (0.9, 3.0, -1.0)
    assert np.array_equal(imu(serialize_message(msg))[1], v)


def test_codec_ignores_sentinels_left_in_uninitialised_bytes(monkeypatch):
    """rclpy's buffer ends in padding that is not written (uninitialised memory): an earlier codec's sentinel
    left there must not make the field search ambiguous (a plant once failed to start on exactly that)."""
    from amb_ros import codec as codec_module

    honest = codec_module.serialize_message

    def stale(msg):  # rclpy's bytes, the unwritten tail holding a stale copy of the first sentinel
        raw = bytearray(honest(msg))
        used = np.zeros(len(raw), dtype=bool)
        end = codec_module._mark_used(msg, used, codec_module.CDR_HEADER)
        assert len(raw) - end >= 8  # this layout's serialization ends in at least 8 unwritten bytes
        raw[end : end + 8] = struct.pack("<d", codec_module._sentinels(1)[0])
        return bytes(raw)

    monkeypatch.setattr(codec_module, "serialize_message", stale)
    codec = m.joint_state_codec(CHANNELS, ("effort",))  # the plant's command layout: 8 bytes of tail padding
    y = np.array([0.5, -0.25, 0.125, 2.0])
    back = deserialize_message(codec.encode(7, y), JointState)
    assert np.array_equal(back.effort, y) and list(back.name) == list(CHANNELS)
    msg = JointState(name=list(CHANNELS), effort=y.tolist())
    assert np.array_equal(codec.decode(honest(msg))[1], y)


def test_slow_path_reorders_and_rejects():
    dec = m.joint_state_decoder(CHANNELS, ("position",))
    swapped = serialize_message(joint_state(("amb1_z", "amb1_y", "amb5_y", "amb5_z"), [2.0, 1.0, 3.0, 4.0]))
    assert np.array_equal(dec(swapped)[1], [1.0, 2.0, 3.0, 4.0])
    for bad, reason in [
        (joint_state(CHANNELS, [1.0, np.nan, 0.0, 0.0]), "non-finite"),
        (joint_state(("a", "b", "c", "d"), [0.0] * 4), "channel names"),
        (joint_state(CHANNELS, [0.0] * 3), "3 values for 4 names"),
    ]:
        with pytest.raises(m.Rejected, match=reason):
            dec(serialize_message(bad))
    with pytest.raises(m.Rejected, match="undecodable"):
        dec(b"\x00\x01\x00\x00garbage")


def trajectory(names, rows, stamps):
    """A /amb_plant/state block built with rclpy's classes (rows = [q, dq] per sample, stamps in ns)."""
    from builtin_interfaces.msg import Duration
    from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

    n = len(names)
    msg = JointTrajectory(joint_names=list(names))
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(int(stamps[0]), 10**9)
    for row, t in zip(rows, stamps, strict=True):
        sec, nsec = divmod(int(t - stamps[0]), 10**9)
        msg.points.append(JointTrajectoryPoint(positions=[float(v) for v in row[:n]],
                                               velocities=[float(v) for v in row[n:]],
                                               time_from_start=Duration(sec=sec, nanosec=nsec)))  # fmt: skip
    return msg


def test_state_blocks_round_trip_through_rclpy_and_reject_bad_blocks():
    from trajectory_msgs.msg import JointTrajectory

    from amb_ros.state_block import StateBlockDecoder, StateBlockWriter

    names = ("mode1", "mode2", "mode3")
    rng = np.random.default_rng(1)
    rows = rng.standard_normal((11, 6))
    stamps = 3_999_999_000 + 200_000 * np.arange(11)  # crosses a whole second inside the first block
    writer = StateBlockWriter(names, 4)
    blocks = [b for t, x in zip(stamps, rows, strict=True) if (b := writer.add(int(t), x)) is not None]
    blocks.append(writer.flush())
    assert writer.flush() is None and len(blocks) == 3  # 4 + 4 + 3 samples
    msgs = [deserialize_message(b, JointTrajectory) for b in blocks]
    assert [len(msg.points) for msg in msgs] == [4, 4, 3] and list(msgs[2].joint_names) == list(names)
    assert msgs[0].points[3].time_from_start.nanosec == 600_000 and msgs[1].header.stamp.sec == 4
    assert np.array_equal([p.positions[1] for msg in msgs for p in msg.points], rows[:, 1])
    assert np.array_equal([p.velocities[2] for msg in msgs for p in msg.points], rows[:, 5])
    dec = StateBlockDecoder(names, 4)
    assert dec.codec.decode(serialize_message(msgs[0])) is not None  # rclpy's padding differs: still the fast path
    for a, msg in zip((0, 4, 8), msgs, strict=True):  # rclpy's own buffers: fast path (4) and slow path (3)
        got_t, got_x = dec(serialize_message(msg))
        assert np.array_equal(got_t, stamps[a : a + len(msg.points)]) and np.array_equal(got_x, rows[a : a + 4])
    perm = ("mode2", "mode3", "mode1")  # names identify the columns: a permutation is reordered
    swapped = trajectory(perm, rows[:4][:, [1, 2, 0, 4, 5, 3]], stamps[:4])
    assert np.array_equal(dec(serialize_message(swapped))[1], rows[:4])
    bad_rows = rows[:4].copy()
    bad_rows[2, 4] = np.inf
    for bad, reason in [
        (trajectory(names, bad_rows, stamps[:4]), "non-finite"),
        (trajectory(("a", "b", "c"), rows[:4], stamps[:4]), "joint names"),
        (trajectory(names, rows[:4], stamps[[0, 2, 1, 3]]), "strictly increasing"),
        (trajectory(names, rows[:4, :5], stamps[:4]), "velocities for 3 names"),
        (JointTrajectory(joint_names=list(names)), "without points"),
    ]:
        with pytest.raises(m.Rejected, match=reason):
            dec(serialize_message(bad))
    # the monitor's input learns names and block size from its first usable block only
    from stability_monitor.messages import StateBlockInput

    learner = StateBlockInput()
    with pytest.raises(m.Rejected, match="without points"):
        learner.samples(serialize_message(JointTrajectory(joint_names=list(names))))
    assert learner.names is None
    got_t, got_x = learner.samples(blocks[0])
    assert learner.names == names and learner.scale_groups() == (0, 0, 0, 1, 1, 1)
    assert np.array_equal(got_t, stamps[:4]) and np.array_equal(got_x, rows[:4])


@pytest.mark.ros
def test_controller_rejects_bad_samples_over_dds(tmp_path, venv_bin):
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray

    from amb_ros.qos import lockstep_qos

    rec = DdsRecorder({"/amb/current": JointState, "/diagnostics": DiagnosticArray})
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    node = rclpy.create_node("test_feeder", context=ctx)
    pub = node.create_publisher(JointState, "/amb/displacement", lockstep_qos())
    y0 = np.array([1e-5, -2e-5, 3e-6, 4e-6])
    try:
        with spawn([str(venv_bin / "amb-controller")], tmp_path / "ctl.log") as ctl:
            end = time.monotonic() + 60
            while pub.get_subscription_count() < 1 and time.monotonic() < end:
                time.sleep(0.05)
            assert pub.get_subscription_count() == 1, ctl.text()
            for msg in [
                joint_state(CHANNELS, y0, 0),
                joint_state(CHANNELS, [np.nan, 0, 0, 0], 200_000),
                joint_state(("x", "y", "z", "w"), y0, 200_000),
                joint_state(CHANNELS, y0[:3], 200_000),
                joint_state(CHANNELS, y0, 123),  # not on the 200 us grid of 5 kHz
            ]:
                pub.publish(msg)
            end = time.monotonic() + 20  # the first delivery may wait for a reliable-protocol repair
            while not rec.messages["/amb/current"] and time.monotonic() < end:
                time.sleep(0.05)
            time.sleep(1.0)
            assert ctl.stop() == 0, ctl.text()
        time.sleep(0.5)
    finally:
        node.destroy_node()
        ctx.try_shutdown()
        rec.close()
    currents = rec.messages["/amb/current"]
    assert len(currents) == 1
    cfg = load_config()
    lim = cfg.controller.current_limit
    pid = DiscretePID(DiscretePIDCoefficients.from_gains(AMBGains.from_config(cfg), 2e-4), 4, lim)
    offset = np.array(cfg.controller.bias_current_offset or (0.0,) * 4)  # the static load's bias (real rig)
    expected = np.clip(pid.step(y0) + offset, -lim, lim)
    np.testing.assert_allclose(currents[0].effort, expected, rtol=1e-15, atol=0)
    statuses = [s for a in rec.messages["/diagnostics"] for s in a.status if s.name == "amb_controller"]
    final = [s for s in statuses if {kv.key: kv.value for kv in s.values}.get("final") == "true"]
    assert final, "no final diagnostics from the controller"
    values = {kv.key: kv.value for kv in final[-1].values}
    assert values["rejected total"] == "4" and values["samples answered"] == "1"
    assert "rejected" in final[-1].message


def rates_block(k0: int, rows: np.ndarray, names=m.BASE_RATE_NAMES, grid_ns: int = 200_000, offset_ns: int = 0):
    """A /base/rates block of samples k0, k0+1, ... (rows = [Omega, dOmega])."""
    from builtin_interfaces.msg import Duration
    from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

    msg = JointTrajectory(joint_names=list(names))
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(k0 * grid_ns + offset_ns, 10**9)
    msg.points = [
        JointTrajectoryPoint(
            positions=r[:3].tolist(), velocities=r[3:].tolist(), time_from_start=Duration(nanosec=i * grid_ns)
        )
        for i, r in enumerate(rows)
    ]
    return msg


@pytest.mark.ros
def test_plant_takes_base_rate_blocks_and_rejects_bad_ones_over_dds(tmp_path, venv_bin):
    """A lockstep plant fed /base/rates blocks with a NaN, an off-grid stamp and foreign names, then a good block,
    steps with the good block's rates exactly (its state equals the core's PlantStepper with those rates) and
    counts three rejections."""
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.executors import SingleThreadedExecutor
    from rosgraph_msgs.msg import Clock
    from trajectory_msgs.msg import JointTrajectory

    from amb_dynamics.sampled import PlantStepper
    from amb_dynamics.structure import build_structure
    from amb_ros.qos import lockstep_qos
    from amb_ros.state_block import block_of

    steps = 10
    t = np.arange(steps + 2) * 2e-4
    good = np.zeros((steps + 2, 6))
    good[:, 2], good[:, 5] = 7.35 * np.cos(24.5 * t), -180.0 * np.sin(24.5 * t)  # pitch: Omega_z, dOmega_z
    bad_nan = good[:3].copy()
    bad_nan[1, 4] = np.nan
    rec = DdsRecorder({"/amb_plant/state": JointTrajectory, "/diagnostics": DiagnosticArray})
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    node = rclpy.create_node("test_base_feeder", context=ctx)
    qos = lockstep_qos()
    rates_pub = node.create_publisher(JointTrajectory, m.BASE_RATES, qos)
    cmd_pub = node.create_publisher(JointState, m.CURRENT, qos)

    def answer(y: JointState) -> None:  # zero current for every sample, stamped with the sample's stamp
        cmd = JointState(name=list(CHANNELS), effort=[0.0] * 4)
        cmd.header.stamp = y.header.stamp
        cmd_pub.publish(cmd)

    node.create_subscription(JointState, m.DISPLACEMENT, answer, qos)
    node.create_subscription(Clock, m.CLOCK, lambda _c: None, qos)
    executor = SingleThreadedExecutor(context=ctx)
    executor.add_node(node)
    paper = Path(__file__).resolve().parents[1] / "config" / "seed_paper.yaml"  # the linear plant: PlantStepper
    params = [f"duration_s:={steps * 2e-4!r}", "initial_displacement:=0.0001", "min_state_subscribers:=1",
              f"config_file:={paper}"]  # fmt: skip
    try:
        with spawn([str(venv_bin / "amb-plant"), "--ros-args", *[a for p in params for a in ("-p", p)]],
                   tmp_path / "plant.log") as plant:  # fmt: skip
            end = time.monotonic() + 60
            while rates_pub.get_subscription_count() < 1 and time.monotonic() < end:
                executor.spin_once(timeout_sec=0.05)
            for msg in [rates_block(0, bad_nan), rates_block(0, good[:3], offset_ns=100),
                        rates_block(0, good[:3], names=("a", "b", "c")), rates_block(0, good)]:  # fmt: skip
                rates_pub.publish(msg)
            end = time.monotonic() + 60
            while plant.popen.poll() is None and time.monotonic() < end:
                executor.spin_once(timeout_sec=0.05)
            assert plant.wait(30) == 0, plant.text()
        time.sleep(0.5)
    finally:
        node.destroy_node()
        ctx.try_shutdown()
        rec.close()
    cfg = load_config(paper)
    model = build_structure(cfg)
    stepper = PlantStepper(model, cfg, 2e-4)
    stamps, rows = zip(*(block_of(b, model.dof_names) for b in rec.messages["/amb_plant/state"]), strict=True)
    stamps, X = np.concatenate(stamps), np.concatenate(rows)
    assert np.array_equal(stamps, np.arange(steps + 1) * 200_000)
    x = X[0]
    assert np.abs(x).max() > 0  # the disk starts displaced
    for k in range(steps):
        E, _G, g = stepper.matrices(good[k, :3], good[k, 3:])
        x = E @ x + g
        np.testing.assert_allclose(X[k + 1], x, rtol=0, atol=1e-12 * np.abs(X).max())
    statuses = [s for a in rec.messages["/diagnostics"] for s in a.status if s.name == "amb_plant"]
    values = {kv.key: kv.value for kv in statuses[-1].values}
    assert values["final"] == "true" and values["steps"] == str(steps)
    assert values[f"rejected {m.BASE_RATES}"] == "3" and values["rejected total"] == "3"
