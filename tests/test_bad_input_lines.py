"""Every bad input of issue 20 item 7: one line on stderr naming what is wrong, exit status 2, nothing written.

Each case runs the command's own ``main`` in-process (a traceback would surface here as the exception itself)
and checks the exit status, that stderr is exactly one line, that it names the option or file, and that no
output file (or half-written bag) was left behind.  Before this change each of these printed a traceback, ran
for minutes, or was accepted.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from amb_dynamics.recorded import MAX_TRAJECTORY_BYTES
from helpers import cli_bag as _bag
from helpers import cli_dyn as _dyn
from helpers import cli_monitor as _monitor
from helpers import cli_rig as _rig

SAMPLE_BAG = Path(__file__).resolve().parents[1] / "bags" / "sample_pitch"
PITCH = ["--motion", "pitch", "--amplitude", "0.3", "--frequency", "24.5"]


def _eight_byte_bag(tmp: Path) -> Path:
    bag = tmp / "eight"
    bag.mkdir()
    (bag / "metadata.yaml").write_bytes((SAMPLE_BAG / "metadata.yaml").read_bytes())
    (bag / "sample_pitch_0.mcap").write_bytes((SAMPLE_BAG / "sample_pitch_0.mcap").read_bytes()[:8])
    return bag


def _undecodable_bag(tmp: Path) -> Path:
    """A ros2-profile MCAP whose one /amb/displacement message is not a JointState."""
    from mcap.writer import Writer

    from amb_bag import msgdefs

    path = tmp / "garbage.mcap"
    with open(path, "wb") as f:
        w = Writer(f)
        w.start(profile="ros2", library="test")
        text = msgdefs.full_text("sensor_msgs/msg/JointState").encode()
        sid = w.register_schema("sensor_msgs/msg/JointState", "ros2msg", text)
        cid = w.register_channel("/amb/displacement", "cdr", sid)
        w.add_message(cid, 1, b"\x00\x01\x00\x00\xff\xff\xff\x7f", 1)
        w.finish()
    return path


# (id, runner, argv builder (tmp -> argv), words the line must contain)
CASES = [
    (
        "config-not-utf8",
        _dyn,
        lambda t: ["modes", "--config", str(_file(t, "bad.yaml", b"a: \xff\xfe\n"))],
        ["bad.yaml", "line 1", "UTF-8"],
    ),
    (
        "config-duplicate-key",
        _dyn,
        lambda t: ["modes", "--config", str(_file(t, "dup.yaml", b"spin_speed_rpm: 1\nspin_speed_rpm: 2\n"))],
        ["dup.yaml", "line 2", "duplicate key 'spin_speed_rpm'"],
    ),
    ("config-is-dev-zero", _dyn, lambda t: ["modes", "--config", "/dev/zero"], ["/dev/zero", "not a regular file"]),
    (
        "set-blamed-on-override",
        _dyn,
        lambda t: ["modes", "--set", "controller.rate_hz=-5"],
        ["--set controller.rate_hz=-5", "rate_hz"],
    ),
    ("modes-nan-speed", _dyn, lambda t: ["modes", "--speed-rpm", "nan"], ["--speed-rpm", "finite"]),
    ("modes-extreme-speed", _dyn, lambda t: ["modes", "--speed-rpm", "1e300"], ["--speed-rpm", "<="]),
    (
        "floquet-extreme-amplitude",
        _dyn,
        lambda t: ["floquet", "--motion", "pitch", "--amplitude", "1e300", "--frequency", "24.5"],
        ["--amplitude"],
    ),
    (
        "floquet-inf-frequency",
        _dyn,
        lambda t: ["floquet", "--motion", "pitch", "--amplitude", "0.3", "--frequency", "inf"],
        ["--frequency"],
    ),
    (
        "floquet-1mhz",
        _dyn,
        lambda t: ["floquet", "--motion", "pitch", "--amplitude", "0.3", "--frequency", "6.283e6"],
        ["--frequency", "<= 100000"],
    ),
    (
        "floquet-sampled-1mhz",
        _dyn,
        lambda t: [
            "floquet",
            "--motion",
            "pitch",
            "--amplitude",
            "0.3",
            "--frequency",
            "6.2e4",
            "--controller",
            "sampled",
        ],
        ["two controller samples"],
    ),
    (
        "floquet-sampled-slow-base",  # T/Ts = 31,416: three exact products of that length exceed the work bound
        _dyn,
        lambda t: [
            "floquet",
            "--motion",
            "pitch",
            "--amplitude",
            "0.3",
            "--frequency",
            "0.5",
            "--controller",
            "sampled",
        ],
        ["controller samples", "at most"],
    ),
    (
        "chart-nan-amplitude",
        _dyn,
        lambda t: [
            "chart",
            "--motion",
            "pitch",
            "--amplitude",
            "nan",
            "--frequency",
            "1:40:3",
            "--out",
            str(t / "c.png"),
        ],
        ["--amplitude", "finite"],
    ),
    (
        "chart-extreme-amplitude",
        _dyn,
        lambda t: [
            "chart",
            "--motion",
            "pitch",
            "--amplitude",
            "0:1e300:3",
            "--frequency",
            "1:40:3",
            "--out",
            str(t / "c.png"),
        ],
        ["--amplitude"],
    ),
    (
        "chart-100k-squared",
        _dyn,
        lambda t: [
            "chart",
            "--motion",
            "pitch",
            "--amplitude",
            "0:0.5:100000",
            "--frequency",
            "1:40:100000",
            "--out",
            str(t / "c.png"),
        ],
        ["100000 x 100000", "refused"],
    ),
    ("simulate-nan-duration", _dyn, lambda t: ["simulate", *PITCH, "--duration", "nan"], ["--duration", "finite"]),
    ("simulate-huge-duration", _dyn, lambda t: ["simulate", *PITCH, "--duration", "1e300"], ["--duration"]),
    ("campbell-out-dir", _dyn, lambda t: ["campbell", "--out", str(t)], ["--out", "is a folder"]),
    ("check-8-byte-mcap", _bag, lambda t: ["check", str(_eight_byte_bag(t))], ["sample_pitch_0.mcap", "truncated"]),
    (
        "analyze-8-byte-mcap",
        _monitor,
        lambda t: ["analyze", str(_eight_byte_bag(t))],
        ["sample_pitch_0.mcap", "truncated"],
    ),
    (
        "plot-undecodable-message",
        _bag,
        lambda t: ["plot", str(_undecodable_bag(t)), "--out", str(t / "p.png")],
        ["/amb/displacement", "cannot be decoded"],
    ),
    ("play-rate-1e-300", _bag, lambda t: ["play", str(SAMPLE_BAG), "--rate", "1e-300"], ["--rate"]),
    ("play-delay-negative", _bag, lambda t: ["play", str(SAMPLE_BAG), "--delay", "-1"], ["--delay"]),
    ("play-delay-nan", _bag, lambda t: ["play", str(SAMPLE_BAG), "--delay", "nan"], ["--delay"]),
    (
        "record-exclude-bad-regex",
        _bag,
        lambda t: ["record", "-o", str(t / "r"), "--exclude", "["],
        ["--exclude '['", "regular expression"],
    ),
    (
        "rig-param-newline",
        _rig,
        lambda t: ["run", "--param", "controller:proportional_gain=1\n2"],
        ["--param controller:proportional_gain", "control character"],
    ),
    ("rig-param-bad-yaml", _rig, lambda t: ["run", "--param", "controller:proportional_gain=["], ["--param"]),
    ("rig-duration-nan", _rig, lambda t: ["run", "--duration", "nan"], ["--duration"]),
    ("rig-lock-wait-negative", _rig, lambda t: ["run", "--lock-wait", "-1"], ["--lock-wait", ">= 0"]),
    ("rig-bag-exists", _rig, lambda t: ["run", "--bag", str(t)], ["--bag", "already exists"]),
    (
        "rig-config-not-utf8",
        _rig,
        lambda t: ["run", "--config", str(_file(t, "bad.yaml", b"a: \xff\xfe\n"))],
        ["bad.yaml", "line 1", "UTF-8"],
    ),
    (
        "rig-recorded-dev-zero",  # before: read without end (24 GB in 50 s), then the OOM killer
        _rig,
        lambda t: ["run", "--param", "base_motion:kind=recorded", "--param", "base_motion:recorded_file=/dev/zero"],
        ["/dev/zero", "not a regular file"],
    ),
    (
        "rig-recorded-oversized",  # refused by its size, before a byte is read
        _rig,
        lambda t: [
            "run",
            "--param",
            "base_motion:kind=recorded",
            "--param",
            f"base_motion:recorded_file={_sparse(t, 'huge.csv', MAX_TRAJECTORY_BYTES + 1)}",
        ],
        ["huge.csv", f"larger than the {MAX_TRAJECTORY_BYTES}-byte limit"],
    ),
    (
        "rig-recorded-secret-line",  # the line is named by number; its content (a password hash) never echoed
        _rig,
        lambda t: [
            "run",
            "--param",
            "base_motion:kind=recorded",
            "--param",
            f"base_motion:recorded_file={_file(t, 'shadow', SECRET)}",
        ],
        ["shadow", "line 2"],
    ),
]

SECRET = b"t,roll\nroot:$6$Zq3v9Xk1$hVt0ecretHash:19000:0:99999:7:::\n"


def _sparse(tmp: Path, name: str, size: int) -> Path:
    path = tmp / name
    with open(path, "wb") as f:
        f.truncate(size)
    return path


def _file(tmp: Path, name: str, data: bytes) -> Path:
    path = tmp / name
    path.write_bytes(data)
    return path


@pytest.mark.parametrize(("runner", "make", "words"), [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_bad_input_is_one_line_and_exit_2(runner, make, words, tmp_path, capsys, monkeypatch):
    work = tmp_path / "in"
    work.mkdir()
    argv = make(work)
    before = sorted(p.name for p in work.iterdir())  # inputs the builder wrote
    monkeypatch.setattr(sys, "argv", ["prog", *argv])
    try:
        code = runner(argv)
    except SystemExit as exc:
        code = exc.code
    err = capsys.readouterr().err
    assert code == 2, (code, err)
    assert err.endswith("\n") and err.count("\n") == 1, err
    assert "Traceback" not in err and "root:" not in err and "ecretHash" not in err  # no file content echoed
    for word in words:
        assert word in err, (word, err)
    assert sorted(p.name for p in work.iterdir()) == before  # nothing written (no bag, no PNG, no JSON)


def test_floquet_json_is_finite_even_when_a_number_is_not(monkeypatch, capsys):
    """``finite_json`` turns NaN/inf into null and lists where; ``json.loads`` of the output never sees NaN."""
    from amb_dynamics.guards import finite_json

    clean, where = finite_json({"a": float("nan"), "b": [1.0, float("inf"), {"c": -float("inf")}], "d": 2})
    assert clean == {"a": None, "b": [1.0, None, {"c": None}], "d": 2}
    assert where == ["a", "b.1", "b.2.c"]
    text = json.dumps(clean, allow_nan=False)  # raises on any non-finite float left
    assert json.loads(text)["d"] == 2


def test_set_error_of_a_valid_file_names_the_override_not_the_file(tmp_path):
    """The file alone is valid; the second override breaks it: the message names that override."""
    from amb_dynamics.config import load_config
    from amb_dynamics.errors import ConfigError

    with pytest.raises(ConfigError) as exc:
        load_config(None, ["controller.rate_hz=6000", "shaft.elements=0"])
    text = str(exc.value)
    assert text.startswith("--set shaft.elements=0 (on ") and "elements" in text
    assert "rate_hz" not in text


def test_floquet_at_1_hz_writes_strict_json_with_finite_multipliers(capsys):
    """Before: ``floquet`` of a 1 Hz base motion printed NaN into its JSON.  Parsed here with NaN/Infinity refused."""
    from amb_dynamics import cli

    assert (
        cli.main(["floquet", "--motion", "pitch", "--amplitude", "0.3", "--frequency", str(2 * math.pi), "--json"]) == 0
    )

    def refuse(constant):
        raise ValueError(f"{constant} in the JSON")

    doc = json.loads(capsys.readouterr().out, parse_constant=refuse)
    mu = np.array(doc["multipliers"], dtype=float)
    assert mu.shape[1] == 2 and np.isfinite(mu).all() and doc["converged"] is True
    assert doc["max_abs_multiplier"] == pytest.approx(np.hypot(mu[:, 0], mu[:, 1]).max(), rel=1e-12)
