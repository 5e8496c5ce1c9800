"""The stacked matrix exponential against scipy's, matrix by matrix (block boundaries, shapes, norms)."""

import numpy as np
import scipy.linalg as sla

from amb_dynamics.matrix_exp import BLOCK, expm_stack


def _reference(X: np.ndarray) -> np.ndarray:
    flat = X.reshape(-1, *X.shape[-2:])
    return np.array([sla.expm(m) for m in flat]).reshape(X.shape)


def test_stack_across_blocks_equals_scipy_matrix_by_matrix():
    rng = np.random.default_rng(7)
    n = 2 * BLOCK + 5  # two full blocks and a partial one
    X = rng.standard_normal((n, 12, 12))
    X *= np.geomspace(1e-3, 40.0, n)[:, None, None]  # norms from well below to far above theta_13
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
