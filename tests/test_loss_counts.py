"""Counts that never lie (issue 20 item 3): stamp gaps seen by the recorder itself, unknown never summed as 0.

Before: a standalone ``amb-bag record`` that lost 6,067 of 15,001 samples (no /diagnostics on the domain, so
no published counts) printed ``lost in total: 0``.  The messages here are serialized by rclpy (not by the code
under test) with stamps on a 5 kHz grid; the expected losses are the samples the test drops.
"""

from __future__ import annotations

import numpy as np
import pytest

from amb_bag.loss import custom_data, format_table, loss_table, unknown_topics
from amb_bag.stamp_gaps import StampGaps, stamp_ns

TS_NS = 200_000  # 5 kHz


def _joint_state(k: int) -> bytes:
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import JointState

    msg = JointState()
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(k * TS_NS, 1_000_000_000)
    msg.name = ["v1", "w1", "v2", "w2"]
    msg.position = [1e-5 * k] * 4
    return serialize_message(msg)


def test_stamp_of_a_serialized_header_is_read_back():
    assert stamp_ns(_joint_state(123_456)) == 123_456 * TS_NS
    assert stamp_ns(b"\x00\x01\x00\x00") is None


def test_gaps_on_the_grid_are_counted_without_any_published_count():
    rng = np.random.default_rng(7)
    n = 15_001
    dropped = set(rng.choice(np.arange(1, n - 1), size=6_067, replace=False).tolist())  # first and last kept
    gaps = StampGaps()
    for k in range(n):
        if k not in dropped:
            data = _joint_state(k)
            gaps.add("/amb/displacement", data)
            if k % 1000 == 0:
                gaps.add("/amb/displacement", data)  # a duplicate is not a sample
    assert gaps.missing() == {"/amb/displacement": 6_067}
    rows = loss_table({"/amb/displacement": n - 6_067, "/rosout": 3}, {}, gaps.missing())
    assert rows["/amb/displacement"]["lost"] == 6_067 and rows["/amb/displacement"]["published"] is None
    assert unknown_topics(rows) == ["/rosout"]
    text = format_table(rows)
    assert "lost in total: 6067 on 1 topics; unknown on 1 without a count (/rosout)" in text
    assert custom_data(rows)["amb_bag.lost_total"] == "at least 6067 (some unknown)"


@pytest.mark.parametrize(("published", "gap", "lost"), [(100, 3, 5), (100, 9, 9), (None, 0, 0), (None, None, None)])
def test_lost_is_the_larger_of_the_publisher_count_and_the_stamp_gaps(published, gap, lost):
    rows = loss_table({"/amb/current": 95}, {} if published is None else {"/amb/current": published},
                      None if gap is None else {"/amb/current": gap})  # fmt: skip
    assert rows["/amb/current"]["lost"] == lost
    assert ("lost in total: 0" in format_table(rows)) == (lost == 0)
    if lost is None:
        assert "lost in total: unknown (no count for /amb/current)" in format_table(rows)


def test_check_keeps_the_evidence_of_a_truncated_bag_whose_metadata_survived(tmp_path, capsys):
    """lost = the count the surviving metadata.yaml recorded - the messages recovered; the original is kept."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).parent / "bagtools"))
    import mix

    from amb_bag import cli
    from amb_bag.metadata import load_metadata

    bag = tmp_path / "good"
    mix.write_bag(bag, 40, chunk_size=2048)
    original = (bag / "metadata.yaml").read_bytes()
    total = load_metadata(bag)["message_count"]
    data = (bag / "good_0.mcap").read_bytes()
    (bag / "good_0.mcap").write_bytes(data[: len(data) * 3 // 10])  # the summary and some chunks lost
    with pytest.raises(SystemExit) as exc:
        cli.main(["check", str(bag), "--json"])
    assert exc.value.code == cli.EXIT_DAMAGED
    import json

    report = json.loads(capsys.readouterr().out)
    recovered = report["recovered_messages"]
    assert 0 < recovered < total
    assert report["lost_at_least"] == total - recovered  # every message the original metadata counted
    assert (bag / "metadata.yaml.orig").read_bytes() == original  # the evidence, byte for byte
    assert load_metadata(bag)["message_count"] == recovered  # the repaired bag describes what it holds
    with pytest.raises(SystemExit) as exc:
        cli.main(["check", str(bag)])
    assert exc.value.code == 0 and (bag / "metadata.yaml.orig").read_bytes() == original
