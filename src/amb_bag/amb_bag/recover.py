"""``amb-bag check``: verify a bag and recover a crashed recording up to its last complete chunk.

A recorder killed with ``kill -9`` leaves MCAP files without summary and footer, and no metadata.yaml.  The
standard readers return nothing from such a file; the data of every chunk that reached the disk is intact,
though, and so are the Schema and Channel records (they sit inside the chunks).  For each file that does not
verify, this module streams its records with ``NonSeekingReader(validate_crcs=True)`` in file order until the
first incomplete or corrupt record, writes them into a new file with the same schemas and channels (so QoS
metadata stays identical), renames the damaged original to ``<file>.damaged``, and writes a fresh
metadata.yaml.

What can be measured about the loss, honestly:

- ``recovered``: messages per topic in the complete chunks (exact);
- the recorder's last progress file (written every ``--progress-interval``, 0.25 s by default): messages it
  had received by then (on disk or still in the open chunk), and the publishers' ``published`` counts from
  /diagnostics by then; the recovered /diagnostics messages give published counts independently;
- ``lost_at_least = max(received, published) - recovered`` per topic: a lower bound, since messages after the
  last progress file or report are unknown.
"""

from __future__ import annotations

import json
import os
import re
import shutil
from pathlib import Path

from mcap.reader import NonSeekingReader, SeekingReader
from mcap.writer import Writer

from .errors import BagError, BagFormatError
from .loss import DIAGNOSTICS_TOPIC, RECORDER_NAME, LossTracker, custom_data, loss_table, total_lost
from .metadata import METADATA_FILE, FileRecord, TopicRecord, build_metadata, load_metadata, write_metadata
from .qos import profiles_from_yaml
from .reader import READ_ERRORS, check_mcap_magic, damaged_is_format_error
from .writer import LIBRARY, PROFILE, PROGRESS_FILE

ORIGINAL_METADATA = "metadata.yaml.orig"  # the recorder's metadata a repair replaced, kept as evidence
RECOVERY_KEY = "amb_bag.recovery"
_INDEX = re.compile(r"_(\d+)\.mcap$")


def _bag_dir(path) -> tuple[Path, Path | None]:
    """(bag folder, the single .mcap file asked for or None)."""
    path = Path(path)
    if not path.exists():
        raise BagError(f"{path} does not exist")
    if path.is_file():
        if path.name == METADATA_FILE:
            return path.parent, None
        if path.suffix != ".mcap":
            raise BagFormatError(f"{path} is not a bag folder or an .mcap file")
        return path.parent, path
    return path, None


def _files(bag_dir: Path) -> tuple[list[Path], dict | None, str | None]:
    """MCAP files of the bag (metadata order if it is readable, else by split index), metadata, its problem."""
    try:
        meta = load_metadata(bag_dir)
        files = [bag_dir / Path(p).name for p in meta["relative_file_paths"]]
        if missing := [f.name for f in files if not f.is_file()]:
            raise BagFormatError(f"files listed in {METADATA_FILE} are missing: {', '.join(missing)}")
        return files, meta, None
    except BagFormatError as exc:
        files = sorted(bag_dir.glob("*.mcap"), key=lambda p: (int(m.group(1)) if (m := _INDEX.search(p.name)) else 0,
                                                               p.name))  # fmt: skip
        if not files:
            raise BagFormatError(f"{bag_dir} is not a bag folder (no .mcap file)") from None
        return files, None, str(exc)


class _FileScan:
    """Per-file result: channels (topic -> (schema, channel)), counts, times, and what was wrong."""

    def __init__(self, path: Path):
        self.path, self.problem = path, None
        self.channels: dict[int, tuple] = {}
        self.counts: dict[str, int] = {}
        self.start, self.end = None, None
        self.loss = LossTracker()
        self.own_reports = 0  # the recorder's own /diagnostics messages (not counted in the loss)

    def add(self, schema, channel, message) -> None:
        self.channels.setdefault(channel.id, (schema, channel))
        self.counts[channel.topic] = self.counts.get(channel.topic, 0) + 1
        t = message.log_time
        self.start = t if self.start is None else min(self.start, t)
        self.end = t if self.end is None else max(self.end, t)
        if channel.topic == DIAGNOSTICS_TOPIC and self.loss.update_from_cdr(message.data, RECORDER_NAME):
            self.own_reports += 1


def verify_file(path: Path) -> _FileScan:
    """Read a whole file the strict way (summary, footer, CRCs); ``problem`` says what failed."""
    scan = _FileScan(path)
    check_mcap_magic(path)
    with open(path, "rb") as f:
        try:
            profile = SeekingReader(f).get_header().profile
        except READ_ERRORS:
            profile = PROFILE  # an unreadable header is damage, found below
    if profile != PROFILE:
        raise BagFormatError(f"{path} is an MCAP file but not a ROS 2 bag (profile {profile!r})")
    try:
        with damaged_is_format_error(path, ""), open(path, "rb") as f:
            reader = SeekingReader(f, validate_crcs=True)
            summary = reader.get_summary()
            if summary is None or summary.statistics is None:
                raise BagFormatError(f"{path} has no summary")
            for schema, channel, message in reader.iter_messages(log_time_order=False):
                scan.add(schema, channel, message)
            for channel_id, channel in summary.channels.items():  # channels without messages
                scan.channels.setdefault(channel_id, (summary.schemas[channel.schema_id], channel))
            if summary.statistics.message_count != sum(scan.counts.values()):
                raise BagFormatError(f"{path}: summary count differs from the messages in the file")
    except BagFormatError as exc:
        scan.problem = str(exc)
    return scan


def salvage_file(path: Path) -> _FileScan:
    """Stream ``path`` in file order (CRC-checked) until the first incomplete record; keep the messages."""
    scan, messages = _FileScan(path), []
    with open(path, "rb") as f:
        try:
            for schema, channel, message in NonSeekingReader(f, validate_crcs=True).iter_messages(log_time_order=False):
                scan.add(schema, channel, message)
                messages.append((channel.id, message))
        except READ_ERRORS as exc:
            scan.problem = f"stopped at {type(exc).__name__}"
    scan.messages = messages
    return scan


def _rewrite(scan: _FileScan) -> None:
    """Write the salvaged messages to a new file with the original schemas and channels, then swap it in."""
    tmp = scan.path.with_name(scan.path.name + ".recovering")
    try:
        _write_salvaged(tmp, scan)
    except OSError:
        tmp.unlink(missing_ok=True)  # disk full: nothing half-written is left, the original stays as it was
        raise
    os.replace(scan.path, scan.path.with_name(scan.path.name + ".damaged"))
    os.replace(tmp, scan.path)


def _write_salvaged(tmp: Path, scan: _FileScan) -> None:
    with open(tmp, "wb") as f:
        writer = Writer(f)
        writer.start(profile=PROFILE, library=LIBRARY + " (recovered)")
        schema_ids, channel_ids = {}, {}
        for cid, (schema, channel) in sorted(scan.channels.items()):
            if schema.id not in schema_ids:
                schema_ids[schema.id] = writer.register_schema(schema.name, schema.encoding, schema.data)
            channel_ids[cid] = writer.register_channel(
                channel.topic, channel.message_encoding, schema_ids[schema.id], channel.metadata
            )
        for cid, m in scan.messages:
            writer.add_message(channel_ids[cid], m.log_time, m.data, m.publish_time, m.sequence)
        writer.finish()


def _progress(bag_dir: Path) -> dict:
    try:
        data = json.loads((bag_dir / PROGRESS_FILE).read_text())
        return data if isinstance(data, dict) else {}
    except (OSError, ValueError):
        return {}


def check(path, repair: bool = True) -> dict:
    """Verify the bag at ``path``; if damaged (and ``repair``), recover it.  Returns the report dict.

    ``path`` is a bag folder, or one .mcap file (alone, it is checked and recovered in place, without a
    metadata.yaml).  Report keys: ``bag``, ``status`` ('ok' | 'recovered' | 'damaged'), ``files`` (per file:
    problem, messages), ``topics`` (per topic: recovered, received, published, lost_at_least),
    ``recovered_messages``, ``lost_at_least``.
    """
    bag_dir, single = _bag_dir(path)
    lone = single is not None and not (bag_dir / METADATA_FILE).exists() and not (bag_dir / PROGRESS_FILE).exists()
    files, meta, meta_problem = ([single], None, None) if lone else _files(bag_dir)
    scans = [verify_file(f) for f in files]
    damaged = [s for s in scans if s.problem]
    if damaged:
        scans = [salvage_file(s.path) if s.problem else s for s in scans]
    where = single if lone else bag_dir
    intact_meta = lone or (meta is not None and meta["message_count"] == sum(sum(s.counts.values()) for s in scans))
    if not damaged and intact_meta:
        return _report(where, "ok", scans, _rows(scans, {}), [])
    progress = {} if lone else _progress(bag_dir)
    original = original_counts(meta)  # a surviving metadata.yaml: the counts the recorder wrote are evidence
    rows = _rows(scans, progress, original)
    if not repair:
        return _report(where, "damaged", scans, rows, damaged, meta_problem)
    for scan in scans:
        if getattr(scan, "messages", None) is not None:
            _rewrite(scan)
    report = _report(where, "recovered", scans, rows, damaged, meta_problem)
    if not lone:
        if original:
            keep_original_metadata(bag_dir)
            report["original_metadata"] = ORIGINAL_METADATA
        _write_metadata(bag_dir, scans, rows, report)
        (bag_dir / PROGRESS_FILE).unlink(missing_ok=True)
    return report


def _rows(scans: list[_FileScan], progress: dict, original: dict[str, int] | None = None) -> dict:
    recovered: dict[str, int] = {}
    tracker = LossTracker()
    own = sum(scan.own_reports for scan in scans)
    for scan in scans:
        for topic, n in scan.counts.items():
            recovered[topic] = recovered.get(topic, 0) + n
        tracker.reported.update(scan.loss.reported)  # files in time order: later reports win
    published = tracker.published()
    for topic, n in (progress.get("published") or {}).items():
        published[topic] = max(published.get(topic, 0), int(n))
    received = {t: int(n) for t, n in (progress.get("received") or {}).items()}
    rows = {}
    original = original or {}
    for topic in sorted(set(recovered) | set(published) | set(received) | set(original)):
        got = recovered.get(topic, 0)
        from_others = got - (own if topic == DIAGNOSTICS_TOPIC else 0)
        known = max(received.get(topic, 0), published.get(topic, 0))
        rows[topic] = {
            "recovered": got,
            "received": received.get(topic),
            "published": published.get(topic),
            # the surviving metadata counted what was written (the recorder's own reports included)
            "lost_at_least": max(0, known - from_others, original.get(topic, 0) - got),
        }
        if topic in original:
            rows[topic]["in_original_metadata"] = original[topic]
    return rows


def original_counts(meta: dict | None) -> dict[str, int]:
    """Per-topic message counts of a metadata.yaml that survived the crash ({} without one)."""
    if not meta:
        return {}
    return {e["topic_metadata"]["name"]: int(e["message_count"]) for e in meta["topics_with_message_count"]}


def keep_original_metadata(bag_dir: Path) -> None:
    """Keep the metadata.yaml being replaced as ``metadata.yaml.orig`` (the first one: a second check keeps it)."""
    target = bag_dir / ORIGINAL_METADATA
    if not target.exists():
        shutil.copy2(bag_dir / METADATA_FILE, target)


def _report(bag_dir, status, scans, rows, damaged, meta_problem=None) -> dict:
    return {
        "bag": str(bag_dir),
        "status": status,
        "metadata_problem": meta_problem,
        "files": {s.path.name: {"problem": s.problem, "messages": sum(s.counts.values())} for s in scans},
        "damaged_files": [s.path.name for s in damaged],
        "topics": rows,
        "recovered_messages": sum(r["recovered"] for r in rows.values()),
        "lost_at_least": sum(r["lost_at_least"] for r in rows.values()),
    }


def _write_metadata(bag_dir: Path, scans: list[_FileScan], rows: dict, report: dict) -> None:
    topics: dict[str, TopicRecord] = {}
    for scan in scans:
        for schema, channel in scan.channels.values():
            if channel.topic not in topics:
                profiles = profiles_from_yaml(channel.metadata.get("offered_qos_profiles", ""))
                topics[channel.topic] = TopicRecord(
                    channel.topic, schema.name, profiles, channel.metadata.get("topic_type_hash", "")
                )
    for topic, record in topics.items():
        record.message_count = rows.get(topic, {}).get("recovered", 0)
    files = [
        FileRecord(s.path.name, s.start, s.end - s.start, sum(s.counts.values())) if s.start is not None
        else FileRecord(s.path.name)
        for s in scans
    ]  # fmt: skip
    own = sum(scan.own_reports for scan in scans)
    received = {t: r["recovered"] - (own if t == DIAGNOSTICS_TOPIC else 0) for t, r in rows.items()}
    published = {t: r["published"] for t, r in rows.items() if r["published"] is not None}
    keys = ("damaged_files", "recovered_messages", "lost_at_least", "original_metadata")
    extra = {RECOVERY_KEY: json.dumps({k: report[k] for k in keys if k in report}, separators=(",", ":"))}
    loss = loss_table(received, published)
    write_metadata(bag_dir, build_metadata(list(topics.values()), files, {**custom_data(loss), **extra}))
    report["lost_vs_publishers"] = total_lost(loss)
