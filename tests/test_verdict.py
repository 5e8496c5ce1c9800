"""The run verdict over the whole run (issue 20 item 4, issue 21 item 5), on synthetic summaries.

Each summary is what amb-rig builds from the nodes' final /diagnostics (values are strings, as on the wire).
Expected numbers are computed here independently (growth rate ln(rho)/T, loss fractions, clearance time).
"""

from __future__ import annotations

import argparse
import math

import pytest

from amb_bringup.verdict import EXIT_FAIL_ON, EXIT_FAILED, EXIT_OK, add_arguments, judge_verdict


def _args(*extra: str, mode: str = "lockstep", no_plant: bool = False) -> argparse.Namespace:
    p = argparse.ArgumentParser()
    add_arguments(p)
    ns = p.parse_args(list(extra))
    ns.mode, ns.no_plant = mode, no_plant
    return ns


def _summary(plant=None, ctl=None, mon=None, errors=(), gap=2.5e-3, peak=1e-4, rate=5000.0) -> dict:
    nodes = {}
    if plant is not None:
        nodes["plant"] = {"values": {"air gap (m)": str(gap), "steps": "25000", **plant}, "message": ""}
    if ctl is not None:
        nodes["controller"] = {"values": ctl, "message": ""}
    if mon is not None:
        nodes["monitor"] = {"values": mon, "message": mon.pop("_message", "")}
    return {"errors": list(errors), "nodes": nodes, "rate_hz": rate,
            "peak_displacement": {"v1": {"m": peak, "air_gap_ratio": peak / gap}}}  # fmt: skip


STABLE_MON = {"rho": "0.998800", "period (s)": "0.128228", "verdict": "stable", "unstable": "false"}


def test_stable_run_is_ok_and_says_rho():
    v = judge_verdict(_summary({}, {"samples lost": "0"}, dict(STABLE_MON)), _args())
    assert v.exit_code == EXIT_OK and v.result == "stable"
    assert v.line.startswith("verdict: stable: rho = 0.9988")
    assert f"{1e-4 / 2.5e-3:.3g} x air gap" in v.line


def test_unstable_is_a_result_with_growth_rate_and_time_to_clearance():
    rho, period, peak, gap = 1.051, 0.128228, 5e-4, 2.5e-3
    mon = {"rho": f"{rho:.6f}", "period (s)": f"{period}", "verdict": "unstable", "unstable": "true"}
    v = judge_verdict(_summary({}, {}, mon, peak=peak, gap=gap), _args())
    sigma = math.log(rho) / period  # 0.388 1/s
    assert v.exit_code == EXIT_OK and v.result == "unstable"
    assert f"growth rate {sigma:.3g} 1/s" in v.line
    assert f"~{math.log(gap / peak) / sigma:.3g} s" in v.line  # e-folding count to the gap over the growth rate
    assert judge_verdict(_summary({}, {}, dict(mon), peak=peak), _args("--fail-on", "unstable")).exit_code == 3


def test_realtime_command_losses_above_one_percent_fail_the_run():
    plant = {"late commands held (samples)": "200", "zero current (samples)": "100"}  # 300 of 25000 = 1.2 %
    v = judge_verdict(_summary(plant, {}, dict(STABLE_MON)), _args(mode="realtime"))
    assert v.exit_code == EXIT_FAILED
    assert "300 of 25000 steps (1.20 % > 1 %)" in v.line
    assert any(f"{100 / 5000.0:.3g} s at zero current" in f for f in v.failures)
    # under the limits (a looser loss fraction and zero-current allowance) the same data is a result again
    loose = _args("--max-command-loss", "0.02", "--max-zero-current", "0.05", mode="realtime")
    assert judge_verdict(_summary(plant, {}, dict(STABLE_MON)), loose).exit_code == EXIT_OK


def test_any_loss_in_lockstep_fails_and_monitor_loss_is_a_warning():
    v = judge_verdict(_summary({}, {"samples lost": "3"}, dict(STABLE_MON)), _args())
    assert v.exit_code == EXIT_FAILED and "lost 3 displacement samples in lockstep" in v.line
    mon = dict(STABLE_MON, **{"samples lost": "7"})
    v = judge_verdict(_summary({}, {"samples lost": "0"}, mon), _args())
    assert v.exit_code == EXIT_OK and "[WARN: the monitor lost 7 samples]" in v.line
    # an estimate on gapped data is no verdict: withheld, with what it said (issue 16)
    assert v.result == "unknown" and "stability withheld: the monitor lost 7 samples" in v.line
    assert "said stable, rho = 0.9988" in v.line


def test_gaps_that_are_ticks_the_plant_skipped_do_not_withhold_the_verdict():
    """A realtime plant that falls a tick behind skips it: the monitor's stamps then have a gap though it received
    every sample the plant published (seen: 13 gaps, 10155 of 10155 samples).  A real loss still withholds."""
    plant = {"published /amb/displacement": "10155", "skipped ticks": "13"}
    mon = dict(STABLE_MON, **{"samples lost": "13", "samples": "10155"})
    v = judge_verdict(_summary(plant, {}, mon), _args(mode="realtime"))
    assert v.result == "stable" and v.line.startswith("verdict: stable: rho = 0.9988"), v.line
    assert "13 gaps, ticks the plant skipped: it received all 10155 samples" in v.line
    mon["samples"] = "10154"  # one sample did not arrive
    v = judge_verdict(_summary(plant, {}, mon), _args(mode="realtime"))
    assert v.result == "unknown" and "stability withheld: the monitor lost 13 samples" in v.line


def test_node_failure_comes_first_and_no_plant_without_rig_fails():
    v = judge_verdict(_summary({}, {}, dict(STABLE_MON), errors=["controller exited unexpectedly (SIGKILL)"]), _args())
    assert v.exit_code == EXIT_FAILED and v.line == "verdict: FAILED: controller exited unexpectedly (SIGKILL)"
    v = judge_verdict(_summary(None, {"samples answered": "0"}, None), _args(no_plant=True))
    assert v.exit_code == EXIT_FAILED and "waited for /amb/displacement" in v.line


def test_nothing_moved_says_why_and_saturation_is_reported():
    v = judge_verdict(_summary({}, {}, {"verdict": "insufficient_excitation"}, peak=0.0), _args())
    assert v.result == "nothing-moved" and "every displacement stayed 0" in v.line and v.exit_code == EXIT_OK
    assert judge_verdict(_summary({}, {}, {}, peak=0.0), _args("--fail-on", "nothing-moved")).exit_code == 3
    v = judge_verdict(_summary({"saturated steps": "250"}, {}, dict(STABLE_MON)), _args())
    assert "SATURATED in 250 of 25000 steps" in v.line and v.exit_code == EXIT_OK
    assert judge_verdict(_summary({"saturated steps": "250"}, {}, dict(STABLE_MON)),
                         _args("--saturation-limit", "0.01")).line.count("SATURATED") == 0  # 1 % < limit  # fmt: skip
    assert judge_verdict(_summary({"saturated steps": "250"}, {}, dict(STABLE_MON)),
                         _args("--fail-on", "saturation")).exit_code == EXIT_FAIL_ON  # fmt: skip


def test_touchdown_is_a_result_and_duplicate_commands_a_failure():
    v = judge_verdict(_summary({"touchdown contacts": "2"}, {}, dict(STABLE_MON)), _args("--fail-on", "touchdown"))
    assert v.result == "touchdown" and v.exit_code == EXIT_FAIL_ON
    v = judge_verdict(_summary({"duplicate commands": "1"}, {}, dict(STABLE_MON)), _args())
    assert v.exit_code == EXIT_FAILED and "duplicate commands" in v.line


def test_unknown_fail_on_result_is_refused():
    with pytest.raises(SystemExit) as exc:
        _args("--fail-on", "unstable,wobbly")
    assert exc.value.code == 2


def test_tainted_ok_marks_instead_of_failing():
    summary = _summary({"duplicate commands": "3"}, {}, dict(STABLE_MON))
    assert judge_verdict(summary, _args()).exit_code == EXIT_FAILED
    v = judge_verdict(_summary({"duplicate commands": "3"}, {}, dict(STABLE_MON)), _args("--tainted-ok"))
    assert v.exit_code == EXIT_OK and v.line.startswith("verdict: stable")
    assert "[TAINTED: 3 duplicate commands for one step" in v.line


def test_held_commands_are_named_with_the_round_trip_against_the_deadline():
    """A realtime run whose plant held late commands (under the loss limit) says how late they came back: the
    round trip's percentiles against the deadline (delay_samples + 1) Ts; a run that held none says nothing."""
    plant = {
        "late commands held (samples)": "37",
        "zero current (samples)": "0",
        "command deadline (us)": "1000.0",
        "round trip p50 (us)": "444.1",
        "round trip p99 (us)": "880.4",
        "round trip max (us)": "23808.8",
    }
    v = judge_verdict(_summary(plant, {}, dict(STABLE_MON)), _args(mode="realtime"))
    assert v.exit_code == EXIT_OK and v.result == "stable"  # 37 of 25000 steps: under the 1 % limit
    assert "37 late commands held: round trip p50/p99/max 444/880/23809 us against a deadline of 1000 us" in v.line
    plant["late commands held (samples)"] = "0"
    assert "late commands" not in judge_verdict(_summary(plant, {}, dict(STABLE_MON)), _args(mode="realtime")).line
