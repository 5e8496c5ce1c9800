"""A short lockstep run with a bag, end to end: exact loss table, a verdict line, exit 0, no temp folder left.

Before: the controller's final ``published /amb/current`` was one report stale (its report read the counter
before updating it), so every bag's loss table showed an ``extra`` for /amb/current; and every run left a
/tmp/amb-rig-* folder behind.
"""

from __future__ import annotations

import os

import pytest

from amb_bag.loss import CUSTOM_KEY
from amb_bag.metadata import custom_json, load_metadata
from helpers import rig_json
from procs import spawn

pytestmark = pytest.mark.ros


def test_lockstep_bag_loss_table_is_exact_and_the_verdict_is_stable(tmp_path, venv_bin):
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    bag = tmp_path / "bag"
    cmd = [str(venv_bin / "amb-rig"), "run", "--json", "--duration", "0.5", "--motion", "pitch", "--amplitude",
           "0.3", "--frequency", "24.5", "--initial-displacement", "1e-4", "--bag", str(bag)]  # fmt: skip
    with spawn(cmd, tmp_path / "rig.log", env={**os.environ, "TMPDIR": str(tmp)}) as proc:
        code = proc.wait(180)
        text = proc.text()
    assert code == 0, text[-3000:]
    s = rig_json(text)
    samples = int(0.5 * s["rate_hz"]) + 1  # t_0 .. t_N: the plant publishes N + 1 samples for N steps
    assert s["verdict"]["exit_code"] == 0 and s["verdict"]["failures"] == []
    assert s["verdict"]["line"].startswith("verdict: ") and s["verdict"]["result"] != "nothing-moved"
    ctl = s["nodes"]["controller"]["values"]
    assert int(ctl["published /amb/current"]) == int(ctl["samples answered"]) == samples  # the final count is fresh
    rows = custom_json(load_metadata(bag), CUSTOM_KEY)
    for topic in ("/amb/current", "/amb/displacement"):
        assert rows[topic]["published"] == rows[topic]["received"] == samples, rows[topic]
        assert rows[topic]["lost"] == 0 and rows[topic]["extra"] == 0
    assert not [p for p in tmp.glob("amb-rig-*") if p.is_dir()]  # a clean run removed its log folder
