"""The /diagnostics schema (amb_ros.diag_keys): typed reads, and the contract between writers and readers.

Every key the schema lists as always written is in its node's final report of a real lockstep and a realtime
run, and amb-rig's verdict and summary name no key by a string of their own (they read through the schema, so a
key renamed in a node cannot silently turn a check off, as ``foreign commands applied`` once did: the verdict
read it, and no node wrote it).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from amb_ros.diag_keys import BOTH, Controller, Key, Monitor, Plant, keys_of, per_topic, topics_with
from helpers import rig_json

ROOT = Path(__file__).resolve().parents[1]
SCHEMAS = {"plant": Plant, "controller": Controller, "monitor": Monitor}


def test_typed_reads():
    values = {"steps": "5000", "unstable": "true", "rho": "1.0234", "verdict": "stable", "air gap (m)": "x"}
    assert Plant.steps.read(values) == 5000 and isinstance(Plant.steps.read(values), int)
    assert Monitor.unstable.read(values) is True and Monitor.unstable.read({"unstable": "maybe"}) is None
    assert Monitor.rho.read(values) == pytest.approx(1.0234, abs=0)
    assert Monitor.verdict.read(values) == "stable"
    assert Plant.air_gap.read(values) is None  # malformed: not a number
    assert Controller.samples_lost.read(values) is None  # absent
    assert Key("n", int).read({"n": "2.5"}) == 2.5  # not an integer: the number as it is, never truncated
    counts = {"foreign publishers /amb/current": "1", "publishers seen /amb/current": "/x, /y"}
    assert topics_with(counts, "foreign publishers") == ["/amb/current"]
    assert per_topic("foreign publishers", "/amb/current").read(counts) == 1
    assert per_topic("publishers seen", "/amb/current").read(counts) == "/x, /y"


VALUES = {"plant", "ctl", "mon", "v", "values"}  # the names these modules give a node's report values


def _keys_read(path: Path) -> set[str]:
    """String constants used to read a node's report values: ``values["k"]``, ``values.get("k")``,
    ``_f(x, "k")``/``_num(x, "k")`` (the summary's own dict, ``s["steps"]``, is not a report)."""
    out = set()
    for n in ast.walk(ast.parse(path.read_text())):
        if isinstance(n, ast.Subscript) and isinstance(n.value, ast.Name) and n.value.id in VALUES:
            args = [n.slice]
        elif (isinstance(n, ast.Call) and isinstance(n.func, ast.Attribute) and n.func.attr == "get"
              and isinstance(n.func.value, ast.Name) and n.func.value.id in VALUES):  # fmt: skip
            args = n.args[:1]
        elif isinstance(n, ast.Call) and isinstance(n.func, ast.Name) and n.func.id in ("_f", "_num"):
            args = n.args[1:2]
        else:
            continue
        out |= {a.value for a in args if isinstance(a, ast.Constant) and isinstance(a.value, str)}
    return out


@pytest.mark.parametrize("module", ["verdict.py", "summary.py", "domain.py"])
def test_readers_name_no_key_of_their_own(module):
    texts = {k.text for schema in SCHEMAS.values() for k in keys_of(schema)}
    own = _keys_read(ROOT / "src" / "amb_bringup" / "amb_bringup" / module) & texts
    assert not own, f"{module} names {sorted(own)} by string: read them through amb_ros.diag_keys"


@pytest.mark.ros
@pytest.mark.parametrize("mode", ["lockstep", "realtime"])
def test_every_always_written_key_is_in_the_final_reports(tmp_path, venv_bin, mode):
    import subprocess

    cmd = [str(venv_bin / "amb-rig"), "run", "--json", "--mode", mode, "--duration", "1.0",
           "--log-dir", str(tmp_path / "logs")]  # fmt: skip
    if mode == "realtime":
        cmd += ["--set", "controller.rate_hz=1000", "--set", "modal_cutoff=800"]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    s = rig_json(proc.stdout)
    for node, schema in SCHEMAS.items():
        report = s["nodes"][node]
        assert report["final"], (node, report["message"])
        required = [k.text for k in keys_of(schema) if mode in k.always]
        assert required and all(mode in BOTH for _ in required)
        missing = [t for t in required if t not in report["values"]]
        assert not missing, f"{node} ({mode}) did not write {missing}"
