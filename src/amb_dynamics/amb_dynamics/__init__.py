"""ROS-free numerical core of amb-rig: FE rotor on AMBs on a moving base, Floquet, Newmark, digital loop."""

import os as _os

# The core works on many small matrices (tens of states): BLAS threads only add overhead and, in the parallel
# chart workers and the node processes sharing this machine's cores, oversubscribe it (measured 25x slower).
# Set before numpy is imported by this package; an explicit user setting wins.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    _os.environ.setdefault(_var, "1")
