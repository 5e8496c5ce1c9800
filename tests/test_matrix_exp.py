"""The stacked matrix exponential against scipy's, matrix by matrix (block boundaries, shapes, norms), and its
scaling bound recomputed from the Taylor series in exact rational arithmetic."""

from fractions import Fraction
from math import factorial

import numpy as np
import scipy.linalg as sla

from amb_dynamics.matrix_exp import BLOCK, DEGREE, THETA_16, expm_stack, squarings


def _reference(X: np.ndarray) -> np.ndarray:
    flat = X.reshape(-1, *X.shape[-2:])
    return np.array([sla.expm(m) for m in flat]).reshape(X.shape)


def test_stack_across_blocks_equals_scipy_matrix_by_matrix():
    rng = np.random.default_rng(7)
    n = 2 * BLOCK + 5  # two full blocks and a partial one
    X = rng.standard_normal((n, 12, 12))
    X *= np.geomspace(1e-3, 40.0, n)[:, None, None]  # norms from well below to far above theta_16
    E = expm_stack(X)
    ref = _reference(X)
    rel = np.abs(E - ref).max(axis=(1, 2)) / np.abs(ref).max(axis=(1, 2))
    assert rel.max() < 1e-11, rel.max()


def test_shapes_kept_and_single_matrix():
    rng = np.random.default_rng(8)
    X = 0.5 * rng.standard_normal((3, 7, 6, 6))
    E = expm_stack(X)
    assert E.shape == X.shape
    ref = _reference(X)
    assert np.abs(E - ref).max() < 1e-12 * np.abs(ref).max()
    A = rng.standard_normal((5, 5))
    ref = sla.expm(A)
    assert expm_stack(A).shape == (5, 5)
    assert np.abs(expm_stack(A) - ref).max() < 1e-12 * np.abs(ref).max()


def test_rotation_generator_gives_the_exact_rotation():
    """exp of a skew generator theta*J is the rotation by theta: an analytic value, not scipy's."""
    theta = np.linspace(0.1, 30.0, BLOCK + 3)
    J = np.array([[0.0, -1.0], [1.0, 0.0]])
    E = expm_stack(theta[:, None, None] * J)
    c, s = np.cos(theta), np.sin(theta)
    exact = np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)
    assert np.abs(E - exact).max() < 1e-12


def _backward_error_series(m: int, terms: int = 80) -> list[Fraction]:
    """Coefficients of h(x) = log(e^-x T_m(x)) (the backward error of the degree-m Taylor polynomial), exactly."""
    e = [Fraction((-1) ** k, factorial(k)) for k in range(terms + 1)]
    t = [Fraction(1, factorial(k)) if k <= m else Fraction(0) for k in range(terms + 1)]
    z = [-sum(e[i] * t[k - i] for i in range(k + 1)) for k in range(terms + 1)]  # e^-x T_m(x) = 1 - z(x)
    z[0] = Fraction(0)
    h, power = [Fraction(0)] * (terms + 1), [Fraction(1)] + [Fraction(0)] * terms
    for j in range(1, terms + 1):  # log(1 - z) = -sum z^j / j; z starts at x^(m+1)
        power = [sum(power[i] * z[k - i] for i in range(k + 1)) for k in range(terms + 1)]
        if not any(power):
            break
        h = [a - b / j for a, b in zip(h, power, strict=True)]
    return h


def test_theta_is_where_the_taylor_backward_error_bound_reaches_unit_roundoff():
    """||2^-s X||_1 <= theta: sum |h_k| theta^k / theta = 2^-53 (Al-Mohy and Higham's bound), found by bisection."""
    coef = np.array([abs(float(c)) for c in _backward_error_series(DEGREE)])
    bound = np.polynomial.polynomial.polyval
    lo, hi = 0.1, 5.0
    for _ in range(100):
        x = (lo + hi) / 2
        lo, hi = (x, hi) if bound(x, coef) / x <= 2.0**-53 else (lo, x)
    assert abs(lo - THETA_16) < 1e-12 * THETA_16
    assert squarings(THETA_16) == 0 and squarings(THETA_16 * 1.001) == 1 and squarings(THETA_16 * 2**10) == 10
