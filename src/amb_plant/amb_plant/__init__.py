"""Node: flexible rotor on AMBs (sampled-data propagator of amb_dynamics); /clock master in lockstep."""

from amb_dynamics.threads import limit_blas_threads

limit_blas_threads()  # an entry-point package: one BLAS thread, set before its modules load numpy
