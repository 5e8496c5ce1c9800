"""amb-rig's parameter options: ``--params-file``, ``--param-at``, ``--print-params``, and the check before start.

``--params-file FILE`` takes the standard ROS 2 layout::

    amb_controller:              # the ROS node name (or amb-rig's short name: controller); '/amb_controller' too
      ros__parameters:
        proportional_gain: 2.0e6
    /**:                         # every node that declares the key
      ros__parameters:
        diagnostics_period_s: 0.2

Its values are applied as ``--param`` items given before the command line's own (so ``--param`` wins), which
makes a params-file run equal to the same run with ``--param``.  ``--param-at T NODE:NAME=VALUE`` schedules a
runtime parameter change that the node applies at its first sample t_k >= T (amb_ros.live_params).  All of it,
with every other node parameter, is checked against the nodes' own declarations (amb_bringup.paramtable)
before any process starts.
"""

from __future__ import annotations

import math
from pathlib import Path

import yaml

from amb_dynamics.errors import InputError

from .paramtable import check_parameters, check_value, closest, table
from .processes import NODES, node_parameters

ROS_NAMES = {v[3]: k for k, v in NODES.items()}  # ROS node name -> amb-rig name
OWNED = {"mode": "--mode", "config_file": "--config", "set": "--set", "run_token": "--run-token"}  # amb-rig options


def add_arguments(r) -> None:
    r.add_argument(
        "--params-file",
        action="append",
        default=[],
        metavar="FILE",
        help="ROS 2 params file (node_name: ros__parameters: ...; '/**' for every node); --param wins",
    )
    r.add_argument(
        "--param-at",
        nargs=2,
        action="append",
        default=[],
        metavar=("T", "NODE:NAME=VALUE"),
        help="runtime parameter change applied by the node at its first sample t_k >= T (s)",
    )
    r.add_argument("--print-params", action="store_true",
                   help="print every node's effective parameters (ROS 2 params-file layout) and exit")  # fmt: skip


def _flow(value) -> str:
    """``value`` as the YAML text of a --param item (flow style, one line)."""
    return yaml.safe_dump([value], default_flow_style=True, width=10**9).strip()[1:-1]


def scalar(raw: str):
    """A --param value: YAML, except that '2e6' (a string to YAML 1.1) is the number it looks like."""
    value = yaml.safe_load(raw)
    if isinstance(value, str):
        try:
            return float(raw)
        except ValueError:
            pass
    return value


def _normalise(item: str) -> str:
    node, _, rest = item.partition(":")
    key, sep, raw = rest.partition("=")
    return f"{node}:{key}={_flow(scalar(raw))}" if sep and raw.strip() else item


def _node_name(key: str, path: str) -> str | None:
    """amb-rig name of a params-file section ('/**' -> None)."""
    bare = key.lstrip("/")
    if key in ("/**", "**"):
        return None
    if bare in ROS_NAMES:
        return ROS_NAMES[bare]
    if bare in NODES:
        return bare
    valid = [*ROS_NAMES, "/**"]
    raise InputError(f"{path}: no node '{key}'{closest(bare, valid)} (nodes: {', '.join(valid)})")


def params_file_items(path: str, specs: dict[str, dict]) -> list[str]:
    """The --param items (``NODE:NAME=VALUE``) equivalent to params file ``path``."""
    try:
        doc = yaml.safe_load(Path(path).read_text())
    except OSError as exc:
        raise InputError(f"--params-file {path}: {exc.strerror}") from None
    except yaml.YAMLError as exc:
        raise InputError(f"--params-file {path}: not YAML ({str(exc).splitlines()[0]})") from None
    if not isinstance(doc, dict):
        raise InputError(f"--params-file {path}: expected 'node_name: ros__parameters: {{...}}' sections")
    items = []
    for key, section in doc.items():
        node = _node_name(str(key), path)
        if not isinstance(section, dict) or set(section) != {"ros__parameters"}:
            raise InputError(f"{path}: section '{key}' must hold exactly 'ros__parameters'")
        params = section["ros__parameters"] or {}
        if not isinstance(params, dict):
            raise InputError(f"{path}: '{key}.ros__parameters' must be a mapping")
        for name, value in params.items():
            targets = [node] if node is not None else [n for n in NODES if name in specs[n]]
            if not targets:
                every = sorted({p for s in specs.values() for p in s})
                raise InputError(f"{path}: no node has a parameter '{name}'{closest(str(name), every)}")
            if isinstance(value, str):  # ROS 2 reads 2.0e4 as a number, YAML 1.1 (PyYAML) as a string
                value = scalar(value)
            items += [f"{n}:{name}={_flow(value)}" for n in targets]
    return items


def schedule_items(param_at: list[list[str]], specs: dict[str, dict]) -> list[str]:
    """--param-at pairs -> one ``NODE:param_at=[...]`` --param item per node."""
    per: dict[str, list[str]] = {}
    for t_text, item in param_at:
        node, _, rest = item.partition(":")
        name, sep, raw = rest.partition("=")
        try:
            t_s = float(t_text)
        except ValueError:
            t_s = math.nan
        if not (t_s >= 0 and math.isfinite(t_s)):
            raise InputError(f"--param-at {t_text} {item}: T must be a time >= 0 s")
        if node not in specs or not sep:
            raise InputError(
                f"--param-at {t_text} {item}: expected NODE:NAME=VALUE with NODE one of {', '.join(specs)}"
            )
        runtime = [k for k, s in specs[node].items() if s.runtime]
        if name not in runtime:
            hint = closest(name, runtime) or f" (runtime parameters of {node}: {', '.join(runtime) or 'none'})"
            raise InputError(f"--param-at: {node} cannot change '{name}' at run time{hint}")
        value = scalar(raw)
        check_value(node, specs[node][name], value)
        per.setdefault(node, []).append(f"{t_s!r} {name}={_flow(value)}")
    return [f"{node}:param_at={_flow(entries)}" for node, entries in per.items()]


def started_nodes(args) -> list[str]:
    return [n for n in NODES if not (n == "plant" and args.no_plant) and not (n == "monitor" and args.no_monitor)]


def prepare(args) -> tuple[dict, dict[str, dict]]:
    """Fold --params-file and --param-at into ``args.param``, check every started node's parameters; return
    (common, per-node) as amb-rig will write them.  Raises InputError (one line) for anything wrong."""
    specs = table()
    for item in args.param:
        key = item.partition(":")[2].partition("=")[0]
        if key in OWNED:
            raise InputError(f"--param {item}: '{key}' is set by amb-rig's {OWNED[key]} option")
    items = [i for path in args.params_file for i in params_file_items(path, specs)]
    for item in items:
        _node, _, rest = item.partition(":")
        if rest.partition("=")[0] in OWNED:
            key = rest.partition("=")[0]
            raise InputError(f"--params-file: '{key}' is set by amb-rig's {OWNED[key]} option")
    args.param = items + schedule_items(args.param_at, specs) + [_normalise(i) for i in args.param]
    try:
        common, per = node_parameters(args)
    except ValueError as exc:
        raise InputError(str(exc)) from None
    check_parameters(common, per, started_nodes(args), specs)
    if "base_motion" in started_nodes(args):
        check_recorded_motion({**common, **per.get("base_motion", {})})
    return common, per


def check_recorded_motion(given: dict) -> None:
    """A recorded base motion is read and checked here, before any process starts, as base_motion will read it
    (bounded, regular files only; a bad file is one line naming the file and line, exit 2)."""
    from amb_dynamics.config import load_config
    from amb_dynamics.errors import AmbError
    from amb_dynamics.recorded import load_recorded

    kind = given.get("kind")
    if not kind:
        try:
            kind = load_config(given.get("config_file") or None, list(given.get("set") or [])).base_motion.kind
        except AmbError:
            return  # a bad config is reported where amb-rig checks it, after the discovery check
    if kind != "recorded":
        return
    if not given.get("recorded_file"):
        raise InputError("base_motion: parameter 'recorded_file' is required for kind recorded")
    load_recorded(given["recorded_file"], given.get("recorded_smoothing") or None)


def effective(args, common: dict, per: dict[str, dict]) -> dict:
    """Every started node's parameters as it will run with them (given values, else declared or config defaults),
    in ROS 2 params-file layout keyed by the ROS node name."""
    from amb_dynamics.config import load_config
    from amb_ros.params import _config_value

    specs = table()
    out = {}
    for node in started_nodes(args):
        given = {**common, **per.get(node, {})}
        cfg = load_config(given.get("config_file") or None, list(given.get("set") or []))
        values = {}
        for name, spec in specs[node].items():
            if name in given:
                values[name] = given[name]
            elif spec.config_key is not None:
                v = _config_value(cfg, spec.config_key)
                values[name] = spec.none_value if v is None else v
            elif isinstance(spec.default, bool | int | float | str | list):
                values[name] = spec.default
        out[NODES[node][3]] = {"ros__parameters": values}
    return out


def print_params(args, common: dict, per: dict[str, dict]) -> None:
    print(yaml.safe_dump(effective(args, common, per), sort_keys=False), end="")
