"""amb-rig's own arguments, checked before any process starts: one line naming the option, exit 2.

Node parameters are checked here only for their form (``NODE:NAME=VALUE``, a known node, a value that is
one line of valid YAML); whether a value suits the node is the node's own parameter validation.
"""

from __future__ import annotations

import math
import os
import re
from pathlib import Path

import yaml

from amb_dynamics.errors import AmbError

from .processes import NODES
from .verdict import check_limits

MAX_DURATION_S = 1e6
_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_.]*\Z")
_CONTROL = re.compile(r"[\x00-\x1f\x7f]")


class RigArgError(AmbError):
    """A bad amb-rig argument (the message names the option)."""


def _number(option: str, value, lo: float, hi: float, allow_lo: bool = True) -> None:
    if value is None:
        return
    if not math.isfinite(value) or value > hi or value < lo or (value == lo and not allow_lo):
        bound = f"{'>=' if allow_lo else '>'} {lo:g} and <= {hi:g}"
        raise RigArgError(f"{option} must be a finite number {bound} (got {value})")


def check_param(item: str) -> tuple[str, str, object]:
    """``NODE:NAME=VALUE`` -> (node, name, value parsed as YAML); anything else raises :class:`RigArgError`."""
    shown = _CONTROL.sub("?", item)[:80]
    node, _, rest = item.partition(":")
    key, sep, raw = rest.partition("=")
    if node not in NODES or not sep or not _NAME.match(key):
        raise RigArgError(f"--param {shown!r}: expected NODE:NAME=VALUE with NODE one of {', '.join(NODES)}")
    if _CONTROL.search(raw):
        raise RigArgError(f"--param {node}:{key}: the value contains a control character (newline, tab, ...)")
    try:
        value = yaml.safe_load(raw) if raw.strip() else ""
    except yaml.YAMLError:
        raise RigArgError(f"--param {node}:{key}: the value is not a number, boolean, string or list") from None
    if isinstance(value, dict):
        raise RigArgError(f"--param {node}:{key}: a mapping is not a parameter value")
    return node, key, value


def _check_bag(option: str, bag: str) -> None:
    path = Path(bag)
    if path.exists() or path.is_symlink():
        raise RigArgError(f"{option} {bag} already exists: give a new folder (a bag is never overwritten)")
    parent = path.resolve().parent
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir() or not os.access(parent, os.W_OK | os.X_OK):
        raise RigArgError(f"{option} {bag}: cannot create it in {parent} (not a writable folder)")


def check_rig_args(args) -> None:
    """Refuse bad ``amb-rig run`` arguments before anything starts (raises :class:`RigArgError`)."""
    _number("--duration", args.duration, 0.0, MAX_DURATION_S, allow_lo=bool(args.no_plant))
    _number("--amplitude", args.amplitude, -math.pi, math.pi)
    _number("--frequency", args.frequency, 0.0, 1e5, allow_lo=False)
    _number("--initial-displacement", args.initial_displacement, -1.0, 1.0)
    _number("--start-timeout", args.start_timeout, 0.0, 3600.0, allow_lo=False)
    _number("--timeout", args.timeout, 0.0, 1e7, allow_lo=False)
    _number("--lock-wait", args.lock_wait, 0.0, 3600.0)
    if args.rt_priority is not None and not 0 <= args.rt_priority <= 99:
        raise RigArgError(f"--rt-priority must be in 0..99 (got {args.rt_priority})")
    if args.bag:
        _check_bag("--bag", args.bag)
    if args.log_dir and Path(args.log_dir).exists() and not Path(args.log_dir).is_dir():
        raise RigArgError(f"--log-dir {args.log_dir} exists and is not a folder")
    for item in args.param:
        check_param(item)
    if complaint := check_limits(args):
        raise RigArgError(complaint)


def refuse(message: str):
    """Print one line on stderr and exit 2 (bad input or refusal)."""
    import sys

    print(message, file=sys.stderr)
    raise SystemExit(2)
