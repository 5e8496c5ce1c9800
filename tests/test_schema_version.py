"""Every JSON document the command-line tools print or write carries "schema_version": 1 (CHANGELOG.md)."""

from __future__ import annotations

import json
import shutil
import subprocess

import pytest

SCHEMA_VERSION = 1


def run_json(cmd: list[str], timeout: float = 300.0) -> dict:
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    assert out.returncode == 0, out.stderr[-2000:]
    text = out.stdout
    return json.loads(text[text.index("{") : text.rindex("}") + 1])


@pytest.mark.parametrize(
    "args",
    [
        ["modes", "--speed-rpm", "0"],
        ["floquet", "--motion", "pitch", "--amplitude", "0.3", "--frequency", "24.5"],
        ["simulate", "--motion", "pitch", "--amplitude", "0.3", "--frequency", "24.5", "--duration", "0.3"],
    ],
    ids=lambda a: a[0],
)
def test_amb_dynamics(venv_bin, tmp_path, args):
    doc = run_json(
        [
            str(venv_bin / "amb-dynamics"),
            *args,
            "--json",
            *(["--out", str(tmp_path / "r.png")] if args[0] == "simulate" else []),
        ]
    )
    assert doc["schema_version"] == SCHEMA_VERSION


def test_amb_dynamics_chart_stdout_and_file(venv_bin, tmp_path):
    out = tmp_path / "chart.json"
    cmd = [str(venv_bin / "amb-dynamics"), "chart", "--motion", "pitch", "--amplitude", "0.1:0.3:2",
           "--frequency", "20:25:2", "--workers", "1", "--out", str(tmp_path / "c.png"), "--json-out", str(out),
           "--json"]  # fmt: skip
    assert run_json(cmd)["schema_version"] == SCHEMA_VERSION
    doc = json.loads(out.read_text())
    assert doc["schema_version"] == SCHEMA_VERSION and len(doc["max_abs_multiplier"]) == 2


def test_amb_bag_info_and_check(venv_bin, repo, tmp_path):
    bag = tmp_path / "bag"
    shutil.copytree(repo / "bags" / "sample_pitch", bag)
    assert run_json([str(venv_bin / "amb-bag"), "info", str(bag), "--json"])["schema_version"] == SCHEMA_VERSION
    doc = run_json([str(venv_bin / "amb-bag"), "check", str(bag), "--dry-run", "--json"])
    assert doc["schema_version"] == SCHEMA_VERSION and doc["status"] == "ok"


def test_amb_monitor_analyze(venv_bin, repo):
    doc = run_json([str(venv_bin / "amb-monitor"), "analyze", str(repo / "bags" / "sample_pitch"), "--json"])
    assert doc["schema_version"] == SCHEMA_VERSION


@pytest.mark.ros
def test_amb_rig_run(venv_bin, tmp_path):
    cmd = [str(venv_bin / "amb-rig"), "run", "--json", "--duration", "0.05", "--no-monitor",
           "--log-dir", str(tmp_path / "logs")]  # fmt: skip
    doc = run_json(cmd, timeout=180.0)
    assert doc["schema_version"] == SCHEMA_VERSION and doc["ok"] is True
