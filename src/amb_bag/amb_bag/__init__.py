"""MCAP recorder (rosbag2 layout), player, info, check and plot."""

from amb_dynamics.threads import limit_blas_threads

limit_blas_threads()  # an entry-point package: one BLAS thread, set before its modules load numpy
