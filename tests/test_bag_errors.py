"""Bad input to every ``amb-bag`` command: one line, non-zero exit, no traceback; crashed files are recovered."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent / "bagtools"))
import mix

from amb_bag import cli

COMMANDS = {
    "info": lambda p, tmp: ["info", str(p)],
    "play": lambda p, tmp: ["play", str(p)],
    "plot": lambda p, tmp: ["plot", str(p), "--out", str(tmp / "out.png")],
    "check": lambda p, tmp: ["check", str(p)],
}


def _bag(tmp_path: Path, name: str = "good", steps: int = 40) -> Path:
    bag = tmp_path / name
    mix.write_bag(bag, steps, chunk_size=2048)
    return bag


def _make(case: str, tmp_path: Path) -> Path:
    """A bad input of the given kind, alone in its own folder."""
    root = tmp_path / case
    root.mkdir()
    if case == "missing":
        return root / "no_such_bag"
    if case == "empty_file":
        (root / "x_0.mcap").write_bytes(b"")
        return root / "x_0.mcap"
    if case == "empty_folder":
        return root
    if case == "foreign_file":
        (root / "notes.mcap").write_text("this is not a bag\n")
        return root / "notes.mcap"
    if case == "foreign_in_bag":  # metadata.yaml fine, the storage file is a PNG
        bag = _bag(root)
        (bag / "good_0.mcap").write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(100))
        return bag
    if case == "not_ros2_mcap":
        from mcap.writer import Writer

        with open(root / "json.mcap", "wb") as f:
            w = Writer(f)
            w.start(profile="", library="test")
            sid = w.register_schema("x", "jsonschema", b"{}")
            cid = w.register_channel("/x", "json", sid)
            w.add_message(cid, 1, b"{}", 1)
            w.finish()
        return root / "json.mcap"
    if case == "truncated_bag":
        bag = _bag(root)
        data = (bag / "good_0.mcap").read_bytes()
        (bag / "good_0.mcap").write_bytes(data[: len(data) * 6 // 10])
        return bag
    if case == "truncated_metadata":
        bag = _bag(root)
        text = (bag / "metadata.yaml").read_text()
        (bag / "metadata.yaml").write_text(text[: len(text) // 3])
        return bag
    raise KeyError(case)


CASES = ["missing", "empty_file", "empty_folder", "foreign_file", "foreign_in_bag", "not_ros2_mcap",
         "truncated_bag", "truncated_metadata"]  # fmt: skip
REPAIRABLE = {("check", "truncated_bag"), ("check", "truncated_metadata")}


def _run(args, capsys):
    """(exit code, captured output); a refusal (exit 2) returns its one stderr line instead of the code."""
    with pytest.raises(SystemExit) as exc:
        cli.main(args)
    out = capsys.readouterr()
    if exc.value.code == cli.EXIT_BAD_INPUT and out.err:
        assert out.err.count("\n") == 1, out.err  # exactly one line
        return out.err.rstrip("\n"), out
    return exc.value.code, out


@pytest.mark.parametrize(
    ("command", "case"), [(c, k) for c in COMMANDS for k in CASES if (c, k) not in REPAIRABLE]
)  # check repairs truncated input instead: test_check_repairs_truncated_inputs
def test_bad_input_gives_one_line_and_nonzero_exit(command, case, tmp_path, capsys):
    path = _make(case, tmp_path)
    code, _ = _run(COMMANDS[command](path, tmp_path), capsys)
    assert isinstance(code, str), f"exit code {code!r} for {command} on {case}"
    assert code.startswith(f"amb-bag {command}: ") and "\n" not in code
    assert not (tmp_path / "out.png").exists()


@pytest.mark.parametrize("case", ["truncated_bag", "truncated_metadata"])
def test_check_repairs_truncated_inputs(case, tmp_path, capsys):
    from rosbags.rosbag2 import Reader

    path = _make(case, tmp_path)
    before = {p.name: p.read_bytes() for p in path.iterdir()}
    code, out = _run(["check", str(path), "--dry-run"], capsys)
    assert code == cli.EXIT_DAMAGED and "damaged" in out.out
    assert {p.name: p.read_bytes() for p in path.iterdir()} == before  # --dry-run changes nothing
    code, out = _run(["check", str(path)], capsys)
    assert code == cli.EXIT_DAMAGED and "recovered" in out.out
    with Reader(path) as r:
        n, count = sum(1 for _ in r.messages()), r.message_count
    assert n == count > 0
    if case == "truncated_metadata":
        assert n == sum(len(mix.step_messages(k)) for k in range(40))  # nothing lost: only the metadata was rebuilt
    code, out = _run(["check", str(path)], capsys)
    assert code == 0 and "intact" in out.out
    code, out = _run(["info", str(path)], capsys)
    assert code == 0 and f"Messages:          {n}" in out.out


def test_cli_process_prints_one_line_without_traceback(tmp_path):
    path = _make("foreign_file", tmp_path)
    amb_bag = Path(sys.executable).parent / "amb-bag"
    proc = subprocess.run([str(amb_bag), "info", str(path)], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2  # bad input (docs/exit-codes.md)
    assert proc.stderr.strip() == f"amb-bag info: {path} is not an MCAP file"
    assert "Traceback" not in proc.stderr and proc.stdout == ""


@pytest.mark.parametrize(
    ("flag", "value", "needle"),
    [("--batch", "-1", "--batch must be in 0..1000 ms, got -1.0"), ("--flush-interval", "0", "must be positive")],
)
def test_record_refuses_bad_options_before_creating_anything(flag, value, needle, tmp_path, capsys):
    code, _ = _run(["record", "-o", str(tmp_path / "bag"), flag, value], capsys)
    assert isinstance(code, str) and code.startswith("amb-bag record: ") and needle in code
    assert not (tmp_path / "bag").exists()
