"""What the launch files start, computed by amb-rig's own code so that the two cannot drift apart.

The launch files in ``launch/`` (installed to share/amb_bringup/launch) declare ``ARGUMENTS`` and hand the
resolved values to :func:`actions`, which turns them into an ``amb-rig run`` command line, parses it with
amb-rig's own parser, checks and resolves every node's parameters with amb-rig's own table
(:func:`amb_bringup.paramfile.prepare`) and returns one ``launch_ros`` Node per process amb-rig would start, with
the same executables (the ``ros2 run`` names) and the same parameters.  Only the ``launch`` / ``launch_ros``
imports are left to a full ROS 2 install.
"""

from __future__ import annotations

from dataclasses import dataclass, field

# launch argument, default ('' = amb-rig's default), description; each maps to the amb-rig option --name-with-dashes
ARGUMENTS = [
    ("duration", "5.0", "run length: simulated s (lockstep), wall s (realtime)"),
    ("mode", "lockstep", "lockstep (the plant is the /clock master) or realtime"),
    ("motion", "", "base motion kind: none, roll, pitch, yaw, combined (default: the config's)"),
    ("amplitude", "", "base motion amplitude (rad)"),
    ("frequency", "", "base motion angular frequency (rad/s)"),
    ("initial_displacement", "0.0", "initial lateral displacement of the disk (m)"),
    ("config", "", "rotor config YAML (default: the seed rotor)"),
    ("set", "", "config overrides key=value, separated by spaces"),
    ("params_file", "", "ROS 2 params file for the nodes (as amb-rig's --params-file)"),
    ("rt_priority", "", "SCHED_FIFO priority of base_motion, plant and controller"),
    ("no_monitor", "false", "do not start the stability monitor"),
    ("no_plant", "false", "no plant: a real rig supplies /amb/displacement"),
    ("bag", "", "record the run with amb-bag into this folder"),
]
FLAGS = ("no_monitor", "no_plant")
LISTS = ("set", "params_file")


@dataclass
class LaunchNode:
    """One process as a launch file starts it (the arguments of ``launch_ros.actions.Node``)."""

    package: str
    executable: str
    name: str | None
    parameters: list[dict] = field(default_factory=list)
    arguments: list[str] = field(default_factory=list)
    ends_run: bool = False  # lockstep plant: the launch ends when it exits


def rig_argv(values: dict[str, str]) -> list[str]:
    """The ``amb-rig run`` arguments equivalent to launch argument ``values`` (strings, '' = unset)."""
    argv = ["run"]
    for name, default, _ in ARGUMENTS:
        value = str(values.get(name, default)).strip()
        option = "--" + name.replace("_", "-")
        if name in FLAGS:
            if value.lower() in ("true", "1", "yes"):
                argv.append(option)
        elif name in LISTS:
            for item in value.split():
                argv += [option, item]
        elif value:
            argv += [option, value]
    return argv


def describe(values: dict[str, str], recorder_only: bool = False) -> list[LaunchNode]:
    """The processes amb-rig would start for launch argument ``values``; raises AmbError/SystemExit on bad input."""
    from .paramfile import prepare, started_nodes
    from .processes import NODES, recorder_arguments
    from .rig import parser

    args = parser().parse_args(rig_argv(values))
    if recorder_only:  # beside someone else's loop: the recorder's own default scheduling
        return [LaunchNode("amb_bag", "record", None, arguments=["-o", args.bag])] if args.bag else []
    bag = [LaunchNode("amb_bag", "record", None, arguments=recorder_arguments(args))] if args.bag else []
    if args.rt_priority is None:  # as amb-rig's main()
        args.rt_priority = 20 if args.mode == "realtime" else 0
    common, per = prepare(args)
    nodes = []
    for name in started_nodes(args):
        package, ros_exe, _, node = NODES[name]
        params = [common] + ([per[name]] if per.get(name) else [])
        ends = name == "plant" and args.mode == "lockstep"
        nodes.append(LaunchNode(package, ros_exe, node, params, ends_run=ends))
    return bag + nodes


def actions(context, recorder_only: bool = False) -> list:
    """launch_ros actions for an OpaqueFunction (``context.launch_configurations`` holds the arguments)."""
    from launch.actions import Shutdown
    from launch_ros.actions import Node

    values = dict(context.launch_configurations)
    out = []
    for n in describe(values, recorder_only):
        kw = {"on_exit": Shutdown()} if n.ends_run else {}
        out.append(Node(package=n.package, executable=n.executable, name=n.name, parameters=n.parameters,
                        arguments=n.arguments, output="screen", **kw))  # fmt: skip
    return out


def launch_description(recorder_only: bool = False, overrides: dict[str, str] | None = None):
    """The whole LaunchDescription of a launch file (its ``generate_launch_description``)."""
    from launch import LaunchDescription
    from launch.actions import DeclareLaunchArgument, OpaqueFunction

    defaults = {**{n: d for n, d, _ in ARGUMENTS}, **(overrides or {})}
    declared = [DeclareLaunchArgument(n, default_value=defaults[n], description=h) for n, _, h in ARGUMENTS]
    return LaunchDescription([*declared, OpaqueFunction(function=actions, kwargs={"recorder_only": recorder_only})])
