"""`colcon build` + `ros2 run` layout: each executable is found the way ros2 run finds it, and runs.

The node packages (with the core and amb_ros) are copied into a temporary workspace and built with colcon (build,
install and log bases in tmp_path).  With the environment that ``install/setup.bash`` gives (AMENT_PREFIX_PATH
and PYTHONPATH of the install, plus the venv's prefix for the message packages, which pip installed there), each
executable is resolved as ros2run does: ``get_package_prefix(pkg)`` / lib / pkg / exe, a file, executable.
Then each node is started from that path with a bad parameter (one line, exit 2), and a short lockstep run
of the three nodes from the install completes.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from procs import spawn

pytestmark = pytest.mark.ros

PACKAGES = ("amb_dynamics", "amb_ros", "base_motion", "amb_plant", "amb_controller", "amb_bringup")
EXECUTABLES = [("base_motion", "base_motion"), ("amb_plant", "plant"), ("amb_controller", "controller"),
               ("amb_bringup", "amb-rig")]  # fmt: skip
RESOLVE = """
import os, sys
from ament_index_python.packages import get_package_prefix
pkg, exe = sys.argv[1], sys.argv[2]
prefix = get_package_prefix(pkg)
path = os.path.join(prefix, 'lib', pkg, exe)
print(prefix); print(path); print(os.path.isfile(path) and os.access(path, os.X_OK))
"""


@pytest.fixture(scope="module")
def workspace(tmp_path_factory, repo):
    ws = tmp_path_factory.mktemp("colcon_ws")
    for pkg in PACKAGES:
        shutil.copytree(
            repo / "src" / pkg, ws / "src" / pkg, ignore=shutil.ignore_patterns("*.egg-info", "__pycache__")
        )
    venv = Path(sys.executable).parent.parent
    env = dict(os.environ, AMENT_PREFIX_PATH=str(venv))
    out = subprocess.run(
        [str(venv / "bin" / "colcon"), "--log-base", "log", "build", "--base-paths", "src", "--build-base", "build",
         "--install-base", "install"],
        cwd=ws, env=env, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]
    install = ws / "install"
    site = f"lib/python{sys.version_info.major}.{sys.version_info.minor}/site-packages"
    run_env = dict(
        os.environ,
        AMENT_PREFIX_PATH=os.pathsep.join([*(str(install / p) for p in PACKAGES), str(venv)]),
        PYTHONPATH=os.pathsep.join(str(install / p / site) for p in PACKAGES),
    )
    return install, run_env


def resolve(env, pkg: str, exe: str) -> Path:
    out = subprocess.run([sys.executable, "-c", RESOLVE, pkg, exe], env=env, capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    prefix, path, executable = out.stdout.split()
    assert executable == "True", path
    return Path(prefix), Path(path)


def test_executables_resolve_like_ros2_run(workspace):
    install, env = workspace
    for pkg, exe in EXECUTABLES:
        prefix, path = resolve(env, pkg, exe)
        assert prefix == install / pkg
        assert path == install / pkg / "lib" / pkg / exe
    # the launch files, where ros2 launch looks for them (setup.py data_files)
    launch = install / "amb_bringup" / "share" / "amb_bringup" / "launch"
    assert sorted(p.name for p in launch.glob("*.launch.py")) == [
        "record.launch.py", "rig.launch.py", "rig_no_plant.launch.py"]  # fmt: skip


def test_installed_nodes_start(workspace, tmp_path, repo):
    _, env = workspace
    paths = {pkg: resolve(env, pkg, exe)[1] for pkg, exe in EXECUTABLES}
    # no config_file: the nodes find the seed rotor installed with amb_dynamics (package data)
    args = ["--ros-args"]
    for pkg in ("base_motion", "amb_plant", "amb_controller"):
        out = subprocess.run([str(paths[pkg]), *args, "-p", "rate_hz:=-1.0"], env=env, capture_output=True,
                             text=True, timeout=60)  # fmt: skip
        lines = [ln for ln in (out.stdout + out.stderr).splitlines() if ln.strip()]
        assert out.returncode == 2 and len(lines) == 1 and "'rate_hz' = -1.0 is out of range" in lines[0], out
    out = subprocess.run([str(paths["amb_bringup"]), "run", "--help"], env=env, capture_output=True, text=True,
                         timeout=60)  # fmt: skip
    assert out.returncode == 0 and "--no-plant" in out.stdout
    # a short lockstep run of the three installed nodes
    with (
        spawn([str(paths["base_motion"]), *args], tmp_path / "base.log", env=env),
        spawn([str(paths["amb_controller"]), *args], tmp_path / "ctl.log", env=env),
        spawn([str(paths["amb_plant"]), *args, "-p", "duration_s:=0.05"], tmp_path / "plant.log", env=env) as plant,
    ):
        assert plant.wait(90) == 0, plant.text()
