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


def forcing_regressors(forcing: str | int | np.ndarray, pairs: int) -> np.ndarray:
    """Sequences over the pair index j spanning the forcing term d_j, shape (k, pairs).

    'none': no forcing (f = 0, e.g. roll); 'constant': d; 'alternating': (-1)^j d (pitch and yaw, where
    f(t + T) = -f(t) with T = pi/omega the period of A(t)); an int r: any d that repeats every r periods; an
    array (k, >= pairs): the sequences themselves (their first ``pairs`` entries), e.g. a base-forcing model
    stacked with the synchronous (spin-harmonic) sequences of :func:`synchronous_regressors`.
    """
    if isinstance(forcing, np.ndarray):
        if forcing.ndim != 2 or forcing.shape[1] < pairs or not np.isfinite(forcing).all():
            raise InputError(f"forcing sequences of shape {forcing.shape} do not cover {pairs} pairs")
        return forcing[:, :pairs]
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


def synchronous_regressors(angles: np.ndarray, harmonics: int, drift: bool) -> np.ndarray:
    """Sequences over the columns spanning a response synchronous with the spin, shape (2 h (1 + 2 drift), cols).

    angles : (cols,) spin angle (rad) at the start of each column.  At constant spin speed the response to
    unbalance and runout (forcing e^{i h phi(t)}) of a T-periodic loop is e^{i h phi(t)} p(t) with p T-periodic,
    so column j carries Re(c_h e^{i h phi_j}): cos and sin of h phi_j per harmonic h span it exactly.  With
    ``drift`` (the speed changes within the window) each harmonic also gets u_j and u_j^2 times them, u_j =
    (j - mean j) / cols: an amplitude and phase that change over the window to second order (a run-up, where the
    response follows the speed through its frequency dependence; first order alone left a false alarm on the
    real rig approaching its 166 rad/s mode at 50 rpm/s).
    """
    angles = np.asarray(angles, dtype=float)
    rows = []
    jc = (np.arange(angles.size) - 0.5 * (angles.size - 1)) / max(angles.size, 1)
    for h in range(1, harmonics + 1):
        c, s = np.cos(h * angles), np.sin(h * angles)
        rows += [c, s]
        if drift:
            rows += [jc * c, jc * s, jc * jc * c, jc * jc * s]
    return np.array(rows).reshape(len(rows), angles.size)


def forcing_basis(forcing: str | int | np.ndarray, pairs: int) -> np.ndarray:
    """The forcing sequences over ``pairs`` pairs; given sequences as an orthonormal basis of their span (rows
    whose RMS is below 1e-9 of their largest entry, e.g. sin of whole turns, are round-off and dropped)."""
    E = forcing_regressors(forcing, pairs)
    if not isinstance(forcing, np.ndarray) or E.shape[0] == 0:
        return E
    rms = np.sqrt(np.mean(E * E, axis=1))
    E = E[rms > 1e-9 * max(float(np.abs(E).max()), 1e-300)]
    if E.shape[0] == 0:
        return np.zeros((0, pairs))
    return sla.orth((E / np.linalg.norm(E, axis=1, keepdims=True)).T, rcond=1e-8).T


def forcing_rank(forcing: str | int | np.ndarray, pairs: int) -> int:
    """Independent forcing sequences over ``pairs`` pairs (each costs one pair of the fit)."""
    return forcing_basis(forcing, pairs).shape[0]


def forcing_complement(pairs: int, forcing: str | int | np.ndarray) -> np.ndarray:
    """Orthonormal basis (pairs, pairs - k) of the sequences orthogonal to the forcing regressors."""
    if isinstance(forcing, np.ndarray):
        E = forcing_basis(forcing, pairs)
        return np.eye(pairs) if E.shape[0] == 0 else sla.null_space(E)
    return _named_complement(pairs, forcing)


@lru_cache(maxsize=64)
def _named_complement(pairs: int, forcing: str | int) -> np.ndarray:
    E = forcing_regressors(forcing, pairs)
    return np.eye(pairs) if E.shape[0] == 0 else sla.null_space(E)
