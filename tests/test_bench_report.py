"""benchmarks/report.py: figures keep every run, the page shows median and range, machine, date and commit."""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "benchmarks"))

import report  # noqa: E402  (benchmarks/ is not a package)


@pytest.fixture(autouse=True)
def clean():
    report.reset()
    yield
    report.reset()


def test_figures_page(tmp_path):
    report.set_source("bench_x")
    report.record("chart time", [3.0, 1.0, 2.5, 10.0], "s", goal="< 10 s")
    fig = report.record_ratio("a vs b", [10.0, 30.0, 20.0], [2.0, 3.0, 4.0], goal=">= 4x")
    assert fig.values == [5.0, 10.0, 5.0] and fig.unit == "x"
    page = report.write_page(tmp_path / "perf.md", ["bench_x"], ["bench_y"])
    text = page.read_text()
    row = next(line for line in text.splitlines() if line.startswith("| chart time"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert cells[1] == f"{statistics.median([3.0, 1.0, 2.5, 10.0]):g}"  # 2.75
    assert cells[2] == "1 - 10 (4)" and cells[3] == "s" and cells[4] == "< 10 s"
    assert cells[5] == "`.venv/bin/python benchmarks/run_all.py bench_x`"
    ratio = next(line for line in text.splitlines() if line.startswith("| a vs b"))
    assert "| 5 | 5 - 10 (3) | x |" in ratio
    head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=REPO, capture_output=True, text=True).stdout.strip()
    assert f"commit: `{head}" in text
    assert "not run: bench_y" in text
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    assert f", {cores} cores," in text
    assert not (tmp_path / "perf.md.part").exists()


def test_bad_figures_are_refused():
    with pytest.raises(ValueError, match="no values"):
        report.record("empty", [], "s")
    with pytest.raises(ValueError, match="2 numerators for 1"):
        report.record_ratio("r", [1.0, 2.0], [1.0])


def test_run_all_rejects_an_unknown_module():
    out = subprocess.run(
        [
            sys.executable,
            str(
                REPO / "benchmarks" / "run_all.py",
            ),
            "bench_nothing",
        ],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert out.returncode == 2
    assert "unknown benchmark 'bench_nothing'" in out.stderr and "Traceback" not in out.stderr


def test_a_bar_in_a_name_does_not_break_the_table(tmp_path):
    report.record("max |a - b|", [1e-9], "")
    text = report.write_page(tmp_path / "p.md").read_text()
    row = next(line for line in text.splitlines() if line.startswith("| max"))
    assert len(row.replace("\\|", "").strip("|").split("|")) == 6
