"""What every reader of the project's bags checks first (amb_bag and the stability monitor's offline analysis)."""

from __future__ import annotations

from pathlib import Path

MCAP_MAGIC = b"\x89MCAP0\r\n"


def check_mcap_magic(path: Path, error: type[Exception]) -> None:
    """Reject unreadable, empty and non-MCAP files with one clear line (``error``) before any parser sees them."""
    try:
        with open(path, "rb") as f:
            head = f.read(len(MCAP_MAGIC))
    except OSError as exc:
        raise error(f"cannot read {path}: {exc.strerror}") from None
    if not head:
        raise error(f"{path} is empty")
    if head != MCAP_MAGIC:
        raise error(f"{path} is not an MCAP file")
