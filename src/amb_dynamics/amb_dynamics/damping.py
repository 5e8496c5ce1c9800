"""Structural damping of the shaft (config ``structural_damping``): a constant viscous matrix on the FE DOFs.

Models (non-rotating viscous damping; the circulatory term that rotating internal damping adds above the
first critical speed is not modelled):

- ``none``: D_s = 0 (the paper's model).
- ``rayleigh``: D_s = alpha M + beta K_shaft, with K_shaft = K_B the shaft's bending stiffness (no bearings).
- ``loss_factor``: every flexural mode r of the free-free shaft (M, K_B) gets the damping ratio eta/2, the
  viscous equivalent of a hysteretic loss factor eta at the mode's own frequency:
  D_s = M Phi diag(eta omega_r) Phi^T M with Phi mass-normalised; the rigid-body modes (omega_r = 0: free
  translation and tilt in both planes) are not damped, so a rigid motion dissipates nothing.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla

RIGID_TOL = 1e-6  # omega_r below RIGID_TOL * max omega_r is a rigid-body mode


def structural_damping_matrix(M: np.ndarray, K_shaft: np.ndarray, sd) -> np.ndarray:
    """D_s (n, n) in N s/m (and N m s/rad) for FE mass M and shaft stiffness K_shaft; ``sd`` the config section."""
    if sd.model == "none":
        return np.zeros_like(M)
    if sd.model == "rayleigh":
        return sd.alpha * M + sd.beta * K_shaft
    w2, Phi = sla.eigh(K_shaft, M)
    omega = np.sqrt(np.clip(w2, 0.0, None))
    omega[omega < RIGID_TOL * omega.max()] = 0.0
    MPhi = M @ Phi
    D = (MPhi * (sd.loss_factor * omega)) @ MPhi.T
    return (D + D.T) / 2
