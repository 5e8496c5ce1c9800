"""Bag format without DDS: rosbag2 schema text, metadata.yaml v9, QoS metadata, splits, independent readers."""

from __future__ import annotations

import sys
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
import yaml

sys.path.insert(0, str(Path(__file__).parent / "bagtools"))
import mix

from amb_bag import msgdefs
from amb_bag.loss import LossTracker, loss_table
from amb_bag.metadata import load_metadata
from amb_bag.qos import profiles_from_yaml, request_for_offers


def _sections(text: str) -> list[str]:
    return [line[5:] for line in text.splitlines() if line.startswith("MSG: ")]


def _msg_file(type_written: str) -> str:
    package, name = type_written.split("/")
    return (Path(sys.prefix) / "share" / package / "msg" / f"{name}.msg").read_text()


@pytest.mark.parametrize(
    ("root", "deps"),
    [
        ("sensor_msgs/msg/Imu", ["geometry_msgs/Quaternion", "geometry_msgs/Vector3", "std_msgs/Header",
                                 "builtin_interfaces/Time"]),
        # depth first: DiagnosticStatus brings KeyValue before the root's next dependency, std_msgs/Header
        ("diagnostic_msgs/msg/DiagnosticArray", ["diagnostic_msgs/DiagnosticStatus", "diagnostic_msgs/KeyValue",
                                                 "std_msgs/Header", "builtin_interfaces/Time"]),
        ("std_msgs/msg/Float64MultiArray", ["std_msgs/MultiArrayLayout", "std_msgs/MultiArrayDimension"]),
        ("std_msgs/msg/Bool", []),
    ],
)  # fmt: skip
def test_schema_text_is_rosbag2_concatenation(root, deps):
    text = msgdefs.full_text(root)
    assert _sections(text) == deps
    package, _, name = root.split("/")
    parts = text.split("\n" + "=" * 80 + "\n")
    assert parts[0] == _msg_file(f"{package}/{name}")  # the root .msg unchanged, comments kept
    for dep, part in zip(deps, parts[1:], strict=True):
        assert part == f"MSG: {dep}\n" + _msg_file(dep)


def test_imu_schema_length_matches_the_measured_rosbag2_text():
    # ROS2-NOTES section 4: rosbag2's text for Imu on these wheels is 2756 characters.
    assert len(msgdefs.full_text("sensor_msgs/msg/Imu")) == 2756


@pytest.mark.filterwarnings("ignore::DeprecationWarning")  # mcap_ros2.reader warns about its ROS 1 sibling
@pytest.mark.parametrize("compression", ["zstd", "lz4", "none"])
def test_rosbags_and_mcap_ros2_read_the_values(tmp_path, compression):
    from mcap_ros2.reader import read_ros2_messages
    from rosbags.rosbag2 import Reader

    bag = tmp_path / "b"
    written = mix.write_bag(bag, 120, compression=compression, chunk_size=4096)
    expected = [(t, mix.values(ty, mix.TS.deserialize_cdr(d, ty))) for t, ty, _, d in written]
    with Reader(bag) as reader:
        got = [(c.topic, mix.values(c.msgtype, mix.TS.deserialize_cdr(raw, c.msgtype)))
               for c, _, raw in reader.messages()]  # fmt: skip
        assert reader.message_count == len(written)
    assert _same(got, expected)
    got2 = [(m.channel.topic, mix.values(m.schema.name, m.ros_msg)) for m in read_ros2_messages(bag / "b_0.mcap")]
    assert _same(got2, expected)
    # and the values are those the mix generated (not only self-consistent)
    assert expected[3][1][:2] == (0, 0) and expected[3][0] == "/amb/displacement"
    assert expected[3][1][3:] == pytest.approx(tuple(1e-5 * np.sin(np.arange(1, 5) * 0.1)))


def _same(a, b) -> bool:
    """Equal per topic in order (readers may interleave topics differently at equal log times)."""
    by_topic = lambda rows: {t: [v for tt, v in rows if tt == t] for t, _ in rows}  # noqa: E731
    return by_topic(a) == by_topic(b)


def test_metadata_yaml_v9_as_rosbag2_writes_it(tmp_path):
    from mcap.reader import make_reader
    from rosbags.rosbag2 import Reader

    bag = tmp_path / "run"
    written = mix.write_bag(bag, 60)
    text = (bag / "metadata.yaml").read_text()
    assert text.startswith("rosbag2_bagfile_information:\n  version: 9\n  storage_identifier: mcap\n")
    assert "  topics_with_message_count:\n    - topic_metadata:\n        name: " in text  # yaml-cpp indentation
    assert '  compression_format: ""\n' in text and "  ros_distro: jazzy\n" in text
    meta = load_metadata(bag)
    counts = Counter(t for t, *_ in written)
    assert {e["topic_metadata"]["name"]: e["message_count"] for e in meta["topics_with_message_count"]} == {
        t: counts.get(t, 0) for t in mix.TOPICS
    }
    assert meta["message_count"] == len(written)
    assert meta["starting_time"]["nanoseconds_since_epoch"] == min(w[2] for w in written)
    assert meta["duration"]["nanoseconds"] == max(w[2] for w in written) - min(w[2] for w in written)
    with open(bag / "run_0.mcap", "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        records = list(reader.iter_metadata())
        profile = reader.get_header().profile
    for entry in meta["topics_with_message_count"]:
        channel = next(c for c in summary.channels.values() if c.topic == entry["topic_metadata"]["name"])
        # the rosbags trap: YAML QoS must equal the channel's offered_qos_profiles, or readers return nothing
        assert profiles_from_yaml(channel.metadata["offered_qos_profiles"]) == entry["topic_metadata"][
            "offered_qos_profiles"] == [mix.RELIABLE_OFFER]  # fmt: skip
        assert channel.metadata["topic_type_hash"] == entry["topic_metadata"]["type_description_hash"]
        assert channel.metadata["topic_type_hash"].startswith("RIHS01_")
        assert summary.schemas[channel.schema_id].encoding == "ros2msg" and channel.message_encoding == "cdr"
    assert profile == "ros2"
    assert [r.name for r in records] == ["rosbag2"]
    assert yaml.safe_load(records[0].metadata["serialized_metadata"])["message_count"] == len(written)
    with Reader(bag) as r:  # rosbags' own checks on metadata.yaml
        assert r.message_count == len(written) == sum(1 for _ in r.messages())


def test_split_by_duration_and_size(tmp_path):
    from rosbags.rosbag2 import Reader

    from amb_bag.writer import BagWriter

    bag = tmp_path / "dur"
    writer = BagWriter(bag, split_duration_ns=250_000_000)
    tid = writer.add_topic("/clock", "rosgraph_msgs/msg/Clock", [mix.RELIABLE_OFFER])
    data = mix.serialize(mix.step_messages(0)[0][2], "rosgraph_msgs/msg/Clock")
    for k in range(1000):  # 1 ms apart: a new file at 250, 500, 750 ms
        writer.write(tid, 10**18 + k * 1_000_000, data, 10**18)
    meta = writer.close()
    assert [f["message_count"] for f in meta["files"]] == [250, 250, 250, 250]
    assert meta["relative_file_paths"] == [f"dur_{i}.mcap" for i in range(4)]
    with Reader(bag) as r:
        assert sum(1 for _ in r.messages()) == 1000
    sized = tmp_path / "size"
    written = mix.write_bag(sized, 300, split_size=60_000, chunk_size=8192, compression="none")
    meta = load_metadata(sized)
    assert len(meta["files"]) > 3 and sum(f["message_count"] for f in meta["files"]) == len(written)
    with Reader(sized) as r:
        assert [raw for _, _, raw in r.messages()] == [w[3] for w in written]


def test_loss_tracker_keeps_latest_count_per_status_and_sums():
    tracker = LossTracker()
    tracker.update([("plant", [("published /amb/displacement", "10"), ("rate", "5")])])
    tracker.update([("plant", [("published amb/displacement", "25")]), ("other", [("published /x", "bad")])])
    tracker.update([("sim2", [("published /amb/displacement", "7")])])
    assert tracker.published() == {"/amb/displacement": 32}
    rows = loss_table({"/amb/displacement": 30, "/clock": 4}, tracker.published())
    assert rows["/amb/displacement"] == {"received": 30, "published": 32, "lost": 2, "extra": 0}
    assert rows["/clock"] == {"received": 4, "published": None, "lost": None, "extra": None}


def test_subscription_qos_matches_every_offer():
    from rclpy.qos import DurabilityPolicy, ReliabilityPolicy

    best_effort = {**mix.RELIABLE_OFFER, "reliability": "best_effort"}
    latched = {**mix.RELIABLE_OFFER, "durability": "transient_local"}
    q = request_for_offers([mix.RELIABLE_OFFER, best_effort])
    assert (q.reliability, q.durability) == (ReliabilityPolicy.BEST_EFFORT, DurabilityPolicy.VOLATILE)
    q = request_for_offers([latched, latched])
    assert (q.reliability, q.durability) == (ReliabilityPolicy.RELIABLE, DurabilityPolicy.TRANSIENT_LOCAL)
    q = request_for_offers([latched, mix.RELIABLE_OFFER])
    assert q.durability == DurabilityPolicy.VOLATILE


@pytest.mark.parametrize("angles", [(0.3, 0.0, 0.0), (0.0, -0.4, 0.0), (0.0, 0.0, 0.25), (0.2, -0.3, 0.7)])
def test_plot_attitude_follows_the_project_axes(angles):
    from scipy.spatial.transform import Rotation

    from amb_bag.plot import euler_from_quaternion

    roll, pitch, yaw = angles
    # docs/physics.md#base-motion: R = Ry(yaw) Rz(pitch) Rx(roll), intrinsic; scipy builds it independently
    x, y, z, w = Rotation.from_euler("YZX", [yaw, pitch, roll]).as_quat()
    assert euler_from_quaternion(x, y, z, w) == pytest.approx((roll, pitch, yaw), abs=1e-12)


def test_committed_sample_bag_is_complete_and_readable():
    from rosbags.rosbag2 import Reader

    from amb_bag.loss import CUSTOM_KEY
    from amb_bag.metadata import custom_json
    from amb_bag.plot import read_series
    from amb_bag.reader import Bag
    from amb_bag.recover import check

    bag = Path(__file__).resolve().parents[1] / "bags" / "sample_pitch"
    assert sum(f.stat().st_size for f in bag.iterdir()) < 2 * 2**20
    assert check(bag, repair=False)["status"] == "ok"
    rows = custom_json(load_metadata(bag), CUSTOM_KEY)
    reported = {t: r for t, r in rows.items() if r["published"] is not None}
    assert len(reported) >= 6 and all(r["lost"] == 0 for r in reported.values())
    with Reader(bag) as reader:
        assert sum(1 for _ in reader.messages()) == reader.message_count == Bag(bag).message_count
    series = read_series(Bag(bag))
    t, attitude, _ = series["/base/imu"]  # the seed pitch case: 0.3 rad at 24.5 rad/s about Z
    assert attitude[:, 1] == pytest.approx(0.3 * np.sin(24.5 * t), abs=1e-9)
    assert np.abs(series["/amb/displacement"][1]).max() < 2.5e-3  # inside the air gap
