"""`amb-dynamics chart --controller sampled` on Dask: serial, local cluster and an external scheduler + two workers
give the same bits; a kill -9 resumes from the chunk cache; SIGTERM stops at once with no worker left; bad input.

One scheduler and two workers (``dask scheduler`` / ``dask worker``, separate processes on 127.0.0.1) are shared
by the module.  The grid is small (3 rows x 7 amplitudes near 30 rad/s: ~530 steps per period at 5 kHz).
"""

import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from amb_dynamics.chart_jobs import ChartSpec, run_chart_job
from amb_dynamics.config import load_config
from amb_dynamics.dask_exec import blas_threads
from helpers import stop_and_check, worker_processes

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "config" / "seed_paper.yaml"
BIN = Path(sys.executable).parent
OMEGAS, AMPS = np.linspace(28.0, 32.0, 3), np.linspace(0.0, 0.5, 7)
GRID = ["--motion", "pitch", "--frequency", "28:32:3", "--amplitude", "0:0.5:7"]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def chart_cmd(tmp: Path, *extra: str) -> list[str]:
    return [
        str(BIN / "amb-dynamics"), "chart", "--config", str(PAPER), "--controller", "sampled", *GRID,
        "--out", str(tmp / "c.png"), "--json-out", str(tmp / "c.json"), "--cache-dir", str(tmp / "cache"), *extra,
    ]  # fmt: skip


@pytest.fixture(scope="module")
def serial():
    spec = ChartSpec(load_config(PAPER), "pitch", "sampled", None)
    return run_chart_job(spec, OMEGAS, AMPS, None, 1, None, progress=False)


@pytest.fixture(scope="module")
def cluster():
    """``dask scheduler`` + two ``dask worker`` processes on 127.0.0.1; yields the address."""
    port = free_port()
    addr = f"tcp://127.0.0.1:{port}"
    procs = [
        subprocess.Popen(
            [str(BIN / "dask"), "scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
    ]
    time.sleep(1.0)
    for _ in range(2):
        procs.append(
            subprocess.Popen(
                [str(BIN / "dask"), "worker", addr, "--nthreads", "1", "--host", "127.0.0.1", "--no-dashboard"],
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
            )
        )
    from distributed import Client

    client = Client(addr, timeout=30)
    client.wait_for_workers(2, timeout=60)
    yield addr, client
    client.close()
    for p in procs[::-1]:
        p.terminate()
    for p in procs:
        try:
            p.wait(10)
        except subprocess.TimeoutExpired:
            p.kill()


def load(tmp: Path) -> dict:
    return json.loads((tmp / "c.json").read_text())


def assert_same_bits(doc: dict, ref: dict) -> None:
    assert np.array_equal(np.array(doc["max_abs_multiplier"]), ref["rho"])
    assert np.array_equal(np.array(doc["error_bound"]), ref["bound"])


def test_serial_chart_is_digital_and_bounded(serial):
    assert serial["rho"].shape == (3, 7) and (serial["method"] == 1).all()  # 28-32 rad/s: incommensurate
    assert (serial["bound"] < 1e-8).all()
    assert np.all(serial["rho"][:, 0] < 1.0)  # at rest the 5 kHz loop is stable


def test_local_cluster_equals_serial(tmp_path, serial):
    out = subprocess.run(chart_cmd(tmp_path, "--workers", "2", "--no-cache"), capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    doc = load(tmp_path)
    assert doc["schema_version"] == 1 and doc["controller"] == "sampled"
    assert_same_bits(doc, serial)
    assert "3/3 chunks" in out.stderr  # the progress line


def test_external_scheduler_two_workers_equals_serial(tmp_path, serial, cluster):
    addr, client = cluster
    assert set(client.run(blas_threads).values()) == {"1"}  # set by the nanny where the worker starts
    out = subprocess.run(chart_cmd(tmp_path, "--scheduler", addr, "--no-cache"), capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert_same_bits(load(tmp_path), serial)


def test_kill9_then_resume_equals_uninterrupted(tmp_path, serial):
    cmd = chart_cmd(tmp_path, "--workers", "1")
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and len(list((tmp_path / "cache").glob("*/chunk-*.npz"))) < 1:
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    n_cached = len(list((tmp_path / "cache").glob("*/chunk-*.npz")))
    assert 1 <= n_cached < 3 and not (tmp_path / "c.json").exists()
    out = subprocess.run(cmd, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    doc = load(tmp_path)
    assert doc["cache"]["cached_chunks"] == n_cached
    assert_same_bits(doc, serial)


@pytest.mark.parametrize(
    ("signum", "group"),
    [(signal.SIGTERM, False), (signal.SIGINT, True)],
    ids=["sigterm-to-the-main-process", "ctrl-c-to-the-process-group"],
)
def test_a_signal_stops_the_chart_within_a_second_without_orphans(tmp_path, signum, group):
    """SIGTERM as a supervisor sends it (to the main process only); Ctrl-C as a terminal sends it (SIGINT to the
    whole foreground process group, workers included)."""
    cmd = chart_cmd(tmp_path, "--workers", "2", "--no-cache")
    # slow rows (T/Ts ~ 6000), 60 of them: ~20 s on two workers here, so still running when the signal comes (6
    # rows were done in 3 s, and a signal during the PNG's writing after the workers have gone is not this test's)
    cmd[cmd.index("28:32:3")] = "2:3:60"
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True)
    deadline = time.monotonic() + 90
    workers = []
    while time.monotonic() < deadline:
        workers = worker_processes(proc)
        if len(workers) >= 2:
            break
        time.sleep(0.1)
    assert len(workers) == 2
    time.sleep(3.0)  # the workers are computing
    assert proc.poll() is None
    elapsed = stop_and_check(proc, workers, signum, group)
    assert elapsed < 1.0, elapsed
    assert not (tmp_path / "c.json").exists()


@pytest.mark.parametrize(
    ("extra", "needle"),
    [
        (["--scheduler", "tcp://127.0.0.1:{port}"], "cannot reach the Dask scheduler"),
        (["--workers", "0"], "--workers must be in 1..256"),
        (["--set", "controller.no_such_key=1"], "no_such_key"),
    ],
)
def test_bad_input_one_line_exit_2(tmp_path, capsys, extra, needle):
    from amb_dynamics import cli

    extra = [e.format(port=free_port()) for e in extra]
    assert cli.main(chart_cmd(tmp_path, *extra)[1:]) == 2
    err = capsys.readouterr().err
    lines = [ln for ln in err.replace("\r", "\n").splitlines() if ln.strip() and "chunks" not in ln]
    assert len(lines) == 1 and needle in lines[0], err
    assert not (tmp_path / "c.json").exists()
