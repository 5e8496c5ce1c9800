"""Stability monitor: online Floquet multipliers of the running rig, instability flag, offline re-analysis."""

import os as _os

# The monitor shares the machine's cores with the lockstep loop: one BLAS thread (set before numpy loads).
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    _os.environ.setdefault(_var, "1")
