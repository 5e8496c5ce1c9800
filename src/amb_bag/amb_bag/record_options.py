"""Options of ``amb-bag record`` / ``ros2 run amb_bag record``: the dataclass, its arguments, their checks."""

from __future__ import annotations

import argparse
import re
from dataclasses import dataclass, field
from pathlib import Path

from amb_ros.scheduling import PRIORITIES

from .errors import BagError
from .writer import DEFAULT_CHUNK_SIZE


@dataclass
class RecordOptions:
    """What to record and how (see ``amb-bag record --help``)."""

    output: Path
    topics: list[str] | None = None
    include_hidden: bool = False
    compression: str = "zstd"
    chunk_size: int = DEFAULT_CHUNK_SIZE
    split_size_mb: float | None = None
    split_duration_s: float | None = None
    discovery_interval_s: float = 0.1
    flush_interval_s: float = 1.0
    progress_interval_s: float = 0.25
    qos_depth: int | None = None
    duration_s: float | None = None
    batch_s: float = 0.05
    priority: str = "idle"
    debug_delay_s: float = 0.0  # test-only: sleep per message, to show that loss is reported
    exclude: list[str] = field(default_factory=list)
    diagnostics_collector: str = ""  # node name of the /diagnostics reader the final report must reach


def add_record_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``amb-bag record`` / ``ros2 run amb_bag record``."""
    parser.add_argument("-o", "--output", required=True, type=Path, help="bag folder to create (must not exist)")
    parser.add_argument("--topics", nargs="+", metavar="TOPIC", help="record only these topics (default: all)")
    parser.add_argument("--exclude", nargs="+", default=[], metavar="REGEX", help="skip topics matching these")
    parser.add_argument("--include-hidden", action="store_true", help="also record hidden topics (/_...)")
    parser.add_argument("--compression", choices=["zstd", "lz4", "none"], default="zstd", help="chunk compression")
    parser.add_argument("--chunk-size", type=int, default=DEFAULT_CHUNK_SIZE, metavar="BYTES",
                        help=f"uncompressed chunk size (default {DEFAULT_CHUNK_SIZE}); a crash loses one")  # fmt: skip
    parser.add_argument("--split-size", type=float, metavar="MB", help="start a new file after this many MB")
    parser.add_argument("--split-duration", type=float, metavar="S", help="start a new file every S seconds")
    parser.add_argument("--flush-interval", type=float, default=1.0, metavar="S",
                        help="finish the open chunk every S s (default 1): a crash loses at most that")  # fmt: skip
    parser.add_argument("--progress-interval", type=float, default=0.25, metavar="S",
                        help="write the progress file (counts for crash reports) every S s (default 0.25)")  # fmt: skip
    parser.add_argument("--discovery-interval", type=float, default=0.1, metavar="S",
                        help="graph scan period for new publishers (default 0.1 s)")  # fmt: skip
    parser.add_argument("--qos-depth", type=int, metavar="N",
                        help="KEEP_LAST N subscriptions instead of KEEP_ALL (may drop when behind)")  # fmt: skip
    parser.add_argument("--duration", type=float, metavar="S", help="stop after S seconds")
    parser.add_argument("--batch", type=float, default=50.0, metavar="MS",
                        help="pause after each drain so that one wake-up takes many messages (default 50 ms; "
                        "not after a drain of 1000 or more, when the recorder is behind)")  # fmt: skip
    parser.add_argument("--priority", choices=PRIORITIES, default="idle",
                        help="scheduling of every recorder thread, DDS's included: idle (SCHED_IDLE, default: only "
                        "CPU time the recorded loop leaves), low (niceness +5) or normal")  # fmt: skip
    parser.add_argument("--diagnostics-collector", default="", metavar="NODE",
                        help="node name of a /diagnostics reader (amb-rig's collector) that the final report, "
                        "an error's included, waits for (up to 4 s) before the recorder exits")  # fmt: skip
    parser.add_argument("--debug-delay-per-message", type=float, default=0.0, help=argparse.SUPPRESS)


def options_from_args(args: argparse.Namespace) -> RecordOptions:
    for name in ("chunk_size", "split_size", "split_duration", "flush_interval", "progress_interval",
                 "discovery_interval", "qos_depth", "duration"):  # fmt: skip
        value = getattr(args, name)
        if value is not None and not value > 0:
            raise BagError(f"--{name.replace('_', '-')} must be positive, got {value}")
    if not 0 <= args.batch <= 1000:
        raise BagError(f"--batch must be in 0..1000 ms, got {args.batch}")
    for pattern in args.exclude:
        try:
            re.compile(pattern)
        except re.error as exc:
            raise BagError(f"--exclude {pattern!r} is not a regular expression ({exc.msg})") from None
    for name in ("flush_interval", "progress_interval", "discovery_interval", "duration", "split_duration"):
        value = getattr(args, name)
        if value is not None and not value < 1e7:  # also NaN: `not nan > 0` above, `not nan < 1e7` here
            raise BagError(f"--{name.replace('_', '-')} must be below 1e7 s, got {value}")
    return RecordOptions(
        output=args.output, topics=args.topics, include_hidden=args.include_hidden, compression=args.compression,
        chunk_size=args.chunk_size, split_size_mb=args.split_size, split_duration_s=args.split_duration,
        discovery_interval_s=args.discovery_interval, flush_interval_s=args.flush_interval,
        progress_interval_s=args.progress_interval,
        qos_depth=args.qos_depth, duration_s=args.duration, debug_delay_s=args.debug_delay_per_message,
        exclude=args.exclude, batch_s=args.batch * 1e-3, priority=args.priority,
        diagnostics_collector=args.diagnostics_collector,
    )  # fmt: skip
