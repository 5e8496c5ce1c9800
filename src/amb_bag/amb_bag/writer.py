"""Bag writer: a rosbag2-layout folder of chunked MCAP files written from pre-serialized CDR bytes.

``<bag>/<name>_<i>.mcap`` (profile ``ros2``; schemas ``ros2msg`` with rosbag2's concatenated definitions;
channels ``cdr`` with ``offered_qos_profiles`` and ``topic_type_hash`` metadata; a ``rosbag2`` metadata record at
the end of each file) plus ``metadata.yaml`` v9 on close.  Crash safety: the file is unbuffered, so each chunk
reaches the operating system when it is finished (the writer notices and notes the per-topic counts then on disk);
:meth:`BagWriter.flush` finishes the open chunk early; :meth:`BagWriter.write_progress` writes
``.amb_bag_progress.json`` (messages received so far, messages on disk, plus what the caller adds), which
``amb-bag check`` uses after a ``kill -9`` to say how many received messages were lost.  Only the chunk being
filled is lost in a crash.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

from mcap.writer import CompressionType, Writer

from . import msgdefs
from .errors import BagError
from .metadata import TIME_MAX_NS, FileRecord, TopicRecord, build_metadata, dump_yaml, write_metadata
from .qos import profiles_to_yaml

PROFILE = "ros2"
LIBRARY = "amb_bag (rosbag2 mcap layout)"
DEFAULT_CHUNK_SIZE = 64 * 1024  # bytes, uncompressed: small, so that a crash loses little
PROGRESS_FILE = ".amb_bag_progress.json"
COMPRESSION = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "none": CompressionType.NONE}
NEVER = 2**63  # split thresholds when splitting is off


class _FileSink:
    """Unbuffered append-only file: ``write`` hands each record group straight to the OS (no user buffer)."""

    def __init__(self, path: Path):
        self._fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
        self.pos = 0

    def write(self, data) -> int:
        view = memoryview(data)
        while view:
            n = os.write(self._fd, view)
            view = view[n:]
        self.pos += len(data)
        return len(data)

    def tell(self) -> int:
        return self.pos

    def flush(self) -> None:
        pass

    def close(self) -> None:
        os.close(self._fd)


class BagWriter:
    """Write messages (raw CDR bytes) into a new rosbag2-layout MCAP bag.

    Parameters
    ----------
    bag_dir : path
        Output folder; must not exist (or be empty).  Files are ``<name>_<i>.mcap`` with ``name`` its basename.
    compression : {'zstd', 'lz4', 'none'}
        Chunk compression.
    chunk_size : int
        Uncompressed chunk size (bytes) at which a chunk is finished and written.
    split_size : int, optional
        Start a new file once the current one reaches this many bytes.
    split_duration_ns : int, optional
        Start a new file once its messages span this long (log time, ns).
    """

    def __init__(self, bag_dir, compression="zstd", chunk_size=DEFAULT_CHUNK_SIZE, split_size=None,
                 split_duration_ns=None):  # fmt: skip
        if compression not in COMPRESSION:
            raise BagError(f"unknown compression {compression!r} (choose zstd, lz4 or none)")
        if chunk_size <= 0 or (split_size is not None and split_size <= 0):
            raise BagError("chunk and split sizes must be positive")
        if split_duration_ns is not None and split_duration_ns <= 0:
            raise BagError("split duration must be positive")
        self.dir = Path(bag_dir)
        if self.dir.exists() and (not self.dir.is_dir() or any(self.dir.iterdir())):
            raise BagError(f"output {self.dir} already exists (choose a new bag name)")
        try:
            self.dir.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise BagError(f"cannot create {self.dir}: {exc.strerror}") from None
        self.name = self.dir.resolve().name
        self.compression, self.chunk_size = compression, int(chunk_size)
        self._split_bytes = int(split_size) if split_size else NEVER
        self._split_ns = int(split_duration_ns) if split_duration_ns else NEVER
        self.topics: list[TopicRecord] = []
        self._on_disk: list[int] = []
        self.files: list[FileRecord] = []
        self._schemas: dict[str, int] = {}
        self._open_file()

    # -- files ---------------------------------------------------------------------------------------------
    def _open_file(self) -> None:
        rel = f"{self.name}_{len(self.files)}.mcap"
        self._sink = _FileSink(self.dir / rel)
        self._mcap = Writer(self._sink, chunk_size=self.chunk_size, compression=COMPRESSION[self.compression])
        self._mcap.start(profile=PROFILE, library=LIBRARY)
        self._add = self._mcap.add_message  # bound once: the hot path calls it per message
        self.files.append(FileRecord(rel))
        self._file_min, self._file_max, self._file_count = TIME_MAX_NS, 0, 0
        self._schemas = {}
        for topic in self.topics:
            self._register(topic)

    def _register(self, topic: TopicRecord) -> int:
        schema_id = self._schemas.get(topic.type)
        if schema_id is None:
            text = msgdefs.full_text(topic.type).encode()
            schema_id = self._mcap.register_schema(topic.type, msgdefs.SCHEMA_ENCODING, text)
            self._schemas[topic.type] = schema_id
        metadata = {
            "offered_qos_profiles": profiles_to_yaml(topic.offered_qos_profiles),
            "topic_type_hash": topic.type_description_hash,
        }
        return self._mcap.register_channel(topic.name, msgdefs.MESSAGE_ENCODING, schema_id, metadata)

    def _close_file(self, custom_data: dict | None = None) -> None:
        record = self.files[-1]
        if self._file_count:
            record.starting_time_ns = self._file_min
            record.duration_ns = self._file_max - self._file_min
        record.message_count = self._file_count
        meta = {"serialized_metadata": dump_yaml(self.metadata(custom_data), root_key=None), "ROS_DISTRO": "jazzy"}
        self._mcap.add_metadata("rosbag2", meta)
        self._mcap.finish()
        self._sink.close()

    def _split(self) -> None:
        self._close_file()
        self._open_file()

    # -- topics and messages -------------------------------------------------------------------------------
    def add_topic(self, name: str, type_name: str, offered_qos_profiles: list[dict], type_hash: str = "") -> int:
        """Register a topic (one MCAP channel per file); returns its id for :meth:`write`."""
        topic = TopicRecord(name, type_name, list(offered_qos_profiles), type_hash or msgdefs.type_hash(type_name))
        self.topics.append(topic)
        channel_id = self._register(topic)
        if channel_id != len(self.topics):
            raise AssertionError("channel ids must follow topic order")
        return len(self.topics) - 1

    def write(self, topic_id: int, log_time: int, data: bytes, publish_time: int, sequence: int = 0) -> None:
        """Append one serialized message; ``log_time`` / ``publish_time`` in ns since the epoch."""
        if log_time - self._file_min >= self._split_ns or self._sink.pos >= self._split_bytes:
            self._split()
        pos = self._sink.pos
        self._add(topic_id + 1, log_time, data, publish_time, sequence)
        self.topics[topic_id].message_count += 1
        if self._sink.pos != pos:  # a chunk (holding this message) was just written
            self._on_disk = [t.message_count for t in self.topics]
        self._file_count += 1
        if log_time < self._file_min:
            self._file_min = log_time
        if log_time > self._file_max:
            self._file_max = log_time

    @property
    def message_count(self) -> int:
        return sum(t.message_count for t in self.topics)

    # -- crash safety, metadata, close ----------------------------------------------------------------------
    def flush(self) -> None:
        """Finish the open chunk now, so that everything written so far is on disk."""
        self._mcap.flush()
        self._on_disk = [t.message_count for t in self.topics]

    def write_progress(self, extra: dict | None = None) -> None:
        """Write the progress file: per topic, messages written so far and messages already on disk."""
        on_disk = self._on_disk + [0] * (len(self.topics) - len(self._on_disk))
        progress = {
            "written": {t.name: t.message_count for t in self.topics},
            "on_disk": {t.name: n for t, n in zip(self.topics, on_disk, strict=True)},
            "files": [f.path for f in self.files],
            **(extra or {}),
        }
        tmp = self.dir / (PROGRESS_FILE + ".tmp")
        tmp.write_text(json.dumps(progress))
        os.replace(tmp, self.dir / PROGRESS_FILE)

    def metadata(self, custom_data: dict | None = None) -> dict:
        """The bag metadata as it stands (the current file's statistics included)."""
        files = [*self.files[:-1], self._current_file_record()]
        return build_metadata(self.topics, files, custom_data)

    def _current_file_record(self) -> FileRecord:
        rec = self.files[-1]
        if self._file_count:
            return FileRecord(rec.path, self._file_min, self._file_max - self._file_min, self._file_count)
        return FileRecord(rec.path)

    def close(self, custom_data: dict | None = None) -> dict:
        """Finish the last file, write metadata.yaml, remove the progress file; returns the metadata."""
        self._close_file(custom_data)
        inner = build_metadata(self.topics, self.files, custom_data)
        write_metadata(self.dir, inner)
        (self.dir / PROGRESS_FILE).unlink(missing_ok=True)
        return inner
