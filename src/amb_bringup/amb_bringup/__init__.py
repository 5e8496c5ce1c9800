"""amb-rig: starts the nodes as separate processes (no launch system) and summarises a run."""

from amb_dynamics.threads import limit_blas_threads

limit_blas_threads()  # an entry-point package: one BLAS thread, set before its modules load numpy
