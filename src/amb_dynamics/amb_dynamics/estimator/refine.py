"""Optimized DMD: the multipliers of a one-period-map fit refined by variable projection (issue 6).

The least-squares DMD of :func:`amb_dynamics.estimator.fit.fit_period_map` treats the regressor columns as exact.  In
the period-stacked data of a rotor with excitation injection they are not: every column also carries the
response of the fast modes to that period's excitation, which is not predicted by the previous column and is
close to white, equal-variance noise on the rows (measured on the seed rotor: flat covariance spectrum).  Noise in
the regressor biases the LS multipliers towards zero (attenuation), most for a weakly excited growing mode.

With the rank found by the DMD, the snapshots are modelled directly as a sum of geometric sequences plus the
forcing (Askham & Kutz 2018, "optimized DMD"):

    Z ~ M V(mu) + D E,        V_lj = mu_l^j (as real rows Re, Im for a conjugate pair),  E = forcing regressors

and ||Z - M V - D E||_F is minimised over mu with M, D eliminated by linear least squares (variable projection,
Golub & Pereyra, Levenberg-Marquardt from the DMD multipliers).  For white noise on Z this is the maximum-
likelihood estimate; the covariance of mu is sigma^2 (J^T J)^-1 with sigma^2 from the residual, which gives
the standard error of rho.  The refinement is kept only if it lowers the residual and stays finite.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from .mapfit import MapFit, forcing_basis

MAX_ITER = 8
REAL_TOL = 1e-9  # |Im mu| below this times |mu|: a real multiplier
EXACT = 1e-24  # relative squared residual of exact data: nothing to refine
SPARE = 4  # the refinement needs n >= 2 q + SPARE columns for q modelled sequences (modes and forcing)
MU_LIMIT = 10.0  # a refined |mu| beyond this times the DMD's largest (or beyond 1e3) is a failed fit
COND_LIMIT = 8.0  # condition number of the unit-norm sequences [V; E]: above, modes and forcing are not told apart


def _split(mu: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """Conjugate pairs (one of each, Im > 0) and real multipliers of a real map; None if unpaired."""
    tol = REAL_TOL * np.maximum(np.abs(mu), 1e-300)
    real = mu[np.abs(mu.imag) <= tol].real
    upper = mu[mu.imag > tol]
    if upper.size != np.count_nonzero(mu.imag < -tol):
        return None
    return upper, real


def _basis(upper: np.ndarray, real: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Rows of V (q, n) and their derivatives dV (npar, q, n) w.r.t. (Re, Im) of each pair and each real mu."""
    j = np.arange(n)
    npair, nreal = upper.size, real.size
    q = 2 * npair + nreal
    V = np.empty((q, n))
    dV = np.zeros((q, q, n))
    # a Marquardt trial step may overshoot to |mu| >> 1: mu^j overflows, and evaluate() rejects the trial
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        for k, mu in enumerate(upper):
            pw = mu**j
            dp = np.where(j > 0, j * mu ** np.maximum(j - 1, 0), 0.0)  # d mu^j / d mu
            V[2 * k], V[2 * k + 1] = pw.real, pw.imag
            dV[2 * k, 2 * k], dV[2 * k, 2 * k + 1] = dp.real, dp.imag  # d/d Re(mu)
            dV[2 * k + 1, 2 * k], dV[2 * k + 1, 2 * k + 1] = -dp.imag, dp.real  # d/d Im(mu) = i d/d mu
        for k, mu in enumerate(real):
            i = 2 * npair + k
            V[i] = mu**j
            dV[i, i] = np.where(j > 0, j * mu ** np.maximum(j - 1, 0), 0.0)
    return V, dV


class _Problem:
    """Variable-projection residual and Jacobian of ||Y - C W|| over the multipliers (W = [V; E])."""

    def __init__(self, Y: np.ndarray, E: np.ndarray, npair: int):
        self.Y, self.E, self.npair = Y, E, npair
        self.n = Y.shape[1]

    def params(self, upper, real):
        return np.concatenate([np.column_stack([upper.real, upper.imag]).ravel(), real])

    def unpack(self, p):
        k = self.npair
        return p[0 : 2 * k : 2] + 1j * p[1 : 2 * k : 2], p[2 * k :]

    def evaluate(self, p, jacobian=True):
        upper, real = self.unpack(p)
        V, dV = _basis(upper, real, self.n)
        W = np.vstack([V, self.E])
        if not np.isfinite(W).all():
            return None
        Wp = np.linalg.pinv(W)  # (n, q + f)
        C = self.Y @ Wp
        R = self.Y - C @ W
        if not jacobian:
            return R, None
        Pp = np.eye(self.n) - Wp @ W
        f = self.E.shape[0]
        dW = np.concatenate([dV, np.zeros((dV.shape[0], f, self.n))], axis=1) if f else dV
        # d R = -R dW^T Wp^T - C dW Pp (Golub-Pereyra, full form)
        J = -(R @ np.transpose(dW, (0, 2, 1)) @ Wp.T + C @ dW @ Pp)
        return R, J.reshape(J.shape[0], -1).T


def refine_fit(Z: np.ndarray, fit: MapFit, forcing: str | int | np.ndarray) -> MapFit:
    """Refine ``fit`` (a DMD fit of the snapshot columns Z (m, J+1)) by variable projection; see module doc.

    Returns a MapFit with the refined multipliers, the standard error of rho from the Jacobian, and method
    'opt'; the DMD fit (method relabelled) when there is nothing to refine or the refinement fails.
    """
    kept = replace(fit, method="opt")
    if not fit.excited:
        return kept
    split = _split(fit.multipliers)
    if split is None:
        return kept
    upper, real = split
    m, n = Z.shape
    E = forcing_basis(forcing, n)
    q = 2 * upper.size + real.size + E.shape[0]
    npar = 2 * upper.size + real.size
    dof = m * (n - q) - npar
    if n - q < q + SPARE or dof < 1:
        return kept  # a short record: exponentials and forcing sequences too alike to tell apart
    _, s, Wt = np.linalg.svd(Z, full_matrices=False)
    prob = _Problem(s[:, None] * Wt, E, upper.size)  # ||Z P|| = ||S W^T P||: the same problem, k <= n rows
    p = prob.params(upper, real)
    out = prob.evaluate(p)
    if out is None:
        return kept
    R, J = out
    cost = float(np.sum(R * R))
    scale = float(np.sum(s * s))
    if cost <= EXACT * scale:
        return kept  # exact data: the DMD is the answer
    lam = 1e-3  # Marquardt: relative to diag(J^T J); Gauss-Newton from the DMD start converges in a few steps
    for _ in range(MAX_ITER):
        r = R.ravel()
        H = J.T @ J
        g = J.T @ r
        try:
            step = np.linalg.solve(H + lam * np.diag(np.diag(H) + 1e-300), -g)
        except np.linalg.LinAlgError:
            break
        trial = prob.evaluate(p + step)
        new_cost = np.inf if trial is None else float(np.sum(trial[0] * trial[0]))
        if new_cost < cost:
            done = cost - new_cost <= 1e-10 * cost
            p, (R, J), cost, lam = p + step, trial, new_cost, lam / 3.0
            if done:
                break
        else:
            lam *= 4.0
    upper, real = prob.unpack(p)
    mu = np.concatenate([upper, upper.conj(), real.astype(complex)])
    order = np.lexsort((-mu.imag, -np.abs(mu)))
    mu = mu[order]
    limit = min(1e3, MU_LIMIT * max(abs(fit.multipliers[0]), 1.0))
    if not np.isfinite(mu).all() or abs(mu[0]) > limit or _condition(prob, p) > COND_LIMIT:
        return kept
    return replace(kept, multipliers=mu, rho_std=_rho_std(p, J, cost / dof, mu[0], upper, real))


def _condition(prob: _Problem, p: np.ndarray) -> float:
    """Condition number of the fitted sequences (rows of [V; E] scaled to unit norm)."""
    upper, real = prob.unpack(p)
    W = np.vstack([_basis(upper, real, prob.n)[0], prob.E])
    norms = np.linalg.norm(W, axis=1, keepdims=True)
    if not (norms > 0).all():
        return float("inf")  # a vanished sequence (e.g. a pair that became real): not identified
    W = W / norms
    sv = np.linalg.svd(W, compute_uv=False)
    return float(sv[0] / sv[-1]) if sv[-1] > 0 else float("inf")


def _rho_std(p, J, sigma2, top, upper, real) -> float:
    """Standard error of |top| from Cov(p) = sigma^2 (J^T J)^-1 (first order)."""
    try:
        cov = sigma2 * np.linalg.inv(J.T @ J)
    except np.linalg.LinAlgError:
        return float("inf")
    g = np.zeros(p.size)
    if abs(top.imag) > 0 and upper.size:
        k = int(np.argmin(np.abs(upper - (top if top.imag > 0 else top.conj()))))
        g[2 * k : 2 * k + 2] = np.array([top.real, abs(top.imag)]) / abs(top)
    else:
        k = int(np.argmin(np.abs(real - top.real)))
        g[2 * upper.size + k] = np.sign(top.real)
    var = float(g @ cov @ g)
    return float(np.sqrt(var)) if np.isfinite(var) and var >= 0 else float("inf")
