"""`amb-dynamics sweep`: config keys as axes of a labelled netCDF dataset, boundary refinement located against a
fine scan with the single-point adaptive Magnus ``floquet`` (an independent path), bad input, kill -9 resume."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from amb_dynamics import cli
from amb_dynamics.config import load_config
from amb_dynamics.floquet import floquet
from amb_dynamics.motion import BaseMotion
from amb_dynamics.structure import build_structure
from amb_dynamics.system import closed_loop, periodic_system
from helpers import stop_and_check, worker_processes

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "config" / "seed_paper.yaml"
BIN = Path(sys.executable).parent


def sweep_args(tmp: Path, *extra: str) -> list[str]:
    return ["sweep", "--config", str(PAPER), "--motion", "pitch", "--out-dir", str(tmp / "sw"),
            "--cache-dir", str(tmp / "cache"), *extra]  # fmt: skip


@pytest.fixture(scope="module")
def tongue(tmp_path_factory):
    """Coarse grid (0.2 rad/s) over the 15.5-15.9 rad/s tongue at A = 0.4 rad, two spin speeds, refined."""
    tmp = tmp_path_factory.mktemp("tongue")
    grid = ["--frequency", "15.3:16.1:5", "--amplitude", "0.3,0.4", "--axis", "spin_speed_rpm=900,1000"]
    args = sweep_args(tmp, *grid, "--refine", "--tol", "1e-4", "--workers", "1", "--json")
    assert cli.main(args) == 0
    return tmp


def rho_floquet(omega: float, A: float = 0.4) -> float:
    cfg = load_config(PAPER)
    loop = closed_loop(build_structure(cfg), cfg)
    return floquet(periodic_system(loop, BaseMotion.single("pitch", A, omega), cfg.spin_rad_s), tol=1e-9).max_abs


def test_dataset_is_labelled_and_matches_single_points(tongue):
    ds = xr.open_dataset(tongue / "sw" / "sweep.nc", engine="scipy")
    assert list(ds.max_abs_multiplier.dims) == ["spin_speed_rpm", "omega_rad_s", "amplitude_rad"]
    assert ds.attrs["schema_version"] == 1
    assert ds.attrs["model"].endswith("full FE")  # the continuous sweep's model: the paper's modal_cutoff not used
    assert np.allclose(ds.spin_speed_rpm.values, [900, 1000]) and np.allclose(ds.amplitude_rad.values, [0.3, 0.4])
    v = float(ds.max_abs_multiplier.sel(spin_speed_rpm=1000, omega_rad_s=15.7, amplitude_rad=0.4, method="nearest"))
    assert abs(v - rho_floquet(15.7)) < 1e-6
    assert len(list((tongue / "sw").glob("slice_*.png"))) == 2


def test_refinement_finds_both_tongue_edges_against_a_fine_scan(tongue):
    edges = json.loads((tongue / "sw" / "boundaries.json").read_text())["boundaries"]
    ours = sorted(e["omega_rad_s"] for e in edges if e["spin_speed_rpm"] == 1000 and e["amplitude_rad"] == 0.4)
    assert len(ours) == 2 and 15.5 < ours[0] < ours[1] < 15.9
    for edge in ours:  # fine scan (step 5e-4 rad/s) within 2e-3 of the edge: the sign change must be there
        scan = edge + np.arange(-2e-3, 2.0001e-3, 5e-4)
        unstable = np.array([rho_floquet(w) > 1.0 for w in scan])
        flips = np.flatnonzero(unstable[1:] != unstable[:-1])
        assert flips.size == 1, unstable
        fine_edge = 0.5 * (scan[flips[0]] + scan[flips[0] + 1])
        assert abs(fine_edge - edge) <= 1e-3


@pytest.mark.parametrize(
    ("extra", "needle"),
    [
        (["--axis", "controller.no_such_key=1:2:2"], "no_such_key"),
        (["--axis", "controller.rate_hz=3000:6000:0"], "empty range"),
        (["--axis", "spin_speed_rpm=0,1000", "--scheduler", "tcp://127.0.0.1:9"], "cannot reach the Dask scheduler"),
    ],
)
def test_bad_input_one_line_no_dataset(tmp_path, capsys, extra, needle):
    args = sweep_args(tmp_path, "--frequency", "20:21:2", "--amplitude", "0.1,0.2", *extra)
    assert cli.main(args) == 2
    err = capsys.readouterr().err
    lines = [ln for ln in err.replace("\r", "\n").splitlines() if ln.strip() and "chunks" not in ln]
    assert len(lines) == 1 and needle in lines[0], err
    assert not (tmp_path / "sw" / "sweep.nc").exists()


def test_kill9_sweep_resumes_to_the_same_dataset(tmp_path):
    # 60 chunks, ~15 s on two workers here: after the first chunk there is work left (12 chunks were done in 2 s)
    grid = ["--frequency", "20:30:30", "--amplitude", "0:0.5:4", "--axis", "controller.rate_hz=4000,5000",
            "--controller", "sampled", "--workers", "1"]  # fmt: skip
    cmd = [str(BIN / "amb-dynamics"), *sweep_args(tmp_path, *grid)]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and len(list((tmp_path / "cache").glob("*/chunk-*.npz"))) < 2:
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    cached = len(list((tmp_path / "cache").glob("*/chunk-*.npz")))
    assert 2 <= cached < 12 and not (tmp_path / "sw" / "sweep.nc").exists()
    assert subprocess.run(cmd, capture_output=True).returncode == 0
    resumed = xr.open_dataset(tmp_path / "sw" / "sweep.nc", engine="scipy").load()
    meta = json.loads((tmp_path / "sw" / "boundaries.json").read_text())
    assert meta["cache"]["cached_chunks"] == cached
    fresh = tmp_path / "fresh"
    assert cli.main(sweep_args(fresh, *grid, "--no-cache")) == 0
    ref = xr.open_dataset(fresh / "sw" / "sweep.nc", engine="scipy").load()
    assert np.array_equal(resumed.max_abs_multiplier.values, ref.max_abs_multiplier.values)
    assert np.array_equal(resumed.error_bound.values, ref.error_bound.values)


@pytest.mark.parametrize(("signum", "group"), [(signal.SIGTERM, False), (signal.SIGINT, True)],
                         ids=["sigterm-to-the-main-process", "ctrl-c-to-the-process-group"])  # fmt: skip
def test_a_signal_stops_the_sweep_within_a_second_without_orphans(tmp_path, signum, group):
    # 60 chunks, ~15 s on two workers here: after the first chunk there is work left (12 chunks were done in 2 s)
    grid = ["--frequency", "20:30:30", "--amplitude", "0:0.5:4", "--axis", "controller.rate_hz=4000,5000",
            "--controller", "sampled", "--workers", "2"]  # fmt: skip
    cmd = [str(BIN / "amb-dynamics"), *sweep_args(tmp_path, *grid)]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and not list((tmp_path / "cache").glob("*/chunk-*.npz")):
        time.sleep(0.05)
    workers = worker_processes(proc)
    assert proc.poll() is None and len(workers) >= 1  # mid-sweep, its worker processes computing
    elapsed = stop_and_check(proc, workers, signum, group)
    assert elapsed < 1.0, elapsed
    assert not (tmp_path / "sw" / "sweep.nc").exists()
