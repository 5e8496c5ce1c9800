"""What a run starts: the node processes and any extra processes (recorder, monitor), as ProcessSpecs.

Each node gets one ROS params file (written to the run's log folder) with the common parameters under ``/**``
and its own under its node name, so that values with commas or brackets need no shell or YAML-inline quoting.

Extension hook: ``EXTRA_PROCESSES`` is a list of functions ``f(args, run_dir) -> ProcessSpec | None`` called
after the core nodes are built; ``amb-bag record`` for ``--bag`` is registered here, and a stability monitor
can be added the same way (its diagnostics then appear in the summary under its node name).
"""

from __future__ import annotations

import shutil
import sys
from collections.abc import Callable
from pathlib import Path

import yaml

from .live import live_process
from .supervisor import ProcessSpec

NODES = {  # name in amb-rig -> (ROS package, ros2 run executable, venv console script, ROS node name)
    "base_motion": ("base_motion", "base_motion", "amb-base-motion", "base_motion"),
    "controller": ("amb_controller", "controller", "amb-controller", "amb_controller"),
    "plant": ("amb_plant", "plant", "amb-plant", "amb_plant"),
    "monitor": ("stability_monitor", "monitor", "amb-monitor", "stability_monitor"),
}


def resolve_executable(package: str, ros_exe: str, script: str) -> str:
    """The venv's console script next to this interpreter, else PATH, else the ament index (ros2 run layout)."""
    here = Path(sys.executable).parent / script
    if here.is_file():
        return str(here)
    found = shutil.which(script)
    if found:
        return found
    try:
        from ament_index_python.packages import get_package_prefix

        path = Path(get_package_prefix(package)) / "lib" / package / ros_exe
        if path.is_file():
            return str(path)
    except Exception:  # no ament index in this environment: fall through to the clear error below
        pass
    raise FileNotFoundError(f"cannot find the executable of {package} ({script} or lib/{package}/{ros_exe})")


def node_parameters(args) -> tuple[dict, dict[str, dict]]:
    """(common, per-node) parameters for a run."""
    sets = list(args.set)
    if args.motion is not None:
        sets.append(f"base_motion.kind={args.motion}")
    if args.amplitude is not None:
        sets.append(f"base_motion.amplitude={args.amplitude!r}")
    if args.frequency is not None:
        sets.append(f"base_motion.frequency={args.frequency!r}")
    common: dict = {"mode": args.mode}
    if args.config:
        common["config_file"] = str(Path(args.config).resolve())
    if sets:
        common["set"] = sets
    per = {name: {} for name in NODES}
    # lockstep: the plant ends the run after --duration of simulated time; realtime: amb-rig ends it after
    # --duration of wall time by stopping every node at once (a plant that stopped first would leave the
    # controller without samples, which it rightly reports as an ERROR)
    per["plant"]["duration_s"] = float(args.duration) if args.mode == "lockstep" else 0.0
    if args.initial_displacement:
        per["plant"]["initial_displacement"] = float(args.initial_displacement)
    per["plant"]["start_timeout_s"] = float(args.start_timeout)
    token = getattr(args, "run_token", None)
    if token:  # the loop's two topics carry it; a message without it is another run's (docs/topics.md)
        per["plant"]["run_token"] = per["controller"]["run_token"] = token
    bag, live = int(bool(getattr(args, "bag", None))), int(bool(getattr(args, "live", False)))
    # the count alone can be met by the other host's readers in a split run: amb-rig's collector is also named
    collector = getattr(args, "collector_name", "")
    for name in NODES:  # amb-rig's collector, the recorder and the live view must hear every final report: one
        # matched reader is not enough when it is the recorder (seen: the collector heard no report of a short run)
        per[name]["min_diagnostics_readers"] = 1 + bag + live  # the plant's also gates its start
        if collector:
            per[name]["diagnostics_collector"] = collector
    if args.rt_priority:  # the loop's nodes only: the monitor and the recorder run beside it (consumer_priority)
        for name in ("base_motion", "controller", "plant"):
            per[name]["rt_priority"] = int(args.rt_priority)
    per["monitor"]["priority"] = consumer_priority(args.mode)
    for item in args.param:
        node, _, rest = item.partition(":")
        key, sep, raw = rest.partition("=")
        if node not in per or not sep or not key:
            raise ValueError(f"--param {item!r}: expected NODE:NAME=VALUE with NODE one of {', '.join(per)}")
        per[node][key] = yaml.safe_load(raw)
    # every reader gets every sample from the first: the plant and base_motion wait for them before step 0
    monitor = int(not getattr(args, "no_monitor", True))
    if monitor and args.no_plant:
        per["monitor"].setdefault("input", "displacement")  # a real rig measures the AMB displacements only
    sensor_only = monitor and per["monitor"].get("input") == "displacement"
    monitor_imu = monitor and not per["monitor"].get("period_s")  # a given period: the monitor reads no /base/imu
    gates = {
        ("plant", "min_subscribers"): 1 + bag + sensor_only,  # the controller, the recorder, the monitor
        ("controller", "min_subscribers"): (0 if args.no_plant else 1) + bag,  # /amb/current: the plant, the recorder
        ("plant", "min_state_subscribers"): bag + (monitor and not sensor_only),
        ("base_motion", "min_rates_subscribers"): (0 if args.no_plant else 1) + bag,  # lockstep: the plant's input
        ("base_motion", "min_imu_subscribers"): bag + monitor_imu,
        ("base_motion", "min_acceleration_subscribers"): bag,
    }
    for (node, key), value in gates.items():
        per[node].setdefault(key, int(value))  # an explicit --param wins
    return common, per


def write_params_file(path: Path, common: dict, per: dict[str, dict]) -> None:
    doc = {"/**": {"ros__parameters": common}}
    for name, params in per.items():
        if params:
            doc[NODES[name][3]] = {"ros__parameters": params}
    path.write_text(yaml.safe_dump(doc, sort_keys=False))


def node_specs(args, run_dir: Path) -> list[ProcessSpec]:
    common, per = node_parameters(args)
    params = run_dir / "params.yaml"
    write_params_file(params, common, per)
    names = ["base_motion", "controller"] + ([] if args.no_plant else ["plant"])
    if getattr(args, "only", None) == "plant":  # the rig side of a split run (amb_bringup.split)
        names = ["plant"]
    if getattr(args, "no_base_motion", False):  # a real rig's own IMU publishes the base motion
        names.remove("base_motion")
    specs = []
    for name in names:
        package, ros_exe, script, node = NODES[name]
        cmd = [resolve_executable(package, ros_exe, script), "--ros-args", "--params-file", str(params)]
        specs.append(ProcessSpec(name, cmd, node=node, ends_run=(name == "plant" and args.mode == "lockstep")))
    return specs


def consumer_priority(mode: str) -> str:
    """Scheduling of the recorder and the monitor beside the loop (``--priority`` / ``priority``).

    Realtime: ``low`` (niceness +5): below the loop's SCHED_FIFO nodes, which it cannot preempt, and not
    SCHED_IDLE.  Beside the real rig's 2 kHz LQG loop (``amb-rig run --config config/seed_rotor_2khz_lqg.yaml
    --mode realtime --duration 5 --motion none --param monitor:priority=P``) the rotor dropped in 7 of 22 runs
    with P = idle and in 1 of 20 with low or normal, on this 2-core machine.  The monitor's DDS threads share Fast
    DDS's transport with the loop's writers, and an idle-class thread that holds something they wait for runs
    last (the likely mechanism; the loop's own nodes then stall for milliseconds).  Lockstep: ``normal``.
    Lockstep has no deadline, and a consumer that falls more than the publishers' history (1000 samples) behind
    loses samples; then the bag or the verdict is incomplete.  Seen under SCHED_IDLE on a loaded 2-core machine:
    the recorder of a lockstep run lost 4,375 samples.
    """
    return "normal" if mode == "lockstep" else "low"


def recorder_arguments(args) -> list[str]:
    """``amb-bag record`` arguments of a run's recorder (amb-rig and rig.launch.py)."""
    out = ["-o", str(args.bag), "--priority", consumer_priority(args.mode)]
    collector = getattr(args, "collector_name", "")
    return out + (["--diagnostics-collector", collector] if collector else [])


def bag_process(args, run_dir: Path) -> ProcessSpec | None:
    """``amb-bag record -o DIR`` when --bag is given and amb-bag is installed."""
    if not getattr(args, "bag", None):
        return None
    exe = Path(sys.executable).parent / "amb-bag"
    exe = str(exe) if exe.is_file() else shutil.which("amb-bag")
    if exe is None:
        raise FileNotFoundError("--bag needs the amb-bag recorder, which is not installed")
    return ProcessSpec(
        "recorder",
        [exe, "record", *recorder_arguments(args)],
        node="amb_bag_recorder",
        required=True,
        stop_tier=2,
    )  # stopped last: it records everyone's final diagnostics


def monitor_process(args, run_dir: Path) -> ProcessSpec | None:
    """The stability monitor (unless --no-monitor); its UNSTABLE verdict is a result, not a failed run."""
    if getattr(args, "no_monitor", True):
        return None
    package, ros_exe, script, node = NODES["monitor"]
    cmd = [resolve_executable(package, ros_exe, script), "--ros-args", "--params-file", str(run_dir / "params.yaml")]
    return ProcessSpec("monitor", cmd, node=node, required=True, stop_tier=1, verdict_only=True)


EXTRA_PROCESSES: list[Callable[..., ProcessSpec | None]] = [bag_process, monitor_process, live_process]


def all_specs(args, run_dir: Path) -> list[ProcessSpec]:
    """Extras first (a recorder must be listening before the first sample), then the nodes, plant last."""
    extras = [spec for f in EXTRA_PROCESSES if (spec := f(args, run_dir)) is not None]
    return extras + node_specs(args, run_dir)
