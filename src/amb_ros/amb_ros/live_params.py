"""Parameters that may change while a node runs (gains, excitation, safe-gain switch, monitor margin).

A real AMB controller is retuned while it levitates; so are these nodes, in two ways:

* ``ros2 param set /amb_controller proportional_gain 2.0e6`` (any parameter client): the on-set-parameters
  callback validates the value (range, choices, type, the node's own cross-checks); a bad value is rejected with a
  reason and the node keeps the old one.  An accepted value is held *pending* and applied by the loop at the next
  sample it processes, never in the middle of one: the sample (k, t_k) it took effect at is stamped in /diagnostics.
* the ``param_at`` parameter (``amb-rig run --param-at T NODE:NAME=VALUE``): a schedule of changes, each applied
  at the first sample t_k >= T by the node itself, so that a lockstep run with a schedule is as deterministic as
  one without (the same sample every time, whatever the wall clock did); in realtime, whose stamps are system
  times, T counts from the first sample the node processed.

Every applied change is published at once as an extra /diagnostics report (keys ``parameter changes``,
``last parameter change``, ``parameter change <n>``) and, through rclpy, on /parameter_events; the recorder
records both topics, so the bag holds every change with its sample.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from rcl_interfaces.msg import SetParametersResult
from rclpy.parameter import Parameter

from .params import ParamError, ParamSpec

PARAM_AT = "param_at"


def param_at_spec() -> ParamSpec:
    return ParamSpec(PARAM_AT, Parameter.Type.STRING_ARRAY,
                     "scheduled changes 'T NAME=VALUE': NAME takes VALUE at the first sample t_k >= T (s)")  # fmt: skip


def check_value(spec: ParamSpec, value: Any, current: Any) -> str:
    """Reason why ``value`` cannot replace ``current`` for ``spec`` ('' = acceptable)."""
    if isinstance(current, bool) != isinstance(value, bool):
        return f"'{spec.name}' must be {type(current).__name__}, got {value!r}"
    if isinstance(current, float) and isinstance(value, int | float):
        if not math.isfinite(float(value)):
            return f"'{spec.name}' = {value} is not finite"
        if (spec.lo is not None and value < spec.lo) or (spec.hi is not None and value > spec.hi):
            lo = "-inf" if spec.lo is None else f"{spec.lo:g}"
            hi = "inf" if spec.hi is None else f"{spec.hi:g}"
            return f"'{spec.name}' = {value} is out of range [{lo}, {hi}]" + (f" {spec.unit}" if spec.unit else "")
    elif type(value) is not type(current):
        return f"'{spec.name}' must be {type(current).__name__}, got {value!r}"
    if spec.choices and value not in spec.choices:
        return f"'{spec.name}' = {value!r} is not one of {', '.join(spec.choices)}"
    return ""


def parse_schedule(items: list[str], runtime: dict[str, ParamSpec], current: dict[str, Any]):
    """``['T NAME=VALUE', ...]`` -> sorted [(T_ns, name, value)]; raises ParamError naming the bad item."""
    import yaml

    out = []
    for item in items:
        t_text, _, assignment = item.strip().partition(" ")
        name, sep, raw = assignment.strip().partition("=")
        try:
            t_s = float(t_text)
        except ValueError:
            t_s = math.nan
        if not sep or not math.isfinite(t_s) or t_s < 0:
            raise ParamError(f"parameter '{PARAM_AT}': {item!r} is not 'T NAME=VALUE' with T >= 0 s")
        if name not in runtime:
            raise ParamError(f"parameter '{PARAM_AT}': '{name}' cannot change at run time "
                             f"(these can: {', '.join(sorted(runtime))})")  # fmt: skip
        value = coerce(yaml.safe_load(raw), current[name])
        reason = check_value(runtime[name], value, current[name])
        if reason:
            raise ParamError(f"parameter '{PARAM_AT}': {reason}")
        out.append((round(t_s * 1e9), name, value))
    return sorted(out, key=lambda e: e[0])


def coerce(value: Any, current: Any) -> Any:
    """An integer given for a float parameter is that float (as ``-p gain:=1000`` is accepted at start-up)."""
    if isinstance(current, float) and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    return value


@dataclass
class Change:
    name: str
    old: Any
    new: Any
    k: int
    t_ns: int
    source: str  # "param_at" or "set" (a parameter client)

    def text(self) -> str:
        return (
            f"{self.name}: {self.old!r} -> {self.new!r} at k = {self.k} (t = {self.t_ns * 1e-9:.9g} s, {self.source})"
        )


class LiveParams:
    """Runtime parameters of one node.

    Parameters
    ----------
    node : RigNode, with its parameters declared (``node.p``) and ``Ts_ns`` set
    runtime : the specs that may change while the node runs (declared writable)
    apply : called by the loop with {name: new value} at the sample the changes take effect; ``node.p`` already
        holds the new values when it is called
    check : optional cross-check of a whole proposed parameter set {name: value} -> reason ('' = fine)
    """

    def __init__(self, node, runtime: list[ParamSpec], apply: Callable[[dict], None], check=None):
        self.node, self.apply, self.check = node, apply, check
        self.runtime = {s.name: s for s in runtime}
        self.schedule = parse_schedule(list(node.p.get(PARAM_AT) or []), self.runtime, node.p)
        self.pending: dict[str, Any] = {}
        self._source = "set"
        self.changes: list[Change] = []
        self.rejected = 0
        self.last_rejection = ""
        # lockstep stamps are t_k = k Ts from 0; realtime stamps are system times: T counts from the first sample
        self.origin_ns: int | None = 0 if getattr(node, "mode", "lockstep") == "lockstep" else None
        node.add_on_set_parameters_callback(self._on_set)

    def _on_set(self, params: list[Parameter]) -> SetParametersResult:
        proposed = dict(self.node.p, **{n: v for n, (v, _) in self.pending.items()})
        for prm in params:
            spec = self.runtime.get(prm.name)
            if spec is None:
                return self._reject(f"'{prm.name}' cannot change at run time")
            value = prm.value
            reason = check_value(spec, value, proposed[prm.name])
            if reason:
                return self._reject(reason)
            proposed[prm.name] = value
        if self.check is not None and (reason := self.check(proposed)):
            return self._reject(reason)
        for prm in params:
            self.pending[prm.name] = (prm.value, self._source)
        return SetParametersResult(successful=True)

    def _reject(self, reason: str) -> SetParametersResult:
        self.rejected += 1
        self.last_rejection = reason
        self.node.get_logger().warning(f"parameter change rejected: {reason}")
        return SetParametersResult(successful=False, reason=reason)

    def at_sample(self, t_ns: int) -> None:
        """Call before computing sample t_ns: applies due scheduled and pending changes (cheap when none)."""
        if self.origin_ns is None:
            self.origin_ns = t_ns
        rel_ns = t_ns - self.origin_ns
        while self.schedule and self.schedule[0][0] <= rel_ns:
            _, name, value = self.schedule.pop(0)
            self._source = PARAM_AT
            try:
                result = self.node.set_parameters([Parameter(name, value=value)])[0]
            finally:
                self._source = "set"
            if not result.successful:  # e.g. a cross-check with values changed since start-up
                self.node.get_logger().warning(f"{PARAM_AT}: {name}={value!r} at t = {t_ns * 1e-9:g} s rejected")
        if not self.pending:
            return
        k = rel_ns // self.node.Ts_ns  # realtime: samples since the first one this node processed
        applied = {}
        for name, (value, source) in self.pending.items():
            self.changes.append(Change(name, self.node.p[name], value, k, t_ns, source))
            self.node.p[name] = value
            applied[name] = value
        self.pending = {}
        self.apply(applied)
        self.node.get_logger().info("parameter change " + "; ".join(c.text() for c in self.changes[-len(applied) :]))
        self.node.diag.publish(*self.node.status(), self.node.values())  # stamped now, so the bag has it

    def values(self) -> dict[str, str]:
        """Diagnostics keys: every change with its sample, and the rejections."""
        out = {"parameter changes": str(len(self.changes)), "parameter changes rejected": str(self.rejected)}
        if self.changes:
            out["last parameter change"] = self.changes[-1].text()
            for i, c in enumerate(self.changes[-20:], start=max(1, len(self.changes) - 19)):
                out[f"parameter change {i}"] = c.text()
        if self.last_rejection:
            out["last parameter rejection"] = self.last_rejection
        return out
