"""Only amb-* commands of this project land on PATH (the venv's bin); the short ``ros2 run`` names
(controller, plant, monitor, record, base_motion) are installed only by colcon into lib/<package>
(tests/test_ros_layout.py checks that layout)."""

from importlib.metadata import distribution
from pathlib import Path

DISTS = ("amb_dynamics", "amb_ros", "base_motion", "amb_plant", "amb_controller", "stability_monitor", "amb_bag",
         "amb_bringup")  # fmt: skip
SHORT = ("controller", "plant", "monitor", "record", "base_motion")


def test_only_amb_commands_on_path(venv_bin):
    scripts = {ep.name for d in DISTS for ep in distribution(d).entry_points if ep.group == "console_scripts"}
    assert scripts == {"amb-dynamics", "amb-base-motion", "amb-plant", "amb-controller", "amb-monitor", "amb-bag",
                       "amb-rig", "amb-live"}  # fmt: skip
    installed_in_bin = {
        Path(str(f)).name for d in DISTS for f in (distribution(d).files or []) if Path(str(f)).parent.name == "bin"
    }
    assert installed_in_bin and all(name.startswith("amb-") for name in installed_in_bin), installed_in_bin
    assert not [s for s in SHORT if (venv_bin / s).exists()]


def test_setup_gives_short_names_to_colcon_only(repo):
    """The short names are added for ``setup.py install``/``develop`` (colcon), not for pip's wheel builds."""
    import runpy
    import sys
    from unittest import mock

    import setuptools

    for pkg, short in (("amb_controller", "controller"), ("amb_plant", "plant"), ("base_motion", "base_motion"),
                       ("stability_monitor", "monitor"), ("amb_bag", "record")):  # fmt: skip
        for argv, expected in ((["setup.py", "editable_wheel"], False), (["setup.py", "bdist_wheel"], False),
                               (["setup.py", "egg_info", "build", "install"], True),
                               (["setup.py", "develop"], True)):  # fmt: skip
            with mock.patch.object(setuptools, "setup") as setup, mock.patch.object(sys, "argv", argv):
                runpy.run_path(str(repo / "src" / pkg / "setup.py"))
            names = [s.split("=")[0].strip() for s in setup.call_args.kwargs["entry_points"]["console_scripts"]]
            assert (short in names) == expected, (pkg, argv)
            assert any(n.startswith("amb-") for n in names)
