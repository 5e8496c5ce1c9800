"""Run independent chunks of a grid serially or on Dask distributed, with an on-disk cache, progress and clean stops.

* ``workers=1`` (and no scheduler): in this process.  Otherwise a ``LocalCluster`` of ``workers`` processes
  (default: the machine's cores), one thread each, BLAS limited to one thread in every worker process by the
  nanny before it starts (``OPENBLAS_NUM_THREADS`` etc.), bound to 127.0.0.1, no dashboard; or, with
  ``scheduler="tcp://HOST:PORT"``, an existing cluster (``dask scheduler`` + ``dask worker``, Kubernetes, HPC).
* Every finished chunk is saved as ``<cache>/<key>/chunk-<i>.npz`` (written to a temporary name, then renamed):
  a killed run restarts where it stopped.  The key hashes everything the numbers depend on.
* The numbers do not depend on where they ran: each chunk is a deterministic function of its arguments.
* The first SIGINT or SIGTERM kills the local worker processes and raises :class:`Interrupted` (the caller exits
  130 or 143); nothing half-written is left (chunks are atomic, outputs are written last).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from .errors import InputError

BLAS_ENV = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
CONNECT_TIMEOUT_S = 5.0
PRELOAD = "amb_dynamics.chart_jobs"  # numpy, scipy and the chart kernels: a worker imports them as it starts


class Interrupted(Exception):
    """The run was stopped by SIGINT or SIGTERM (``signum``)."""

    def __init__(self, signum: int):
        super().__init__(f"interrupted by signal {signum}")
        self.signum = signum


def cache_key(*parts) -> str:
    """sha256 (first 20 hex digits) of a JSON rendering of ``parts`` (numpy arrays as their exact float hex)."""

    def enc(o):
        if isinstance(o, np.ndarray):
            return [float(v).hex() for v in o.ravel()] + [list(o.shape)]
        if isinstance(o, float):
            return o.hex()
        raise TypeError(type(o))

    text = json.dumps(parts, default=enc, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:20]


def blas_threads() -> str | None:
    """OPENBLAS_NUM_THREADS as seen by the process that runs this (for tests of the worker start-up)."""
    return os.environ.get("OPENBLAS_NUM_THREADS")


class _Signals:
    """First SIGINT/SIGTERM: remember it and raise Interrupted in the main thread."""

    def __enter__(self):
        self.old = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
        for s in self.old:
            signal.signal(s, self._handler)
        return self

    def _handler(self, signum, _frame):
        for s, h in self.old.items():  # a second signal gets the default behaviour
            signal.signal(s, h)
        raise Interrupted(signum)

    def __exit__(self, *exc):
        for s, h in self.old.items():
            signal.signal(s, h)
        return False


class ChunkRunner:
    """Evaluate ``fn(*args)`` for every ``args`` in ``chunks``; each result a dict of numpy arrays.

    Parameters
    ----------
    fn : module-level function (importable on the workers)
    chunks : sequence of argument tuples
    label : name used in the progress line
    cache_dir : folder of this job's chunk files (None: no cache)
    workers : number of local worker processes (1: serial in this process; None: os.cpu_count())
    scheduler : address of an existing Dask scheduler (overrides ``workers``)
    progress : print a progress line on stderr
    """

    def __init__(
        self,
        fn: Callable,
        chunks: Sequence[tuple],
        label: str,
        cache_dir: Path | None = None,
        workers: int | None = None,
        scheduler: str | None = None,
        progress: bool = True,
    ):
        self.fn, self.chunks, self.label = fn, list(chunks), label
        self.cache_dir = Path(cache_dir) if cache_dir else None
        self.workers = workers if workers is not None else (os.cpu_count() or 1)
        self.scheduler, self.progress = scheduler, progress
        if self.workers < 1:
            raise InputError(f"--workers must be >= 1 (got {self.workers})")
        self.cached = 0
        self.compute_seconds: float | None = None
        self._t0 = time.perf_counter()

    # ---- cache ------------------------------------------------------------------------------------------
    def _path(self, i: int) -> Path | None:
        return self.cache_dir / f"chunk-{i:06d}.npz" if self.cache_dir else None

    def _load(self, i: int) -> dict | None:
        p = self._path(i)
        if p is None or not p.exists():
            return None
        try:
            with np.load(p) as z:
                return {k: z[k] for k in z.files}
        except (OSError, ValueError, EOFError):  # a damaged file is recomputed
            return None

    def _store(self, i: int, res: dict) -> None:
        p = self._path(i)
        if p is None:
            return
        p.parent.mkdir(parents=True, exist_ok=True)
        tmp = p.with_name(f".{p.name}.{os.getpid()}.part")
        with open(tmp, "wb") as f:
            np.savez(f, **res)
        os.replace(tmp, p)

    def _report(self, done: int) -> None:
        if not self.progress:
            return
        n = len(self.chunks)
        bar = "#" * int(30 * done / max(n, 1))
        dt = time.perf_counter() - self._t0
        msg = f"\r{self.label} {bar:<30} {done}/{n} chunks ({self.cached} cached) {dt:6.1f} s"
        print(msg, end="", file=sys.stderr, flush=True)

    # ---- run --------------------------------------------------------------------------------------------
    def run(self) -> list[dict]:
        results: list[dict | None] = [self._load(i) for i in range(len(self.chunks))]
        todo = [i for i, r in enumerate(results) if r is None]
        self.cached = len(results) - len(todo)
        done = self.cached
        self._report(done)
        try:
            with _Signals():
                if todo and self.scheduler is None and self.workers == 1:
                    for i in todo:
                        results[i] = self.fn(*self.chunks[i])
                        self._store(i, results[i])
                        done += 1
                        self._report(done)
                elif todo:
                    self._run_dask(todo, results, done)
        finally:
            if self.progress:
                print(file=sys.stderr, flush=True)  # end the progress line (also before an error)
        return results  # type: ignore[return-value]

    def _run_dask(self, todo: list[int], results: list, done: int) -> None:
        """Dask in a thread with SIGINT/SIGTERM blocked (so are the threads it starts): the signals reach the main
        thread, which only waits, and stop the run at once (a signal taken by a Dask thread would wait for
        whatever the main thread blocks on, up to 10 s)."""
        finished, box = threading.Event(), {}

        def body():
            signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
            try:
                self._dask_body(todo, results, done)
            except BaseException as exc:  # handed to the main thread
                box["exc"] = exc
            finally:
                finished.set()

        threading.Thread(target=body, name="amb-dask", daemon=True).start()
        try:
            while not finished.wait(0.1):
                pass
        except Interrupted:
            _kill_local(None)
            raise
        if "exc" in box:
            raise box["exc"]

    def _dask_body(self, todo: list[int], results: list, done: int) -> None:
        from distributed import Client, as_completed

        cluster = None
        try:
            if self.scheduler:
                try:
                    client = Client(self.scheduler, timeout=CONNECT_TIMEOUT_S, set_as_default=False)
                except (OSError, TimeoutError) as exc:
                    raise InputError(f"cannot reach the Dask scheduler {self.scheduler}: {exc}") from None
            else:
                cluster = local_cluster(min(self.workers, len(todo)))
                client = Client(cluster, set_as_default=False)
        except OSError as exc:
            _kill_local(cluster)
            raise InputError(f"cannot start a local Dask cluster: {exc}") from None
        ok = False
        t_ready = time.perf_counter()
        try:
            futures = {client.submit(self.fn, *self.chunks[i], pure=False): i for i in todo}
            for fut in as_completed(futures, loop=client.loop):
                i = futures[fut]
                results[i] = fut.result()
                self._store(i, results[i])
                done += 1
                self._report(done)
            ok = True
            self.compute_seconds = time.perf_counter() - t_ready  # without the cluster's start-up
        finally:
            if not ok:  # interrupted or failed: kill the local workers at once, do not wait for them
                _kill_local(cluster)
            with contextlib.suppress(Exception):
                client.close(timeout=0.5 if not ok else 5)
            if cluster is not None:
                with contextlib.suppress(Exception):
                    cluster.close(timeout=0.5 if not ok else 5)


def local_cluster(n_workers: int):
    """A ``LocalCluster`` of ``n_workers`` processes, one thread and one BLAS thread each, on 127.0.0.1, no
    dashboard, the chart kernels imported as each worker starts (cluster start-up, not compute)."""
    import dask
    from distributed import LocalCluster

    # the nanny's environment for each worker: one BLAS thread, and not Dask's default
    # MALLOC_TRIM_THRESHOLD_=65536, which made the chart kernel's 4-16 MB temporaries 2-3x slower here
    with dask.config.set({"distributed.nanny.pre-spawn-environ": dict(BLAS_ENV)}):
        return LocalCluster(
            n_workers=n_workers,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address=None,
            env=dict(BLAS_ENV),
            silence_logs=40,
            preload=[PRELOAD],
        )


def _kill_local(cluster) -> None:
    """SIGKILL this process's worker processes at once (closing a cluster politely takes seconds, and a cluster
    interrupted while it starts has no handle yet): every child process of this process, by pid."""
    import psutil

    for child in psutil.Process().children(recursive=True):
        with contextlib.suppress(psutil.Error):
            if "resource_tracker" not in " ".join(child.cmdline()):  # exits with this process by itself
                child.kill()
