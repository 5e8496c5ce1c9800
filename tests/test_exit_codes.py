"""docs/exit-codes.md is the one exit-code table: its rows, the code's constants and each command agree.

The table is parsed from the document (so an edit of either side shows here); every command is run on one
good and one bad input in-process.  The signal row (128 + n) is shown by tests/test_rig_faults.py (SIGINT and
SIGTERM of amb-rig exit 130 and 143).
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from helpers import cli_bag as _bag
from helpers import cli_dyn as _dyn
from helpers import cli_monitor as _monitor
from helpers import cli_rig as _rig

REPO = Path(__file__).resolve().parents[1]
SAMPLE_BAG = REPO / "bags" / "sample_pitch"


def _table() -> dict[str, str]:
    rows = {}
    for line in (REPO / "docs" / "exit-codes.md").read_text().splitlines():
        m = re.match(r"\| (\d+|128 \+ n) \| ([^|]+) \|", line)
        if m:
            rows[m.group(1)] = m.group(2).strip()
    return rows


def test_the_table_has_exactly_the_codes_the_code_uses():
    from amb_bag import cli as bag_cli
    from amb_bringup import rig, verdict

    rows = _table()
    assert list(rows) == ["0", "1", "2", "3", "128 + n"]
    assert rows["0"].startswith("ran as asked") and rows["2"].startswith("bad input")
    assert (verdict.EXIT_OK, verdict.EXIT_FAILED, verdict.EXIT_USAGE, verdict.EXIT_FAIL_ON) == (0, 1, 2, 3)
    assert (rig.EXIT_FAILED, rig.EXIT_USAGE) == (1, 2)
    assert bag_cli.EXIT_BAD_INPUT == 2 and bag_cli.EXIT_DAMAGED == 2


def _exit(fn, argv) -> int:
    try:
        code = fn(argv)
    except SystemExit as exc:
        code = exc.code
    return 0 if code is None else code


@pytest.mark.parametrize(
    ("name", "fn", "good", "bad"),
    [
        ("amb-dynamics", _dyn, ["modes", "--speed-rpm", "0"], ["modes", "--speed-rpm", "inf"]),
        ("amb-bag info", _bag, ["info", str(SAMPLE_BAG)], ["info", str(REPO / "no_such_bag")]),
        ("amb-bag check", _bag, ["check", str(SAMPLE_BAG), "--dry-run"], ["check", str(REPO / "no_such_bag")]),
        ("amb-monitor analyze", _monitor, None, ["analyze", str(REPO / "no_such_bag")]),
        ("amb-rig", _rig, None, ["run", "--duration", "-1"]),
    ],
)
def test_each_command_exits_0_when_it_ran_and_2_on_bad_input(name, fn, good, bad, capsys, monkeypatch):
    monkeypatch.setattr("sys.argv", [name])
    if good is not None:
        assert _exit(fn, good) == 0, capsys.readouterr()
    capsys.readouterr()
    assert _exit(fn, bad) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
