"""Strict, bounded reading of YAML input files: regular files only, size-checked, UTF-8, no duplicate keys.

PyYAML's ``safe_load`` silently keeps the last of two equal keys in a mapping; a rotor file with
``rate_hz`` twice would run with whichever came last.  :class:`UniqueKeyLoader` refuses that.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

import yaml

from .errors import ConfigError

MAX_YAML_BYTES = 1 << 20  # a rotor or params file is a few kB; a MiB leaves ample room


class DuplicateKeyError(yaml.constructor.ConstructorError):
    """A mapping repeats a key (its line is in ``problem_mark``)."""


class UniqueKeyLoader(getattr(yaml, "CSafeLoader", yaml.SafeLoader)):
    """``yaml.SafeLoader`` (libyaml's parser when PyYAML has it: a generated controller's matrices load ~4x faster)
    that raises :class:`DuplicateKeyError` on a repeated mapping key."""

    def construct_mapping(self, node, deep=False):
        seen: set = set()
        for key_node, _value in node.value:
            key = self.construct_object(key_node, deep=deep)
            try:
                duplicate = key in seen
            except TypeError:  # unhashable key: the base class reports it
                break
            if duplicate:
                raise DuplicateKeyError(None, None, f"duplicate key '{key}'", key_node.start_mark)
            seen.add(key)
        return super().construct_mapping(node, deep=deep)


def read_text_bounded(path: Path, limit: int = MAX_YAML_BYTES, what: str = "file", error=ConfigError) -> str:
    """The UTF-8 text of a regular file of at most ``limit`` bytes; anything else raises ``error`` (one line)."""
    try:
        with open(path, "rb") as f:
            st = os.fstat(f.fileno())
            if not stat.S_ISREG(st.st_mode):
                raise error(f"{path}: not a regular file (a {what} must be a file)")
            if st.st_size > limit:
                raise error(f"{path}: {st.st_size} bytes, larger than the {limit}-byte limit of a {what}")
            raw = f.read(limit + 1)
    except OSError as exc:
        raise error(f"{path}: cannot read {what} ({exc.strerror})") from None
    if len(raw) > limit:
        raise error(f"{path}: larger than the {limit}-byte limit of a {what}")
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw[: exc.start].count(b"\n") + 1
        raise error(f"{path}: line {line} is not UTF-8 text (byte {exc.start})") from None


def load_yaml(text: str, source: str, error=ConfigError):
    """Parse YAML with :class:`UniqueKeyLoader`; a syntax error or duplicate key names the source and line."""
    try:
        return yaml.load(text, Loader=UniqueKeyLoader)  # a SafeLoader subclass
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" line {mark.line + 1}" if mark else ""
        raise error(f"{source}:{where} is not valid YAML ({getattr(exc, 'problem', None) or 'syntax error'})") from None
