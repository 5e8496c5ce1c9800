"""One BLAS thread per process, set by the entry points (console scripts, nodes, tools, benchmarks).

The core works on many small matrices (tens of states): BLAS threads only add overhead and, with the parallel
chart workers and the node processes sharing the machine's cores, oversubscribe them (measured 25x slower).
OpenBLAS, OpenMP and MKL read their thread count from the environment once, when numpy loads its BLAS, so the
setting has to be in ``os.environ`` before the process first imports numpy; child processes inherit it.  This
module imports neither numpy nor anything that does, so an entry point can call :func:`limit_blas_threads`
first thing, before its own numpy imports.  Importing :mod:`amb_dynamics` itself changes nothing.
"""

from __future__ import annotations

import os
import sys

BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def single_thread_env() -> dict[str, str]:
    """The BLAS thread variables not yet set in ``os.environ``, each mapped to "1" (an explicit setting wins)."""
    return {var: "1" for var in BLAS_THREAD_VARIABLES if var not in os.environ}


def limit_blas_threads() -> bool:
    """Set one BLAS thread for this process and its children unless the user chose a count.

    Returns
    -------
    bool
        True if the setting takes effect in this process (numpy not imported yet); False if numpy was already
        loaded, in which case only child processes get it.
    """
    os.environ.update(single_thread_env())
    return "numpy" not in sys.modules
