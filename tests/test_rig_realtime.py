"""Realtime (HIL) mode at 1 kHz for 5 s: the controller reports period jitter and missed deadlines, and they are sane.

A static base and a centred rotor keep the linear state at exactly zero, so the run is about timing only (the
seed rotor's digital loop has no margin for a late command: rho = 1.05 per sample with one sample of delay at
1 kHz, see docs/nodes.md).  Cross-checks: the number of control updates matches 5 s at 1 kHz and the plant's
count of commands received; percentiles are ordered; the jitter is well below a period at the median.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from helpers import run_rig

pytestmark = pytest.mark.ros

RATE_HZ = 1000.0
DURATION_S = 5.0

PAPER = Path(__file__).resolve().parents[1] / "config" / "seed_paper.yaml"


def test_realtime_1khz_reports_sane_jitter_and_deadlines(tmp_path, venv_bin):
    args = ["--mode", "realtime", "--duration", str(DURATION_S), "--motion", "none",
            "--set", f"controller.rate_hz={RATE_HZ:g}", "--set", "modal_cutoff=800",
            # the paper's loop: this test is about the wall-clock timers and their report; the command-loss and
            # zero-current limits of the verdict (tests/test_verdict.py) would judge this shared machine's load (one
            # 0.33 s stall of the controller process was seen in CI), not the code
            "--config", str(PAPER), "--max-command-loss", "1", "--max-zero-current", str(DURATION_S)]  # fmt: skip
    code, s, text = run_rig(tmp_path, venv_bin, args)
    assert code == 0, text[-2000:]
    ctl = s["nodes"]["controller"]["values"]
    plant = s["nodes"]["plant"]["values"]
    assert ctl["mode"] == "realtime" and ctl["rate (Hz)"] == "1000"
    ticks = int(ctl["ticks"])
    # about one update per millisecond over the run: amb-rig stops the nodes DURATION_S after the plant started
    # (timed from the plant's own report, which is at most one diagnostics period old: <= 0.5 s more, plus the
    # stop), even when the plant started seconds before the monitor first reported
    assert 0.8 * DURATION_S * RATE_HZ <= ticks <= 1.2 * DURATION_S * RATE_HZ
    # best-effort realtime topics: a few messages may drop, and the counts are taken at slightly different stops
    assert abs(int(plant["received /amb/current"]) - int(ctl["published /amb/current"])) <= 0.1 * ticks
    assert abs(int(ctl["received /amb/displacement"]) - int(plant["published /amb/displacement"])) <= 0.1 * ticks
    p50, p99, pmax = (float(ctl[f"period error {q} (us)"]) for q in ("p50", "p99", "max"))
    assert 0.0 <= p50 <= p99 <= pmax
    assert p50 < 250.0  # a quarter period
    missed, skipped = int(ctl["missed deadlines"]), int(ctl["skipped ticks"])
    # by construction: every sample missing from the stamp sequence (skipped) is a missed deadline, and each update
    # adds at most one more (its command later than a period); how many there are is this shared machine's load
    # (CI saw 347 and 538 in 5,000 ticks on busy days), so the test checks the accounting, not the machine
    assert 0 <= skipped <= missed <= skipped + ticks
    assert "sample-to-command latency p99 (us)" in ctl
    # the plant's own ticker reports too
    assert float(plant["period error p50 (us)"]) <= float(plant["period error p99 (us)"])
    assert s["nodes"]["controller"]["level"] in ("OK", "WARN")
