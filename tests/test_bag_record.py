"""Recording over DDS (spawned processes, localhost only): completeness, loss accounting, crash recovery, replay.

The test publisher (tests/bagtools/publisher.py) publishes the docs/topics.md topic mix as raw CDR bytes and logs
exactly what it sent; the recorder must hold every message, byte for byte, and independent readers (rosbags,
mcap_ros2) must decode the values the publisher generated.
"""

from __future__ import annotations

import io
import json
import pickle
import re
import sys
import time
from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest

from procs import spawn

sys.path.insert(0, str(Path(__file__).parent / "bagtools"))
import mix

from amb_bag import cli
from amb_bag.loss import CUSTOM_KEY
from amb_bag.metadata import custom_json, load_metadata

pytestmark = [pytest.mark.ros, pytest.mark.slow]
PUBLISHER = Path(__file__).parent / "bagtools" / "publisher.py"
STEPS = 1000
RUN_TIMEOUT_S = 90


def _by_topic(pairs) -> dict[str, list[bytes]]:
    out = defaultdict(list)
    for topic, data in pairs:
        out[topic].append(data)
    return dict(out)


def _record(tmp: Path, venv_bin: Path, name: str, rec_args=(), pub_args=(), steps=STEPS, rate=1000):
    """Record one publisher run; returns (bag, sent [(topic, bytes)], recorder log text)."""
    bag, sent = tmp / name, tmp / f"{name}-sent.pkl"
    rec_cmd = [str(venv_bin / "amb-bag"), "record", "-o", str(bag), *rec_args]
    pub_cmd = [sys.executable, str(PUBLISHER), "--steps", str(steps), "--rate", str(rate), "--log", str(sent),
               "--wait-subscribers", "30", *pub_args]  # fmt: skip
    with spawn(rec_cmd, tmp / f"{name}-rec.log") as rec:
        assert rec.wait_for("recording to", 30), rec.text()
        with spawn(pub_cmd, tmp / f"{name}-pub.log") as pub:
            assert pub.wait(RUN_TIMEOUT_S) == 0, pub.text()
            assert "publisher: subscribed 9" in pub.text(), pub.text()
        assert rec.stop() == 0, rec.log.read_text()
        return bag, pickle.loads(sent.read_bytes()), rec.log.read_text()


def _recorder_report(topic: str, data: bytes) -> bool:
    """A /diagnostics message of the recorder itself (recorded, but not something the publisher sent)."""
    if topic != "/diagnostics":
        return False
    msg = mix.TS.deserialize_cdr(data, mix.TOPICS[topic])
    return all(s.name == "amb_bag_recorder" for s in msg.status)


def _bag_bytes(bag: Path, keep_own: bool = False) -> dict[str, list[bytes]]:
    from rosbags.rosbag2 import Reader

    with Reader(bag) as reader:
        return _by_topic((c.topic, bytes(raw)) for c, _, raw in reader.messages()
                         if keep_own or not _recorder_report(c.topic, bytes(raw)))  # fmt: skip


@pytest.fixture(scope="module")
def run(tmp_path_factory, venv_bin):
    tmp = tmp_path_factory.mktemp("bagrun")
    return _record(tmp, venv_bin, "run")


def test_every_message_recorded_byte_equal(run):
    bag, sent, _ = run
    recorded, expected = _bag_bytes(bag), _by_topic(sent)
    assert set(expected) == set(mix.TOPICS)
    for topic in mix.TOPICS:
        assert len(recorded[topic]) == len(expected[topic]), topic
        assert recorded[topic] == expected[topic], topic
    assert len(expected["/clock"]) == STEPS and len(expected["/diagnostics"]) == STEPS // 100 + 1


def test_loss_statistics_are_zero_and_match_the_publisher(run):
    bag, sent, log = run
    rows = custom_json(load_metadata(bag), CUSTOM_KEY)
    counts = {t: len(v) for t, v in _by_topic(sent).items()}
    for topic in mix.TOPICS:
        assert rows[topic] == {"received": counts[topic], "published": counts[topic], "lost": 0, "extra": 0}
    assert "lost in total: 0" in log


@pytest.mark.filterwarnings("ignore::DeprecationWarning")  # mcap_ros2.reader warns about its ROS 1 sibling
def test_independent_readers_decode_the_sent_values(run):
    from mcap_ros2.reader import read_ros2_messages
    from rosbags.rosbag2 import Reader

    bag, sent, _ = run
    expected = defaultdict(list)
    for topic, data in sent:
        expected[topic].append(mix.values(mix.TOPICS[topic], mix.TS.deserialize_cdr(data, mix.TOPICS[topic])))
    got = defaultdict(list)
    with Reader(bag) as reader:
        for c, _, raw in reader.messages():
            if not _recorder_report(c.topic, bytes(raw)):
                got[c.topic].append(mix.values(c.msgtype, mix.TS.deserialize_cdr(raw, c.msgtype)))
    got2 = defaultdict(list)
    for path in sorted(bag.glob("*.mcap")):
        for m in read_ros2_messages(path):
            if not (m.channel.topic == "/diagnostics" and m.ros_msg.status[0].name == "amb_bag_recorder"):
                got2[m.channel.topic].append(mix.values(m.schema.name, m.ros_msg))
    for topic in mix.TOPICS:
        assert got[topic] == expected[topic] == got2[topic], topic
    # the values are the generated ones: step 10's displacement is 1e-5 sin(0.1 i + 0.01)
    assert expected["/amb/displacement"][10][3:] == pytest.approx(tuple(1e-5 * np.sin(np.arange(1, 5) * 0.1 + 0.01)))


def test_info_and_plot_series_from_the_recorded_run(run, tmp_path, capsys):
    from amb_bag.plot import read_series
    from amb_bag.reader import Bag

    bag, sent, _ = run
    with pytest.raises(SystemExit) as exc:
        cli.main(["info", str(bag), "--json"])
    assert exc.value.code == 0
    info = json.loads(capsys.readouterr().out)
    counts = {t: len(v) for t, v in _by_topic(sent).items()}
    counts["/diagnostics"] += len(_bag_bytes(bag, keep_own=True)["/diagnostics"]) - counts["/diagnostics"]  # + own
    assert {t["name"]: t["message_count"] for t in info["topics"] if t["name"] in mix.TOPICS} == counts
    assert info["message_count"] >= len(sent) and 0.5 < info["duration_s"] < 30
    series = read_series(Bag(bag))
    t, rho, _ = series["/stability/multipliers"]
    k = np.arange(0, STEPS, mix.MULTIPLIER_EVERY)
    assert rho[:, 0] == pytest.approx(np.hypot(0.9 + 1e-4 * k, 0.1), rel=1e-12)  # max |mu| of the sent pairs
    t_disp, _, names = series["/amb/displacement"]
    assert names == mix.CHANNELS and t_disp == pytest.approx(np.arange(STEPS) * mix.STEP_S, abs=1e-9)
    # log time mapped through /clock to simulated time: a retransmitted sample arrives late, hence the median
    assert np.median(np.abs(t - k * mix.STEP_S)) <= 2 * mix.STEP_S
    assert np.all(t >= (k - 1) * mix.STEP_S) and np.all(t <= (k + 250) * mix.STEP_S)
    t_imu, attitude, _ = series["/base/imu"]  # the mix pitches the base: 0.3 sin(24.5 t) about Z
    assert attitude[:, 1] == pytest.approx(0.3 * np.sin(24.5 * t_imu), abs=1e-12)
    assert np.abs(attitude[:, [0, 2]]).max() < 1e-15
    with pytest.raises(SystemExit) as exc:
        cli.main(["plot", str(bag), "--out", str(tmp_path / "run.png")])
    assert exc.value.code == 0 and (tmp_path / "run.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_slow_recorder_reports_loss(tmp_path, venv_bin):
    # Test-only slowness: 2 ms per message and KEEP_LAST 2 subscriptions, against a publisher flat out.
    bag, sent, log = _record(tmp_path, venv_bin, "slow", ["--debug-delay-per-message", "0.002", "--qos-depth", "2"],
                             steps=300, rate=0)  # fmt: skip
    rows = custom_json(load_metadata(bag), CUSTOM_KEY)
    counts = {t: len(v) for t, v in _by_topic(sent).items()}
    recorded = _bag_bytes(bag)
    for topic, sent_n in (("/clock", 300), ("/amb/displacement", 300), ("/amb_plant/state", 300 // mix.STATE_BLOCK)):
        row = rows[topic]
        assert row["published"] == counts[topic] == sent_n
        assert row["received"] == len(recorded.get(topic, []))
        assert row["lost"] == sent_n - row["received"] > 0
    assert f"lost in total: {sum(r['lost'] or 0 for r in rows.values())}" in log


def test_slow_recorder_without_any_diagnostics_counts_its_own_gaps(tmp_path, venv_bin):
    """A publisher that sends no /diagnostics (nobody reports a count) and a recorder that cannot keep up: the
    recorder counts the samples missing between the stamps it got, never "lost in total: 0".  The first step is
    settled (acknowledged, then 1 s for the slow recorder to take it) and the last stays in its reader queue, so
    every sample it lost lies between two it has: lost = sent - received exactly, with sent known here."""
    bag, sent, log = _record(tmp_path, venv_bin, "blind", ["--debug-delay-per-message", "0.002", "--qos-depth", "2"],
                             ["--diag-every", "0", "--settle-first", "1.0"], steps=300, rate=0)  # fmt: skip
    assert not _by_topic(sent).get("/diagnostics")  # the publisher reported nothing
    rows = custom_json(load_metadata(bag), CUSTOM_KEY)
    recorded = _bag_bytes(bag)["/amb/displacement"]
    sent_n = len(_by_topic(sent)["/amb/displacement"])
    assert sent_n == 300 and recorded[0] == _by_topic(sent)["/amb/displacement"][0]  # the first step was taken
    row = rows["/amb/displacement"]
    assert row["published"] is None and row["received"] == len(recorded) < sent_n
    assert row["lost"] == sent_n - len(recorded), row
    assert "lost in total: 0" not in log
    assert re.search(r"lost in total: \d+ on \d+ topics; unknown on \d+ without a count", log), log[-2000:]


def _messages_in_complete_chunks(path: Path) -> int:
    """Count Message records inside the complete Chunk records of a (crashed) file, with mcap's stream parser."""
    import zstandard
    from mcap.exceptions import McapError
    from mcap.records import Chunk, Message
    from mcap.stream_reader import StreamReader

    def count(records) -> int:
        n = 0
        try:
            for record in records:
                if isinstance(record, Chunk):
                    data = zstandard.decompress(record.data) if record.compression == "zstd" else record.data
                    n += count(StreamReader(io.BytesIO(data), skip_magic=True).records)
                n += isinstance(record, Message)
        except McapError:  # end of a chunk's records, or the truncated tail of the file
            pass
        return n

    with open(path, "rb") as f:
        return count(StreamReader(f, emit_chunks=True).records)


def test_kill_9_then_check_recovers_all_complete_chunks(tmp_path, venv_bin, capsys):
    from rosbags.rosbag2 import Reader

    bag, sent_log, steps = tmp_path / "crash", tmp_path / "crash-sent.pkl", 1500
    rec_cmd = [str(venv_bin / "amb-bag"), "record", "-o", str(bag), "--flush-interval", "3600",
               "--progress-interval", "0.1", "--topics", *mix.TOPICS]  # fmt: skip
    pub_cmd = [sys.executable, str(PUBLISHER), "--steps", str(steps), "--rate", "2000", "--log", str(sent_log),
               "--wait-subscribers", "30"]  # fmt: skip
    n_diag = steps // 100 + 1
    with spawn(rec_cmd, tmp_path / "crash-rec.log") as rec:
        with spawn(pub_cmd, tmp_path / "crash-pub.log") as pub:
            assert pub.wait(RUN_TIMEOUT_S) == 0, pub.text()
        progress_file = bag / ".amb_bag_progress.json"
        end = time.monotonic() + 20
        while time.monotonic() < end:  # until the recorder has received everything (partly still in memory)
            progress = json.loads(progress_file.read_text()) if progress_file.exists() else {}
            if progress.get("received", {}).get("/diagnostics") == n_diag:
                break
            time.sleep(0.05)
        rec.popen.kill()  # SIGKILL: no chance to write the open chunk, the summary or metadata.yaml
        rec.popen.wait()
    sent = _by_topic(pickle.loads(sent_log.read_bytes()))
    assert progress["received"] == {t: len(v) for t, v in sent.items()}
    in_chunks = _messages_in_complete_chunks(bag / "crash_0.mcap")
    with pytest.raises(SystemExit) as exc:
        cli.main(["check", str(bag), "--json"])
    assert exc.value.code == cli.EXIT_DAMAGED
    report = json.loads(capsys.readouterr().out)
    total = sum(len(v) for v in sent.values())
    own = sum(len(v) for v in _bag_bytes(bag, keep_own=True).values()) - sum(len(v) for v in _bag_bytes(bag).values())
    assert report["recovered_messages"] == in_chunks == sum(progress["on_disk"].values())
    # the open chunk, known from the progress file (the recorder's own reports are not part of the loss)
    assert report["lost_at_least"] == total - (in_chunks - own) > 0
    recovered = _bag_bytes(bag)
    for topic, data in recovered.items():
        assert data == sent[topic][: len(data)], topic  # a prefix of what was sent, byte-equal
    with Reader(bag) as reader:
        assert reader.message_count == in_chunks
    assert (bag / "crash_0.mcap.damaged").exists() and not progress_file.exists()


def test_play_then_record_again_gives_the_same_messages(run, tmp_path, venv_bin):
    bag, _, _ = run
    again = tmp_path / "again"
    rec_cmd = [str(venv_bin / "amb-bag"), "record", "-o", str(again), "--topics", *mix.TOPICS]
    play_cmd = [str(venv_bin / "amb-bag"), "play", str(bag), "--rate", "0.5", "--wait-for-subscribers", "30",
                "--topics", *mix.TOPICS]  # fmt: skip
    with spawn(rec_cmd, tmp_path / "again-rec.log") as rec:
        assert rec.wait_for("recording to", 30), rec.text()
        with spawn(play_cmd, tmp_path / "play.log") as player:
            assert player.wait(RUN_TIMEOUT_S) == 0, player.text()
        in_bag = sum(len(v) for t, v in _bag_bytes(bag, keep_own=True).items() if t in mix.TOPICS)
        assert f"published {in_bag} messages" in player.log.read_text()
        assert rec.stop() == 0, rec.log.read_text()
    assert _bag_bytes(again) == {t: v for t, v in _bag_bytes(bag).items() if t in mix.TOPICS}
    first, second = _clock_span(bag), _clock_span(again)
    assert second == pytest.approx(2 * first, rel=0.25)  # --rate 0.5 doubles the spacing


def _clock_span(bag: Path) -> int:
    """Log-time span (ns) of the /clock messages of a bag."""
    from amb_bag.reader import Bag

    times = [log for _, _, log, _, _ in Bag(bag).messages(["/clock"])]
    return max(times) - min(times)


def test_late_best_effort_publisher_widens_the_subscription(tmp_path, venv_bin):
    """A reliable publisher first, then a best-effort one on the same topics: the recorder widens its QoS."""
    bag = tmp_path / "mixed"
    rec_cmd = [str(venv_bin / "amb-bag"), "record", "-o", str(bag), "--topics", *mix.TOPICS]
    pub = [sys.executable, str(PUBLISHER), "--steps", "300", "--rate", "500", "--wait-subscribers", "30"]
    with spawn(rec_cmd, tmp_path / "mixed-rec.log") as rec:
        with spawn([*pub, "--name", "reliable_pub", "--log", str(tmp_path / "a.pkl")], tmp_path / "a.log") as a:
            assert a.wait(RUN_TIMEOUT_S) == 0 and "publisher: subscribed 9" in a.text(), a.text()
        with spawn([*pub, "--name", "best_effort_pub", "--best-effort"], tmp_path / "b.log") as b:
            assert b.wait(RUN_TIMEOUT_S) == 0, b.text()
            subscribed = b.text()
        assert rec.stop() == 0
    log = rec.log.read_text()
    # the best-effort publisher only starts once it is matched, which needs the widened subscription
    assert "publisher: subscribed 9" in subscribed, subscribed
    assert "/clock: new publisher QoS, subscription widened" in log, log
    sent_a = _by_topic(pickle.loads((tmp_path / "a.pkl").read_bytes()))
    recorded = _bag_bytes(bag)
    assert recorded["/clock"][:300] == sent_a["/clock"]  # the reliable run, complete and in order
    assert len(recorded["/clock"]) > 300  # and the best-effort one was recorded too
    rows = custom_json(load_metadata(bag), CUSTOM_KEY)
    assert rows["/clock"]["published"] == 600
    assert rows["/clock"]["lost"] == 600 - rows["/clock"]["received"] == 600 - len(recorded["/clock"])
