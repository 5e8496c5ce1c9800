"""The run's single verdict line and exit code, judged over the whole run (docs/exit-codes.md).

A *result* (stable, UNSTABLE, touchdown, saturation, nothing moved) is what the rotor did: exit 0, unless the
user named it in ``--fail-on`` (exit 3).  A *failure* is a run whose data cannot be trusted: a node died or
reported ERROR, any sample lost in lockstep, realtime command losses above ``--max-command-loss`` (a fraction of
the steps, default 1 %), time at zero current above ``--max-zero-current`` (default 0 s: the rotor was not
levitated), duplicate commands for one step (a second publisher whose command may have been applied), or
``--no-plant`` in lockstep with no rig answering: exit 1.

Inputs are the nodes' final /diagnostics values as collected in the summary (strings, as on the wire), read
through the typed schema of amb_ros.diag_keys; keys a node does not report are simply not judged.
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass, field

from amb_ros.diag_keys import Controller, Key, Monitor, Plant, per_topic

EXIT_OK, EXIT_FAILED, EXIT_USAGE, EXIT_FAIL_ON = 0, 1, 2, 3
FAIL_ON_CHOICES = ("unstable", "touchdown", "saturation", "nothing-moved")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``amb-rig run`` options of the verdict."""
    parser.add_argument("--fail-on", type=fail_on_list, default=frozenset(), metavar="RESULT[,RESULT]",
                        help=f"exit 3 when the run's result is one of {', '.join(FAIL_ON_CHOICES)}")  # fmt: skip
    parser.add_argument("--max-command-loss", type=float, default=0.01, metavar="FRACTION",
                        help="realtime: a run whose plant lacked a fresh command in more than this fraction of "
                        "its steps failed (default 0.01)")  # fmt: skip
    parser.add_argument("--max-zero-current", type=float, default=0.0, metavar="S",
                        help="a run with more than S s at zero current (commands lost) failed (default 0)")  # fmt: skip
    parser.add_argument("--tainted-ok", action="store_true",
                        help="a run where foreign commands reached the plant is TAINTED, not failed")  # fmt: skip
    parser.add_argument("--saturation-limit", type=float, default=0.0, metavar="FRACTION",
                        help="report saturation above this fraction of steps (default 0)")  # fmt: skip


def fail_on_list(text: str) -> frozenset[str]:
    items = frozenset(t.strip() for t in text.split(",") if t.strip())
    if bad := sorted(items - set(FAIL_ON_CHOICES)):
        raise argparse.ArgumentTypeError(f"unknown result {bad[0]!r} (choose from {', '.join(FAIL_ON_CHOICES)})")
    return items


def check_limits(args) -> str | None:
    """One-line complaint about a bad limit, or None."""
    if not 0 <= args.max_command_loss <= 1:
        return f"--max-command-loss must be a fraction in 0..1 (got {args.max_command_loss})"
    if not (math.isfinite(args.max_zero_current) and args.max_zero_current >= 0):
        return f"--max-zero-current must be a finite number of s >= 0 (got {args.max_zero_current})"
    if not 0 <= args.saturation_limit <= 1:
        return f"--saturation-limit must be a fraction in 0..1 (got {args.saturation_limit})"
    return None


@dataclass
class Verdict:
    line: str
    result: str  # stable | unstable | touchdown | nothing-moved | unknown (saturation is added to the line)
    failures: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    exit_code: int = EXIT_OK

    def to_dict(self) -> dict:
        return {"line": self.line, "result": self.result, "failures": self.failures, "warnings": self.warnings,
                "exit_code": self.exit_code}  # fmt: skip


def _f(values: dict, key: Key) -> float | None:
    """A numeric key's value, None if absent, malformed or not finite."""
    v = key.read(values)
    return v if isinstance(v, int | float) and math.isfinite(v) else None


def _values(summary: dict, node: str) -> dict:
    return summary.get("nodes", {}).get(node, {}).get("values", {}) or {}


def taint(summary: dict) -> list[str]:
    """Foreign commands that reached the plant (a failure, or with ``--tainted-ok`` a TAINTED mark)."""
    plant = _values(summary, "plant")
    out = []
    if duplicates := _f(plant, Plant.duplicate_commands):
        out.append(f"{duplicates:.0f} duplicate commands for one step reached the plant: a second publisher on "
                   "/amb/current, and which command was applied cannot be told")  # fmt: skip
    return out


def trust_failures(summary: dict, args) -> list[str]:
    """Reasons the run's data cannot be trusted (beyond the node errors amb-rig already found)."""
    plant, ctl = _values(summary, "plant"), _values(summary, "controller")
    out = [] if getattr(args, "tainted_ok", False) else taint(summary)
    lost = _f(ctl, Controller.samples_lost)
    if args.mode == "lockstep" and lost:
        out.append(f"the controller lost {lost:.0f} displacement samples in lockstep (any loss there is a failure)")
    steps = _f(plant, Plant.steps)
    rate = summary.get("rate_hz") or 0.0
    held, zeroed = _f(plant, Plant.late_commands_held), _f(plant, Plant.zero_current)
    if steps and held is not None and zeroed is not None:
        fraction = (held + zeroed) / steps
        if fraction > args.max_command_loss:
            out.append(f"the plant lacked a fresh command in {held + zeroed:.0f} of {steps:.0f} steps "
                       f"({100 * fraction:.2f} % > {100 * args.max_command_loss:g} %)")  # fmt: skip
    if zeroed and rate and zeroed / rate > args.max_zero_current:
        out.append(f"{zeroed / rate:.3g} s at zero current (rotor not levitated; limit {args.max_zero_current:g} s)")
    if args.no_plant and args.mode == "lockstep" and ctl and not _f(ctl, Controller.samples_answered):
        out.append("--no-plant: no rig answered; the controller waited for /amb/displacement and got no sample")
    return out


def _result(summary: dict, args) -> tuple[str, str, list[str]]:
    """(result, text, warnings) from the monitor, the plant and the controller."""
    plant, mon, ctl = _values(summary, "plant"), _values(summary, "monitor"), _values(summary, "controller")
    warnings = []
    lost = _f(mon, Monitor.samples_lost)
    received, published = _f(mon, Monitor.samples), _f(plant, per_topic("published", "/amb/displacement"))
    if lost and published and received == published:  # every sample came: the stamps' gaps are skipped ticks
        warnings.append(f"the monitor's stamps have {lost:.0f} gaps, ticks the plant skipped: it received all "
                        f"{received:.0f} samples the plant published")  # fmt: skip
        lost = 0
    elif lost:
        warnings.append(f"the monitor lost {lost:.0f} samples")
    if foreign_samples := _f(ctl, Controller.samples_out_of_window):
        warnings.append(
            f"the controller rejected {foreign_samples:.0f} samples stamped far ahead of the run (foreign?)"
        )
    for who, values, topic, what in (("plant", plant, "/amb/current", "commands"),
                                     ("controller", ctl, "/amb/displacement", "samples")):  # fmt: skip
        if n := _f(values, per_topic("foreign", topic)):  # well-formed, another run token: not applied (docs/topics.md)
            warnings.append(f"the {who} rejected {n:.0f} {what} with another run token (another run or an intruder "
                            "on this ROS_DOMAIN_ID)")  # fmt: skip
    if late := late_commands(plant):
        warnings.append(late)
    if Monitor.model_mismatch.read(mon) is True:
        model_rho = mon.get(Monitor.model_rho.text)
        warnings.append(f"the stability estimate disagrees with the config's model (model rho {model_rho}): "
                        "is the rig the config?")  # fmt: skip
    if foreign := summary.get("foreign_diagnostics"):
        names = ", ".join(f"{k} ({n})" for k, n in sorted(foreign.items()))
        warnings.append(f"ignored /diagnostics from processes outside this run: {names}")
    gap = _f(plant, Plant.air_gap)
    peaks = [p["m"] for p in (summary.get("peak_displacement") or {}).values() if p.get("m") is not None]
    peak = max(peaks) if peaks else None
    peak_text = f"; peak {peak:.3g} m = {peak / gap:.3g} x air gap" if peak is not None and gap else ""
    touchdowns = _f(plant, Plant.touchdown_contacts)  # the plant node's count of backup-bearing contacts
    if touchdowns:
        return "touchdown", f"TOUCHDOWN ({touchdowns:.0f} contact events){peak_text}", warnings
    rho, period = _f(mon, Monitor.rho), _f(mon, Monitor.period)
    if lost and Monitor.verdict.read(mon) in ("stable", "marginal", "unstable"):  # gapped data: no verdict from them
        said = "UNSTABLE" if Monitor.unstable.read(mon) is True else Monitor.verdict.read(mon)
        return "unknown", (f"stability withheld: the monitor lost {lost:.0f} samples (its estimate on gapped data "
                           f"said {said}, rho = {rho:.4f})") + peak_text, warnings  # fmt: skip
    said_unstable = Monitor.verdict.read(mon) == "unstable"
    if Monitor.unstable.read(mon) is True or (rho is not None and rho > 1.0 and said_unstable):
        text = "UNSTABLE"
        if rho is not None:
            text += f": rho = {rho:.4f}"
            if period:
                sigma = math.log(rho) / period
                text += f", growth rate {sigma:.3g} 1/s"
                if sigma > 0 and peak and gap and peak < gap:
                    text += f", clearance reached in ~{math.log(gap / peak) / sigma:.3g} s from the peak so far"
        return "unstable", text + peak_text, warnings
    if peak == 0.0 or (Monitor.verdict.read(mon) == "insufficient_excitation"):
        why = summary.get("nodes", {}).get("monitor", {}).get("message") or "no displacement"
        if peak == 0.0:
            why = "every displacement stayed 0 (base at rest and no --initial-displacement?)"
            return "nothing-moved", f"nothing moved: {why}", warnings
        # the rotor vibrates (unbalance, runout, noise, forced response) but no transient shows above the noise
        return "nothing-moved", f"no stability estimate: {why}" + peak_text, warnings
    if rho is not None:
        return "stable", f"stable: rho = {rho:.4f}" + peak_text, warnings
    if ctl or plant:
        return "unknown", "no stability estimate (monitor off or not enough periods)" + peak_text, warnings
    return "unknown", "no result", warnings


def late_commands(plant: dict) -> str | None:
    """Realtime: held commands, with the round trip that made them late against the loop's deadline (a command
    must be back (delay_samples + 1) periods after its sample); each held sample is a whole sample of extra delay,
    beyond the loop's delay margin (the summary's preflight line)."""
    held, deadline = _f(plant, Plant.late_commands_held), _f(plant, Plant.command_deadline)
    if not held or not deadline:
        return None
    rtt = [_f(plant, k) for k in (Plant.round_trip_p50, Plant.round_trip_p99, Plant.round_trip_max)]
    if None in rtt:
        return f"{held:.0f} late commands held"
    return (f"{held:.0f} late commands held: round trip p50/p99/max {rtt[0]:.0f}/{rtt[1]:.0f}/{rtt[2]:.0f} us "
            f"against a deadline of {deadline:.0f} us after the sample")  # fmt: skip


def _saturation(summary: dict, args) -> str | None:
    plant = _values(summary, "plant")
    steps, saturated = _f(plant, Plant.steps), _f(plant, Plant.saturated_steps)
    if steps and saturated and saturated / steps > args.saturation_limit:
        return f"; current SATURATED in {saturated:.0f} of {steps:.0f} steps"
    return None


def judge_verdict(summary: dict, args) -> Verdict:
    """The verdict of a finished run; ``summary["errors"]`` holds amb-rig's own findings (node failures)."""
    failures = list(summary.get("errors", [])) + trust_failures(summary, args)
    result, text, warnings = _result(summary, args)
    results = {result}
    if saturation := _saturation(summary, args):
        text += saturation
        results.add("saturation")
    if failures:
        line = f"verdict: FAILED: {failures[0]}" + (f" (+{len(failures) - 1} more)" if len(failures) > 1 else "")
        code = EXIT_FAILED
    else:
        line = f"verdict: {text}"
        code = EXIT_FAIL_ON if results & set(args.fail_on) else EXIT_OK
    if warnings:
        line += "  [WARN: " + "; ".join(warnings) + "]"
    if getattr(args, "tainted_ok", False) and (tainted := taint(summary)):
        line += "  [TAINTED: " + "; ".join(tainted) + "]"
        warnings = warnings + tainted
    return Verdict(line, result, failures, warnings, code)
