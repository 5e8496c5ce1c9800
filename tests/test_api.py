"""The public namespace of amb_dynamics, no side effects on import, and one BLAS thread set by the entry points.

OpenBLAS starts its worker threads when numpy loads it, sized by OPENBLAS_NUM_THREADS: counting the threads of a
fresh process (/proc/self/task) shows whether an entry point set the variable in time.
"""

from __future__ import annotations

import ast
import importlib.util
import json
import os
import subprocess
import sys

import pytest

import amb_dynamics
from amb_dynamics.threads import BLAS_THREAD_VARIABLES

CORE_API = {
    "load_config",
    "build_structure",
    "closed_loop",
    "periodic_system",
    "BaseMotion",
    "modes_at_speed",
    "floquet_multipliers",
    "sampled_floquet",
    "stability_chart",
    "newmark_response",
    "SampledLoop",
    "StreamingEstimator",
    "EstimatorConfig",
    "limit_blas_threads",
}


def fresh_python(code: str) -> str:
    """stdout of a new interpreter without any BLAS thread setting in its environment."""
    env = {k: v for k, v in os.environ.items() if k not in BLAS_THREAD_VARIABLES}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    return out.stdout


def test_all_lists_the_public_api_without_side_effects():
    out = fresh_python(
        "import os, sys, json\n"
        "before = dict(os.environ)\n"
        "import amb_dynamics\n"
        "print(amb_dynamics.__all__)\n"
        "print(json.dumps([dict(os.environ) == before, 'numpy' in sys.modules]))\n"
    ).splitlines()
    names = ast.literal_eval(out[0])
    unchanged, numpy_loaded = json.loads(out[1])
    assert CORE_API <= set(names)
    assert names == sorted(set(names))
    assert all(not n.startswith("_") for n in names)
    assert unchanged, "importing amb_dynamics changed os.environ"
    assert not numpy_loaded, "importing amb_dynamics loaded numpy (too early for the entry points' BLAS setting)"


def test_every_public_name_resolves_and_unknown_names_fail():
    for name in amb_dynamics.__all__:
        obj = getattr(amb_dynamics, name)
        assert callable(obj), name
        assert obj.__module__.startswith("amb_dynamics."), name
    assert set(amb_dynamics.__all__) <= set(dir(amb_dynamics))
    # a public name that is also a submodule's would be replaced by the module once anything imports it
    clash = [n for n in amb_dynamics.__all__ if importlib.util.find_spec(f"amb_dynamics.{n}") is not None]
    assert clash == [], clash
    with pytest.raises(AttributeError, match="no_such_name"):
        _ = amb_dynamics.no_such_name


THREADS = "len(__import__('os').listdir('/proc/self/task'))"


@pytest.mark.skipif(not os.path.isdir("/proc/self/task"), reason="thread count read from Linux /proc")
def test_numpy_alone_starts_blas_threads():
    # the control: without the setting, loading numpy adds BLAS threads on a multi-core machine
    if (os.cpu_count() or 1) < 2:
        pytest.skip("one core: OpenBLAS starts no worker thread either way")
    n0, n1 = map(int, fresh_python(f"print({THREADS}); import numpy; print({THREADS})").split())
    assert n1 > n0


@pytest.mark.skipif(not os.path.isdir("/proc/self/task"), reason="thread count read from Linux /proc")
@pytest.mark.parametrize(
    "entry",
    [
        "from amb_dynamics.cli import main; main(['modes', '--speed-rpm', '0'])",
        "import amb_plant.node",
        "import amb_controller.node",
        "import base_motion.node",
        "import stability_monitor.node",
        "import stability_monitor.cli",
        "import amb_bag.cli",
        "import amb_bringup.rig",
    ],
)
def test_entry_points_load_numpy_with_one_blas_thread(entry):
    # rclpy starts threads of its own: count before and after the entry point loads numpy
    code = (
        "import contextlib, io, os, sys\n"
        "import rclpy\n"
        f"n0 = {THREADS}\n"
        "assert 'numpy' not in sys.modules\n"
        f"with contextlib.redirect_stdout(io.StringIO()):\n    {entry}\n"
        "import numpy\n"
        f"print(n0, {THREADS}, os.environ['OPENBLAS_NUM_THREADS'])\n"
    )
    n0, n1, value = fresh_python(code).split()
    assert value == "1"
    assert int(n1) == int(n0), f"{entry}: BLAS started {int(n1) - int(n0)} extra threads"
