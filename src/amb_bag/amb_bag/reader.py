"""Open a bag (rosbag2-layout folder or a single ``.mcap`` file), check it, list its topics, read messages.

Everything a damaged, truncated, empty or foreign file can raise while being read (mcap errors, CRC errors,
``struct.error``, decompression errors, bad UTF-8, ...) becomes one :class:`BagFormatError` naming the file, so
the CLI prints one line.  Messages come back raw (CDR bytes) in log-time order, split files one after another.
"""

from __future__ import annotations

import contextlib
import struct
from dataclasses import dataclass, field
from pathlib import Path

from mcap.exceptions import McapError
from mcap.reader import SeekingReader
from mcap.stream_reader import CRCValidationError

from amb_ros.bagfiles import check_mcap_magic as _check_magic

from .errors import BagError, BagFormatError
from .metadata import METADATA_FILE, load_metadata
from .qos import profiles_from_yaml
from .writer import PROFILE

try:  # decompression errors of the optional codecs
    from zstandard import ZstdError
except ImportError:  # pragma: no cover - zstandard comes with mcap's zstd support
    ZstdError = McapError
READ_ERRORS = (
    McapError,
    CRCValidationError,
    struct.error,
    EOFError,
    UnicodeDecodeError,
    ValueError,
    KeyError,
    IndexError,
    ZstdError,
    RuntimeError,
)  # fmt: skip  (lz4 raises RuntimeError on corrupt frames)


@contextlib.contextmanager
def damaged_is_format_error(path: Path, hint: str = "; `amb-bag check` recovers its complete chunks"):
    """Turn any read error on ``path`` into one BagFormatError line."""
    try:
        yield
    except BagError:
        raise
    except READ_ERRORS as exc:
        detail = str(exc).splitlines()[0][:120] if str(exc) else type(exc).__name__
        raise BagFormatError(f"{path} is truncated or damaged ({detail}){hint}") from None


def check_mcap_magic(path: Path) -> None:
    """Reject unreadable, empty and non-MCAP files with a clear line before any parser sees them."""
    try:
        _check_magic(path, BagFormatError)
    except BagFormatError as exc:
        if str(exc).startswith("cannot read"):
            raise BagError(str(exc)) from None
        raise


@dataclass
class TopicSummary:
    """A topic as stored in the MCAP files (channel metadata) with its message count over all files."""

    name: str
    type: str
    message_count: int = 0
    offered_qos_profiles: list[dict] = field(default_factory=list)
    type_description_hash: str = ""
    serialization_format: str = "cdr"


def bag_files(path) -> tuple[Path, list[Path], dict | None]:
    """(bag folder, its MCAP files, metadata or None) for a bag folder or a single .mcap file."""
    path = Path(path)
    if not path.exists():
        raise BagError(f"{path} does not exist")
    if path.is_file():
        if path.name == METADATA_FILE:
            return bag_files(path.parent)
        return path.parent, [path], None
    if not (path / METADATA_FILE).exists():
        if any(path.glob("*.mcap")):
            raise BagFormatError(f"{path} has no {METADATA_FILE}: the recording did not finish; run `amb-bag check`")
        raise BagFormatError(f"{path} is not a bag folder (no {METADATA_FILE}, no .mcap file)")
    meta = load_metadata(path)
    files = [path / Path(p).name for p in meta["relative_file_paths"]]
    if missing := [f.name for f in files if not f.is_file()]:
        raise BagFormatError(f"{path}: files listed in {METADATA_FILE} are missing: {', '.join(missing)}")
    return path, files, meta


class Bag:
    """A readable, checked bag.  Opening reads every file's summary; ``messages()`` streams the data."""

    def __init__(self, path):
        self.dir, self.files, self.metadata = bag_files(path)
        self.size_bytes = sum(f.stat().st_size for f in self.files)
        self.topics: dict[str, TopicSummary] = {}
        self.start_ns, self.end_ns, self.message_count = None, None, 0
        self.compression: set[str] = set()
        for f in self.files:
            self._summarise(f)
        if self.metadata is not None and self.metadata["message_count"] != self.message_count:
            raise BagFormatError(
                f"{self.dir}: {METADATA_FILE} says {self.metadata['message_count']} messages but the files hold "
                f"{self.message_count}; run `amb-bag check`"
            )

    def _summarise(self, path: Path) -> None:
        check_mcap_magic(path)
        with damaged_is_format_error(path), open(path, "rb") as f:
            reader = SeekingReader(f)
            header = reader.get_header()
            if header.profile != PROFILE:
                raise BagFormatError(f"{path} is an MCAP file but not a ROS 2 bag (profile {header.profile!r})")
            summary = reader.get_summary()
            if summary is None or summary.statistics is None:
                raise BagFormatError(f"{path} has no summary section (not finished); run `amb-bag check`")
        stats = summary.statistics
        for channel_id, channel in summary.channels.items():
            schema = summary.schemas.get(channel.schema_id)
            if schema is None:
                raise BagFormatError(f"{path}: channel {channel.topic} has no schema")
            topic = self.topics.get(channel.topic)
            if topic is None:
                with damaged_is_format_error(path, ""):
                    profiles = profiles_from_yaml(channel.metadata.get("offered_qos_profiles", ""))
                topic = self.topics[channel.topic] = TopicSummary(
                    channel.topic, schema.name, 0, profiles, channel.metadata.get("topic_type_hash", ""),
                    channel.message_encoding,
                )  # fmt: skip
            topic.message_count += stats.channel_message_counts.get(channel_id, 0)
        self.compression.update(c.compression or "none" for c in summary.chunk_indexes)
        if stats.message_count:
            start, end = stats.message_start_time, stats.message_end_time
            self.start_ns = start if self.start_ns is None else min(self.start_ns, start)
            self.end_ns = end if self.end_ns is None else max(self.end_ns, end)
        self.message_count += stats.message_count

    def select(self, topics: list[str] | None) -> list[str]:
        """The recorded topics among ``topics`` (all if None); unknown names are an error."""
        if not topics:
            return sorted(self.topics)
        wanted = [t if t.startswith("/") else "/" + t for t in topics]
        if unknown := [t for t in wanted if t not in self.topics]:
            raise BagError(f"topics not in the bag: {', '.join(unknown)}")
        return wanted

    def messages(self, topics: list[str] | None = None):
        """Yield ``(topic, type, log_time_ns, publish_time_ns, data)`` in log-time order."""
        wanted = set(self.select(topics))
        for path in self.files:
            with damaged_is_format_error(path), open(path, "rb") as f:
                reader = SeekingReader(f, validate_crcs=True)
                for schema, channel, message in reader.iter_messages(topics=list(wanted), log_time_order=True):
                    yield channel.topic, schema.name, message.log_time, message.publish_time, message.data
