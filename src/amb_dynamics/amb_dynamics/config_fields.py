"""The one field helper of every config dataclass: unit, range, choices and a one-line doc in the metadata."""

from __future__ import annotations

import dataclasses
from dataclasses import field
from typing import Any


def spec(
    unit: str = "",
    lo: float | None = None,
    hi: float | None = None,
    *,
    open_lo: bool = False,
    choices: tuple | None = None,
    default: Any = dataclasses.MISSING,
    doc: str = "",
):
    """A dataclass field with unit, range and choices for validation."""
    meta = {"unit": unit, "lo": lo, "hi": hi, "open_lo": open_lo, "choices": choices, "doc": doc}
    if default is dataclasses.MISSING:
        return field(metadata=meta)
    if isinstance(default, list | dict):
        return field(default_factory=lambda: default, metadata=meta)
    return field(default=default, metadata=meta)
