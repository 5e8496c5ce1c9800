"""What every reader of the project's bags checks first (amb_bag and the stability monitor's offline analysis)."""

from __future__ import annotations

import os
from pathlib import Path

MCAP_MAGIC = b"\x89MCAP0\r\n"
# magic, the smallest header record (opcode, length, two empty strings) and footer record, magic
MIN_MCAP_BYTES = 2 * len(MCAP_MAGIC) + (1 + 8 + 4 + 4) + (1 + 8 + 8 + 8 + 4)


def check_mcap_magic(path: Path, error: type[Exception]) -> None:
    """Reject unreadable, empty and non-MCAP files with one clear line (``error``) before any parser sees them."""
    try:
        with open(path, "rb") as f:
            head = f.read(len(MCAP_MAGIC))
            size = os.fstat(f.fileno()).st_size
    except OSError as exc:
        raise error(f"cannot read {path}: {exc.strerror}") from None
    if not head:
        raise error(f"{path} is empty")
    if head != MCAP_MAGIC:
        raise error(f"{path} is not an MCAP file")
    if size < MIN_MCAP_BYTES:
        raise error(f"{path} is truncated: {size} bytes, less than any MCAP file ({MIN_MCAP_BYTES})")
