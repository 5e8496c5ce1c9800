"""Matrix exponential of a stack of matrices at once (scaling and squaring of a degree-16 Taylor polynomial).

scipy.linalg.expm accepts stacks but works matrix by matrix in Python; the Floquet kernels exponentiate hundreds
of same-size, similar-norm matrices, so one scaling for the whole stack (from the largest 1-norm) keeps every
matrix within the approximant's backward-error bound and lets numpy batch the products.

Why Taylor and not Higham's (2005) Pade 13: on stacks of small matrices (the charts' 56 states) a batched LU solve
costs about ten batched matrix products, so the Pade's one solve outweighs the three extra squarings a Taylor
polynomial needs for the same accuracy.  The degree-16 polynomial is evaluated by Paterson-Stockmeyer in six
products (A^2, A^3, A^4 and three Horner steps in A^4), its four coefficient blocks by one matrix product of the
coefficients with the stacked powers.  ``THETA_16`` is the largest 1-norm for which the relative backward error
of the truncated series is below 2^-53 (the bound of Al-Mohy and Higham, SIAM J. Sci. Comput. 2011, from the
absolute values of the series of log(e^-x T_16(x)); tests recompute it with exact rational arithmetic).  The
stack is taken in blocks of ``BLOCK`` matrices (each with its own scaling): a block's temporaries stay in the
core's cache.
"""

from __future__ import annotations

from math import factorial

import numpy as np
import scipy.linalg as sla

BLOCK = 16  # matrices per block
DEGREE = 16
THETA_16 = 0.7802874256626574  # ||2^-s X||_1 <= theta_16 -> relative backward error of T_16 < 2^-53
TAYLOR = np.array([1.0 / factorial(k) for k in range(DEGREE + 1)])
BLOCKS = TAYLOR[:DEGREE].reshape(4, 4)  # Paterson-Stockmeyer: B_j = sum_i BLOCKS[j, i] A^i, j = 0..3


def expm_stack(X: np.ndarray) -> np.ndarray:
    """expm of every matrix of X, shape (..., d, d)."""
    X = np.asarray(X, dtype=float)
    if X.ndim == 2:
        return _expm_block(X[None])[0]
    flat = X.reshape(-1, *X.shape[-2:])
    out = np.empty_like(flat)
    for b in range(0, flat.shape[0], BLOCK):
        out[b : b + BLOCK] = _expm_block(flat[b : b + BLOCK])
    return out.reshape(X.shape)


def squarings(norm: float) -> int:
    """Number s of squarings with ||2^-s X||_1 <= THETA_16."""
    return max(0, int(np.ceil(np.log2(norm / THETA_16)))) if norm > THETA_16 else 0


def _expm_block(X: np.ndarray) -> np.ndarray:
    """expm of every matrix of a stack (n, d, d), one scaling for all (from the largest 1-norm)."""
    n, d, _ = X.shape
    s = squarings(float(np.abs(X).sum(axis=-2).max()) if X.size else 0.0)
    A = X * 2.0**-s if s else X
    A2 = A @ A
    A4 = A2 @ A2
    B = (BLOCKS[:, 1:] @ np.stack([A, A2, A2 @ A]).reshape(3, -1)).reshape(4, n, d, d)
    B.reshape(4, n, d * d)[..., :: d + 1] += BLOCKS[:, :1, None]  # the identity terms, on the diagonals
    R = B[3] + TAYLOR[DEGREE] * A4
    for j in (2, 1, 0):  # Horner in A^4
        R = A4 @ R
        R += B[j]
    for _ in range(s):
        R = R @ R
    return R


def balancing_scale(A: np.ndarray) -> np.ndarray:
    """Diagonal similarity D (as a vector) with D^-1 A D balanced.

    In [q; q'] coordinates the stiffness block M^-1 K is ~1e9 while the eigenvalues are ~1e4: scaling the 1-norm
    of such a matrix would square far too often and lose accuracy.  Multipliers are invariant under D.
    """
    _, (scale, _) = sla.matrix_balance(A, permute=False, separate=True)
    return scale
