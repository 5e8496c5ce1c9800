"""Read the monitor's topics from a rosbag2-layout MCAP bag (``<bag>/metadata.yaml`` + ``<bag>/<name>_0.mcap``)
or a single ``.mcap`` file, with one clear line for every way a bag can be unusable.

Only the ``mcap`` library is used (the node packages do not import each other); messages come back raw (CDR),
in log-time order, and are decoded by the same decoders as the live node.
"""

from __future__ import annotations

import struct
from pathlib import Path

import yaml
from mcap.exceptions import McapError
from mcap.reader import SeekingReader

from amb_dynamics.errors import AmbError
from amb_ros.bagfiles import check_mcap_magic

METADATA_FILE = "metadata.yaml"
READ_ERRORS = (McapError, struct.error, EOFError, UnicodeDecodeError, ValueError, KeyError, IndexError, RuntimeError)
try:  # zstd-compressed chunks raise their own error type when damaged
    from zstandard import ZstdError

    READ_ERRORS = (*READ_ERRORS, ZstdError)
except ImportError:  # pragma: no cover
    pass
RECOVER_HINT = "; `amb-bag check` recovers its complete chunks"


class BagReadError(AmbError):
    """The bag is missing, empty, foreign, truncated or lacks a topic the analysis needs."""


def bag_files(path: Path) -> list[Path]:
    """The MCAP files of a bag folder (from its metadata.yaml) or a single .mcap file."""
    if not path.exists():
        raise BagReadError(f"{path} does not exist")
    if path.is_file():
        return [path]
    meta_path = path / METADATA_FILE
    if not meta_path.is_file():
        if any(path.glob("*.mcap")):
            raise BagReadError(f"{path} has no {METADATA_FILE}: the recording did not finish{RECOVER_HINT}")
        raise BagReadError(f"{path} is not a bag folder (no {METADATA_FILE}, no .mcap file)")
    try:
        info = yaml.safe_load(meta_path.read_text())["rosbag2_bagfile_information"]
        names = [Path(p).name for p in info["relative_file_paths"]]
    except (yaml.YAMLError, TypeError, KeyError, UnicodeDecodeError) as exc:
        raise BagReadError(f"{meta_path} is not rosbag2 metadata ({type(exc).__name__})") from None
    files = [path / n for n in names]
    missing = [f.name for f in files if not f.is_file()]
    if missing or not files:
        raise BagReadError(
            f"{path}: files listed in {METADATA_FILE} are missing: {', '.join(missing) or 'none listed'}"
        )
    return files


def _check_magic(path: Path) -> None:
    check_mcap_magic(path, BagReadError)


def bag_topics(files: list[Path]) -> dict[str, str]:
    """topic -> message type over all files (reads the summaries; a truncated file fails here)."""
    topics: dict[str, str] = {}
    for path in files:
        _check_magic(path)
        try:
            with open(path, "rb") as f:
                summary = SeekingReader(f).get_summary()
        except READ_ERRORS as exc:
            raise BagReadError(f"{path} is truncated or damaged ({_first_line(exc)}){RECOVER_HINT}") from None
        if summary is None:
            raise BagReadError(f"{path} has no summary section (recording not finished){RECOVER_HINT}")
        for channel in summary.channels.values():
            schema = summary.schemas.get(channel.schema_id)
            topics[channel.topic] = schema.name if schema is not None else ""
    return topics


def read_messages(files: list[Path], topics: list[str]):
    """Yield ``(topic, log_time_ns, cdr_bytes)`` of ``topics`` in log-time order, file after file."""
    for path in files:
        try:
            with open(path, "rb") as f:
                reader = SeekingReader(f, validate_crcs=True)
                for _schema, channel, message in reader.iter_messages(topics=topics, log_time_order=True):
                    yield channel.topic, message.log_time, message.data
        except READ_ERRORS as exc:
            raise BagReadError(f"{path} is truncated or damaged ({_first_line(exc)}){RECOVER_HINT}") from None


def _first_line(exc: Exception) -> str:
    text = str(exc).splitlines()[0][:120] if str(exc) else ""
    return text or type(exc).__name__
