"""Floquet multipliers identified from data: the one-period map of period-stacked snapshots (issue 6).

A linear T-periodic loop sampled at phases t_i = t0 + i T/P of every period j gives, per phase, snapshots
that are a sum of geometric sequences in j plus the forced periodic response:

    s_j(i) = sum_l c_l mu_l^j v_l(i) + p_{j mod r}(i),        mu_l = Floquet multipliers (one period T)

where r is the number of periods after which the forcing repeats (pitch and yaw: the base motion repeats
after 2 periods of A(t), and f(t + T) = -f(t)).  Stacking the P phase vectors of one period into a column
z_j (``StreamingEstimator`` does it) gives z_{j+1} = A z_j + d_{j mod r} with the eigenvalues of A the
multipliers of the modes present in the data.  ``fit_period_map`` identifies A on the dominant subspace:

1. project the columns on the complement of the r forcing classes (removes d exactly; Frisch-Waugh);
2. SVD of the regressor; keep the directions above max(numerical floor, measurement-noise floor, and for noisy
   data the plateau floor of process-noise innovations, :func:`plateau_floor`): this is the rank / energy
   test, and a zero rank means *insufficient excitation* (no transient above noise: a decayed noise-free rotor
   carries no information about its multipliers);
3. exact DMD (least squares, optionally total least squares for measurement noise) in that subspace;
4. eigenvalues -> multipliers, and a first-order standard error of rho = max|mu| from the LS residual
   covariance and the eigenvalue's left/right eigenvectors;
5. optionally ('opt', the monitor's default) the multipliers refined by variable projection on the snapshots
   themselves, with the standard error from its Jacobian (:mod:`amb_dynamics.estimator.refine`).

``InstabilityFlag`` turns the estimates into a verdict with a margin, a confidence gate and hysteresis.
Noise-free data of a linear loop are fitted exactly: the dominant multipliers come out to round-off.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla

from ..errors import InputError
from .mapfit import (
    COLLECTING,
    INSUFFICIENT,
    MARGINAL,
    STABLE,
    TOO_FEW,
    UNSTABLE,
    MapFit,
    forcing_complement,
    forcing_rank,
)
from .refine import refine_fit

REL_FLOOR = 1e-9  # singular values below this fraction of the data norm are round-off, not signal
NOISE_FACTOR = 1.5  # noise floor = this times the expected largest singular value of the noise matrix
PLATEAU_FACTOR = 1.5  # the same safety on the top of the innovation plateau (plateau_floor)
MIN_SNR = 2.0  # a transient whose largest singular value is under this times the floor identifies no map
# Noisy data: a direction is signal only this far above the floor.  The floor is the expected top of the noise
# spectrum; its top singular values scatter around it, and the more pairs a window has the more of them cross it.
# A crossing direction is a mode fitted to a few columns' innovations: with 32 pairs of the real rig's
# displacements it gave rho 1.5-2.6 at a stable point (docs/monitor.md#window).
KEEP_FACTOR = 1.3
METHODS = ("ls", "tls", "opt")


def noise_floor(row_noise: np.ndarray | None, rows: int, cols: int, data_norm: float) -> float:
    """Largest singular value that noise (or round-off) alone would give an (rows x cols) matrix.

    row_noise : (rows,) noise std per row in the units of the data, or None (noise-free: round-off only).
    For independent noise of std v_i in row i the largest singular value is about sqrt(sum v_i^2) +
    sqrt(cols max v_i^2) (the Marchenko-Pastur edge for equal v_i), times the safety ``NOISE_FACTOR``.
    """
    floor = REL_FLOOR * data_norm
    if row_noise is not None:
        v2 = np.square(np.broadcast_to(np.asarray(row_noise, dtype=float), (rows,)))
        floor = max(floor, NOISE_FACTOR * (np.sqrt(v2.sum()) + np.sqrt(cols * v2.max())))
    return float(floor)


def plateau_floor(s: np.ndarray, rows: int) -> float:
    """Largest singular value of a noise matrix whose smallest one is s[-1], for a (rows x len(s)) regressor.

    Process noise (excitation injection, plant noise) gives every period an innovation that the one-period map
    does not predict: in the period-stacked data it acts like noise whose level the measurement-noise floor does
    not know, and its singular values form a plateau under the transient's.  With more rows than pairs the
    smallest singular value is on that plateau, and a noise matrix's singular values span about
    sigma (sqrt(rows) -+ sqrt(k)) (Marchenko-Pastur): the top of the plateau is s_min (sqrt(rows) + sqrt(k)) /
    (sqrt(rows) - sqrt(k)), times ``PLATEAU_FACTOR``.  Under white measurement noise alone this is the
    measurement-noise floor again (sigma from the data instead of the fourth differences); for exact data it
    is round-off; with no more rows than pairs it is not defined (0).  Only for noisy data (``fit_period_map``
    with ``row_noise``): with fewer pairs than modes the smallest singular value is still signal, which exact
    data must keep.
    """
    k = s.size
    if k < 2 or rows <= k:
        return 0.0
    return float(PLATEAU_FACTOR * s[-1] * (np.sqrt(rows) + np.sqrt(k)) / (np.sqrt(rows) - np.sqrt(k)))


def fit_period_map(
    Z: np.ndarray,
    forcing: str | int = "constant",
    row_noise: np.ndarray | float | None = None,
    method: str = "ls",
    max_rank: int = 12,
    min_dof: int = 1,
) -> MapFit:
    """Identify z_{j+1} = A z_j + d_{j mod r} on the dominant subspace and return A's eigenvalues.

    Parameters
    ----------
    Z : np.ndarray, shape (m, J+1)
        Column j = stacked snapshots of period j (rows scaled to comparable units).
    forcing : str, int or array
        Model of the forcing term d_j: 'none', 'constant', 'alternating' (pitch, yaw), a repeat count r, or
        the sequences themselves (k, >= J) (see :func:`.mapfit.forcing_regressors`); each independent sequence
        costs one snapshot pair.
    row_noise : (m,) array, float or None
        Measurement-noise std per row in the units of Z (None: noise-free, round-off floor only).
    method : 'ls', 'tls' or 'opt'
        Least squares (consistent under process noise), total least squares (debiased for measurement
        noise, Hemati et al. 2017: both snapshot sets projected on the leading right singular vectors), or
        'opt': the LS fit refined by variable projection (optimized DMD, :mod:`amb_dynamics.estimator.refine`:
        maximum likelihood for white noise on the snapshots, which the excitation's fast response is).
    max_rank : int
        Largest number of modes modelled.
    min_dof : int
        Pairs that must remain after the forcing classes and the rank (>= 1 for a residual).
    """
    Z = np.asarray(Z, dtype=float)
    if Z.ndim != 2 or not np.isfinite(Z).all():
        raise InputError("snapshot matrix must be a finite 2-D array")
    if method not in METHODS:
        raise InputError(f"unknown estimation method '{method}' (ls, tls or opt)")
    base = "ls" if method == "opt" else method
    if max_rank < 1 or min_dof < 1:
        raise InputError("max_rank and min_dof must be >= 1")
    m, cols = Z.shape
    pairs = cols - 1
    empty = np.zeros(0, dtype=complex)
    if pairs < 1:
        return MapFit(empty, np.inf, np.zeros(0), np.nan, pairs, 0, 0, 0, method, TOO_FEW)
    free = pairs - forcing_rank(forcing, pairs)  # pairs left once the forcing is removed
    if free < 1 + min_dof:
        return MapFit(empty, np.inf, np.zeros(0), np.nan, pairs, 0, 0, 0, method, TOO_FEW)
    Q = forcing_complement(pairs, forcing)
    Xm, Xp = Z[:, :-1] @ Q, Z[:, 1:] @ Q
    U, s, Vh = np.linalg.svd(Xm, full_matrices=False)
    # the round-off floor is REL_FLOOR ||Z||_2; the Frobenius norm bounds ||Z||_2 from above, so where the noise
    # floor is well above REL_FLOOR ||Z||_F the 2-norm (an SVD of Z per refit) cannot change the result
    frobenius = float(np.linalg.norm(Z))
    floor = noise_floor(row_noise, m, free, frobenius)
    if floor <= 2.0 * REL_FLOOR * frobenius:
        floor = noise_floor(row_noise, m, free, float(np.linalg.norm(Z, 2)))
    if row_noise is not None:  # noisy data: the innovations of process noise are noise too
        floor = max(floor, plateau_floor(s, m))
    signal_rank = int(np.count_nonzero(s > (floor if row_noise is None else KEEP_FACTOR * floor)))
    rank = min(signal_rank, max_rank, free - min_dof)
    if signal_rank == 0:
        return MapFit(empty, np.inf, s, floor, pairs, 0, 0, 0, method, "no transient above the noise floor")
    if row_noise is not None and s[0] < MIN_SNR * floor:
        return MapFit(empty, np.inf, s, floor, pairs, signal_rank, 0, 0, method,
                      f"transient {s[0] / floor:.3g} x the noise floor (under {MIN_SNR:g})")  # fmt: skip
    Xm0, Xp0 = Xm, Xp
    if base == "tls":
        _, _, Wh = np.linalg.svd(np.vstack([Xm, Xp]), full_matrices=False)
        Pv = Wh[:rank].T @ Wh[:rank]
        Xm, Xp = Xm @ Pv, Xp @ Pv
        U, s_t, Vh = np.linalg.svd(Xm, full_matrices=False)
    else:
        s_t = s
    Ur, sr, Vr = U[:, :rank], s_t[:rank], Vh[:rank].T
    A = (Ur.T @ Xp @ Vr) / sr  # DMD operator: U^T Xp V S^-1
    mu, vl, vr = sla.eig(A, left=True, right=True)
    order = np.lexsort((-mu.imag, -np.abs(mu)))
    mu = mu[order]
    # the residual of the un-projected data in the subspace (TLS makes the projected residual zero)
    std = _rho_std(A, Ur.T @ Xm0, Ur.T @ Xp0, vl[:, order[0]], vr[:, order[0]], mu[0], free - rank)
    fit = MapFit(mu, std, s, floor, pairs, signal_rank, rank, free - rank, method)
    if method == "opt":
        return refine_fit(Z, fit, forcing)
    return fit


def _rho_std(A, Xr, Yr, wl, vr, mu0, dof) -> float:
    """First-order standard error of |mu0| from the least-squares covariance of A (rows independent).

    Xr, Yr : (rank, pairs) data in the subspace.  Cov(A_ab, A_cd) = Se_ac G_bd with Se the residual
    covariance of Yr - A Xr and G = (Xr Xr^T)^-1; d mu = wl^H dA vr / (wl^H vr) and
    d|mu| = Re(conj(mu) d mu) / |mu|.
    """
    if dof < 1:
        return float("inf")
    E = Yr - A @ Xr
    Se = E @ E.T / dof
    try:
        G = np.linalg.inv(Xr @ Xr.T)
    except np.linalg.LinAlgError:
        return float("inf")
    denom = np.vdot(wl, vr)
    if abs(denom) < 1e-14 * np.linalg.norm(wl) * np.linalg.norm(vr) or abs(mu0) == 0:
        return float("inf")
    dmu = np.outer(wl.conj(), vr) / denom  # d mu / d A_ab
    g = np.real(np.conj(mu0) * dmu) / abs(mu0)
    var = float(np.sum((Se @ g @ G) * g))
    return float(np.sqrt(max(var, 0.0)))


# ---- verdict with margin, confidence gate and hysteresis ------------------------------------------------------
@dataclass(frozen=True)
class VerdictPolicy:
    """When the unstable flag is raised and cleared.

    Raise after ``confirm`` consecutive estimates with rho >= 1 + margin and rho - z*std > 1 (with
    ``require_resolved``, only fits that model every significant direction count: safer, but the Monte Carlo
    of benchmarks/bench_monitor.py detects 1-3 periods later and shows no false alarm without it); clear after
    ``confirm`` consecutive estimates with rho + z*std < 1 + margin - hysteresis.
    """

    margin: float = 0.02
    hysteresis: float = 0.02
    z: float = 3.0
    confirm: int = 2
    require_resolved: bool = False

    def __post_init__(self):
        if not (self.margin >= 0 and self.hysteresis >= 0 and self.z >= 0 and self.confirm >= 1):
            raise InputError("verdict policy: margin, hysteresis, z must be >= 0 and confirm >= 1")


@dataclass
class InstabilityFlag:
    """Latched instability verdict driven by successive ``MapFit`` results."""

    policy: VerdictPolicy = field(default_factory=VerdictPolicy)
    unstable: bool = False
    _up: int = 0
    _down: int = 0

    def update(self, fit: MapFit) -> str:
        """Feed one estimate; returns the verdict (stable, marginal, unstable, insufficient_excitation)."""
        p = self.policy
        if not fit.excited:
            self._up = self._down = 0
            if self.unstable:
                return UNSTABLE
            return COLLECTING if fit.reason == TOO_FEW else INSUFFICIENT
        rho, sd = fit.rho, fit.rho_std
        lo, hi = rho - p.z * sd, rho + p.z * sd
        if not self.unstable:
            raise_ok = (fit.resolved or not p.require_resolved) and rho >= 1.0 + p.margin and lo > 1.0
            self._up = self._up + 1 if raise_ok else 0
            if self._up >= p.confirm:
                self.unstable, self._up = True, 0
        else:
            self._down = self._down + 1 if hi < 1.0 + p.margin - p.hysteresis else 0
            if self._down >= p.confirm:
                self.unstable, self._down = False, 0
        if self.unstable:
            return UNSTABLE
        return STABLE if hi < 1.0 else MARGINAL

    def confidence(self, fit: MapFit) -> float:
        """Probability (normal approximation) that rho is on the side of 1 where the estimate is."""
        if not fit.excited or not np.isfinite(fit.rho_std):
            return 0.0
        if fit.rho_std == 0.0:
            return 1.0
        return float(0.5 * (1.0 + math.erf(abs(fit.rho - 1.0) / (fit.rho_std * math.sqrt(2.0)))))
