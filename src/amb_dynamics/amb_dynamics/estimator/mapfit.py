"""The result of one identification of the one-period map, the verdict names and the forcing regressors.

Shared by :mod:`amb_dynamics.estimator.fit` (the DMD fit) and :mod:`amb_dynamics.estimator.refine` (its
variable-projection refinement), so that neither imports the other's caller.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import scipy.linalg as sla

from ..errors import InputError

STABLE, UNSTABLE, MARGINAL = "stable", "unstable", "marginal"
INSUFFICIENT, COLLECTING = "insufficient_excitation", "collecting"  # no information / too few periods yet
TOO_FEW = "too few periods"


@dataclass(frozen=True)
class MapFit:
    """Result of one identification of the one-period map.

    multipliers : (rank,) complex, sorted by decreasing modulus (empty if not excited).
    rho_std : float, first-order standard error of rho (inf if it cannot be estimated).
    singular_values : (k,) of the regressor after removing the forcing (scaled data units).
    noise_floor : float, singular values below it are treated as noise / round-off.
    pairs : int, snapshot pairs (periods) in the fit; dof : int, pairs left after forcing and rank.
    signal_rank : int, significant directions found; rank : int, directions modelled (<= signal_rank).
    """

    multipliers: np.ndarray
    rho_std: float
    singular_values: np.ndarray
    noise_floor: float
    pairs: int
    signal_rank: int
    rank: int
    dof: int
    method: str
    reason: str = ""  # why the data are insufficient ('' if excited)

    @property
    def excited(self) -> bool:
        return self.rank > 0 and not self.reason

    @property
    def rho(self) -> float:
        return float(np.abs(self.multipliers[0])) if self.multipliers.size else float("nan")

    @property
    def resolved(self) -> bool:
        """Every significant direction of the data is in the model (else the window is too short)."""
        return self.excited and self.rank == self.signal_rank

    @property
    def snr(self) -> float:
        """Largest singular value over the noise floor (> 1 means some transient is visible)."""
        return float(self.singular_values[0] / self.noise_floor) if self.singular_values.size else 0.0

    def to_dict(self, top: int | None = None) -> dict:
        mu = self.multipliers if top is None else self.multipliers[:top]
        return {
            "multipliers": [[float(z.real), float(z.imag)] for z in mu],
            "rho": self.rho if self.excited else None,
            "rho_std": self.rho_std if self.excited and np.isfinite(self.rho_std) else None,
            "rank": self.rank,
            "signal_rank": self.signal_rank,
            "pairs": self.pairs,
            "dof": self.dof,
            "snr": self.snr,
            "method": self.method,
            "excited": self.excited,
            "reason": self.reason,
        }


FORCING_KINDS = ("none", "constant", "alternating")


def forcing_regressors(forcing: str | int, pairs: int) -> np.ndarray:
    """Sequences over the pair index j spanning the forcing term d_j, shape (k, pairs).

    'none': no forcing (f = 0, e.g. roll); 'constant': d; 'alternating': (-1)^j d (pitch and yaw, where
    f(t + T) = -f(t) with T = pi/omega the period of A(t)); an int r: any d that repeats every r periods.
    """
    j = np.arange(pairs)
    if forcing == "none":
        return np.zeros((0, pairs))
    if forcing == "constant":
        return np.ones((1, pairs))
    if forcing == "alternating":
        return np.where(j % 2 == 0, 1.0, -1.0)[None, :]
    if isinstance(forcing, int | np.integer) and not isinstance(forcing, bool) and forcing >= 1:
        E = np.zeros((int(forcing), pairs))
        E[j % forcing, j] = 1.0
        return E
    raise InputError(f"unknown forcing model {forcing!r} (none, constant, alternating or a period count >= 1)")


@lru_cache(maxsize=64)
def forcing_complement(pairs: int, forcing: str | int) -> np.ndarray:
    """Orthonormal basis (pairs, pairs - k) of the sequences orthogonal to the forcing regressors."""
    E = forcing_regressors(forcing, pairs)
    return np.eye(pairs) if E.shape[0] == 0 else sla.null_space(E)
