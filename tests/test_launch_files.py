"""The launch files (src/amb_bringup/launch) start what ``amb-rig run`` starts, with the same parameters.

``launch`` and ``launch_ros`` are not installable here, so a stub of the part of their API the files use records
what they build; the files are loaded from the source tree as ``ros2 launch`` would load them, their
OpaqueFunction is called with the declared defaults (plus launch arguments), and the resulting nodes are compared
with amb-rig's own process list (amb_bringup.processes.all_specs) and the params file it writes for its nodes.
"""

from __future__ import annotations

import importlib.util
import sys
import types
from pathlib import Path

import pytest
import yaml

from amb_bringup import paramfile, processes
from amb_bringup.rig import parser

LAUNCH_DIR = Path(__file__).resolve().parents[1] / "src" / "amb_bringup" / "launch"


class Recorded:
    def __init__(self, *args, **kwargs):
        self.args, self.kwargs = args, kwargs


@pytest.fixture
def launch_stub(monkeypatch):
    """Minimal ``launch`` / ``launch_ros`` modules whose classes record their arguments."""
    names = {
        "launch": ["LaunchDescription"],
        "launch.actions": ["DeclareLaunchArgument", "OpaqueFunction", "Shutdown"],
        "launch_ros": [],
        "launch_ros.actions": ["Node"],
    }
    for mod, classes in names.items():
        m = types.ModuleType(mod)
        for cls in classes:
            setattr(m, cls, type(cls, (Recorded,), {}))
        monkeypatch.setitem(sys.modules, mod, m)
    sys.modules["launch"].actions = sys.modules["launch.actions"]
    sys.modules["launch_ros"].actions = sys.modules["launch_ros.actions"]


def run_launch_file(name: str, arguments: dict[str, str]) -> list:
    """Load ``name`` as ros2 launch does and evaluate it with ``arguments`` (name -> value) over the defaults."""
    spec = importlib.util.spec_from_file_location(name.replace(".", "_"), LAUNCH_DIR / name)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    ld = module.generate_launch_description()
    entities = ld.args[0]
    declared = {e.args[0]: e.kwargs["default_value"] for e in entities if type(e).__name__ == "DeclareLaunchArgument"}
    assert set(arguments) <= set(declared), set(arguments) - set(declared)
    context = types.SimpleNamespace(launch_configurations={**declared, **arguments})
    (opaque,) = [e for e in entities if type(e).__name__ == "OpaqueFunction"]
    return opaque.kwargs["function"](context, **opaque.kwargs.get("kwargs", {}))


def amb_rig_processes(argv: list[str], tmp_path: Path):
    """What amb-rig starts for ``argv``: {ROS node name or 'recorder': (argv tail, parameters)}."""
    args = parser().parse_args(["run", *argv])
    paramfile.prepare(args)
    if args.rt_priority is None:
        args.rt_priority = 20 if args.mode == "realtime" else 0
    out = {}
    for spec in processes.all_specs(args, tmp_path):
        if spec.node == "amb_bag_recorder":
            out["recorder"] = (spec.cmd[2:], None)  # amb-bag record <args>
            continue
        doc = yaml.safe_load(Path(spec.cmd[spec.cmd.index("--params-file") + 1]).read_text())
        params = {**doc["/**"]["ros__parameters"], **doc.get(spec.node, {}).get("ros__parameters", {})}
        out[spec.node] = (spec.cmd[0], params)
    return out


def launched(nodes) -> dict:
    out = {}
    for n in nodes:
        kw = n.kwargs
        if kw["package"] == "amb_bag":
            assert kw["executable"] == "record"
            out["recorder"] = (kw["arguments"], None)
            continue
        rig_name = next(k for k, v in processes.NODES.items() if v[3] == kw["name"])
        package, ros_exe, script, _ = processes.NODES[rig_name]
        assert (kw["package"], kw["executable"]) == (package, ros_exe)  # what ros2 run finds in lib/<package>
        params = {}
        for layer in kw["parameters"]:
            params.update(layer)
        out[kw["name"]] = (script, params, "on_exit" in kw)
    return out


CASES = [
    ("rig.launch.py", {}, []),
    ("rig.launch.py", {"duration": "1.5", "motion": "roll", "amplitude": "0.2", "frequency": "20.0",
                       "set": "controller.rate_hz=2000 base_forcing=true", "bag": "out/b1",
                       "initial_displacement": "1e-4"},
     ["--duration", "1.5", "--motion", "roll", "--amplitude", "0.2", "--frequency", "20.0", "--set",
      "controller.rate_hz=2000", "--set", "base_forcing=true", "--bag", "out/b1", "--initial-displacement", "1e-4"]),
    ("rig.launch.py", {"mode": "realtime", "no_monitor": "true"}, ["--mode", "realtime", "--no-monitor"]),
    ("rig_no_plant.launch.py", {}, ["--no-plant"]),
]  # fmt: skip


@pytest.mark.parametrize(("name", "arguments", "argv"), CASES)
def test_launch_file_starts_what_amb_rig_starts(launch_stub, tmp_path, name, arguments, argv):
    got = launched(run_launch_file(name, arguments))
    want = amb_rig_processes(argv, tmp_path)
    assert sorted(got) == sorted(want)
    for node, (script, params, ends) in ((k, v) for k, v in got.items() if k != "recorder"):
        rig_cmd, rig_params = want[node]
        assert Path(rig_cmd).name == script
        assert params == rig_params, node
        # the launch ends with the plant in lockstep, as amb-rig's run does
        assert ends == (node == "amb_plant" and rig_params["mode"] == "lockstep")
    if "recorder" in want:
        assert got["recorder"][0] == want["recorder"][0]


def test_params_file_argument_and_recorder_launch(launch_stub, tmp_path):
    pf = tmp_path / "p.yaml"
    pf.write_text("amb_controller:\n  ros__parameters:\n    proportional_gain: 2.0e4\n")
    got = launched(run_launch_file("rig.launch.py", {"params_file": str(pf)}))
    assert got["amb_controller"][1]["proportional_gain"] == 2.0e4
    assert got["amb_controller"][1] == amb_rig_processes(["--params-file", str(pf)], tmp_path)["amb_controller"][1]
    rec = launched(run_launch_file("record.launch.py", {"bag": "out/rec"}))
    assert rec == {"recorder": (["-o", "out/rec"], None)}
    # amb-rig's own recorder sits beside a lockstep loop: never starved (the recorder alone keeps its default)
    assert amb_rig_processes(["--bag", "out/rec"], tmp_path)["recorder"][0] == ["-o", "out/rec", "--priority", "normal"]


def test_a_typo_in_a_launch_argument_fails_like_amb_rig(launch_stub, tmp_path):
    from amb_dynamics.errors import InputError

    pf = tmp_path / "p.yaml"
    pf.write_text("amb_controller:\n  ros__parameters:\n    proportinal_gain: 2.0e4\n")
    with pytest.raises(InputError, match="did you mean 'proportional_gain'"):
        run_launch_file("rig.launch.py", {"params_file": str(pf)})


def test_launch_files_are_installed():
    setup = (LAUNCH_DIR.parent / "setup.py").read_text()
    assert '("share/" + PACKAGE + "/launch", sorted(glob("launch/*.launch.py")))' in setup
    assert sorted(p.name for p in LAUNCH_DIR.glob("*.launch.py")) == [
        "record.launch.py", "rig.launch.py", "rig_no_plant.launch.py"]  # fmt: skip
