"""Stability monitor: online Floquet multipliers of the running rig, instability flag, offline re-analysis."""

from amb_dynamics.threads import limit_blas_threads

# The monitor shares the machine's cores with the lockstep loop: one BLAS thread (set before numpy loads).
limit_blas_threads()
