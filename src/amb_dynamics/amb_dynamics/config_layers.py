"""A rotor file built on another one: ``base: OTHER.yaml`` plus the keys that differ.

A variant of a rig (another controller, another rate, a heavier disk) should not copy the hundred lines of the
rig it varies: it names its base (a path relative to its own folder, or absolute) and lists what changes.  The
base is read first (it may have a base of its own), then the file's keys are laid over it: a mapping merges key
by key, anything else (a number, a list such as ``controller.filters``) replaces the base's value.  Validation
(unknown keys, ranges) runs once, on the merged result, as for any other file.
"""

from __future__ import annotations

from pathlib import Path

from .errors import ConfigError
from .yamlread import load_yaml, read_text_bounded

BASE_KEY = "base"
MAX_DEPTH = 8  # a chain of bases this long is a mistake, not a design


def read_layered(path: Path) -> dict:
    """The mapping of the rotor file at ``path`` with its chain of bases resolved and merged."""
    return _read(path, ())


def _read(path: Path, chain: tuple[Path, ...]) -> dict:
    data = load_yaml(read_text_bounded(path, what="config"), str(path))
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: top level must be a mapping of keys")
    if BASE_KEY not in data:
        return data
    ref = data.pop(BASE_KEY)
    if not isinstance(ref, str) or not ref.strip():
        raise ConfigError(f"{path}: '{BASE_KEY}' must name a rotor file (a path relative to this file's folder)")
    base = (path.parent / ref).resolve()
    here = path.resolve()
    if base in (*chain, here):
        raise ConfigError(f"{path}: '{BASE_KEY}: {ref}' leads back to {base} (a file cannot be its own base)")
    if len(chain) >= MAX_DEPTH:
        raise ConfigError(f"{path}: more than {MAX_DEPTH} bases in a chain")
    return merge(_read(base, (*chain, here)), data)


def merge(base: dict, over: dict) -> dict:
    """``over`` laid on ``base``: mappings merged recursively, any other value replaced (new dicts, inputs kept)."""
    out = dict(base)
    for key, value in over.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = merge(out[key], value)
        else:
            out[key] = value
    return out
