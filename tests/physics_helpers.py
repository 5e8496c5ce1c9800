"""Shared helpers of the physics verification tests (PHYSICS.md section 8).

Generic numerics (set matching, companion forms, a validation ODE solver, config loading) and the independent
nonlinear Newton-Euler disk of T10; every quantity under test comes from the core's production code paths.
"""

from __future__ import annotations

import functools

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import linear_sum_assignment

from amb_dynamics import config, structure, system

# Parameter set P0 of PHYSICS.md 8.1
P0 = {"m": 1.0, "Id": 1.0, "Ip": 1.5, "k": 4.0, "kt": 9.0}
# State indices of the one-node model, x = [v, w, ty, tz, v', w', ty', tz']
TRANSLATION = [0, 1, 4, 5]
TILT = [2, 3, 6, 7]


def matched_error(got: np.ndarray, expected: np.ndarray) -> float:
    """Largest |got_i - expected_j| over the optimal one-to-one matching of two equal-size sets."""
    got, expected = np.asarray(got, complex).ravel(), np.asarray(expected, complex).ravel()
    assert got.shape == expected.shape, f"set sizes differ: {got.size} vs {expected.size}"
    cost = np.abs(got[:, None] - expected[None, :])
    rows, cols = linear_sum_assignment(cost)
    return float(cost[rows, cols].max())


def quadratic_eigenvalues(M: np.ndarray, D: np.ndarray, K: np.ndarray) -> np.ndarray:
    """Eigenvalues of (lambda^2 M + lambda D + K) z = 0 through the first-order companion form."""
    n = M.shape[0]
    Minv = np.linalg.inv(M)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ K, -Minv @ D]])
    return np.linalg.eigvals(A)


def even_quartic_roots(c4: float, c2: float, c0: float) -> np.ndarray:
    """Roots lambda of c4 lambda^4 + c2 lambda^2 + c0 = 0 (4 complex values)."""
    return np.roots([c4, 0.0, c2, 0.0, c0]).astype(complex)


def p0_stiffness(k: float = P0["k"], kt: float = P0["kt"], kc: float = 0.0) -> np.ndarray:
    """K_B of PHYSICS.md 8.1 on [v, w, ty, tz]."""
    return np.array([[k, 0, 0, kc], [0, k, -kc, 0], [0, -kc, kt, 0], [kc, 0, 0, kt]], dtype=float)


@functools.cache
def load(*overrides: str) -> config.RotorConfig:
    """The paper rotor (config/seed_paper.yaml) with overrides (cached: configs are frozen)."""
    return config.load_config(config.paper_config_path(), list(overrides))


def rigid_loop(
    kc: float = 0.0,
    c: float = 0.0,
    m: float = P0["m"],
    Id: float = P0["Id"],
    Ip: float = P0["Ip"],
    overrides: tuple[str, ...] = (),
) -> system.ClosedLoop:
    """Closed loop of the one-node rigid disk of 8.1 through the production assembly."""
    cfg = load(*overrides)
    model = structure.rigid_disk_model(m, Id, Ip, p0_stiffness(kc=kc), c, cfg=cfg)
    return system.closed_loop(model, cfg)


def constant_rates(Omega, spin: float) -> np.ndarray:
    """Coefficient vector c of system.COEFFICIENTS for a constant Omega (3,) and spin phi_dot."""
    return system.coefficients_from_rates(np.asarray(Omega, float), np.zeros(3), spin)


def block(A: np.ndarray, idx: list[int]) -> np.ndarray:
    """Square sub-matrix A[idx, idx]."""
    return A[np.ix_(idx, idx)]


def off_block(A: np.ndarray, idx: list[int]) -> float:
    """Largest coupling |A[idx, rest]|, |A[rest, idx]| between idx and the other states."""
    rest = [i for i in range(A.shape[0]) if i not in idx]
    return float(max(np.abs(A[np.ix_(idx, rest)]).max(), np.abs(A[np.ix_(rest, idx)]).max()))


def dop853_monodromy(A_of_t, N: int, T: float, rtol: float = 1e-10, atol: float = 1e-12) -> np.ndarray:
    """Validation monodromy: DOP853 on the matrix ODE X' = A(t) X, X(0) = I (PHYSICS.md 6)."""

    def rhs(t, x):
        return (A_of_t(t) @ x.reshape(N, N)).ravel()

    sol = solve_ivp(rhs, (0.0, T), np.eye(N).ravel(), method="DOP853", rtol=rtol, atol=atol)
    assert sol.success, sol.message
    return sol.y[:, -1].reshape(N, N)


def newton_euler_tilt(x, Om, dOm, spin, Id, Ip, kt):
    """Nonlinear Newton-Euler disk on a tilt spring kt in the moving base (PHYSICS.md 8.1 T10).

    x = (ty, tz, ty', tz') (rad, rad/s); Om, dOm (3,) base rates; spin = phi_dot.  Returns x' (4,).
    """
    ty, tz, dty, dtz = x
    cy, sy, cz, sz = np.cos(ty), np.sin(ty), np.cos(tz), np.sin(tz)
    a = np.array([cy * cz, sz, -sy * cz])
    a_y, a_z = np.array([-sy * cz, 0.0, -cy * cz]), np.array([-cy * sz, cz, sy * sz])
    a_yy, a_yz, a_zz = (
        np.array([-cy * cz, 0.0, sy * cz]),
        np.array([sy * sz, 0.0, cy * sz]),
        np.array([-cy * cz, -sz, sy * cz]),
    )
    da_B = a_y * dty + a_z * dtz
    da_I = da_B + np.cross(Om, a)
    w_perp = np.cross(a, da_I)
    ws = Om @ a + spin
    M_s = kt * np.cross(a, [1.0, 0.0, 0.0])
    dda_I = (Ip * ws * w_perp - np.cross(a, M_s)) / Id - (da_I @ da_I) * a
    dda_B = dda_I - 2 * np.cross(Om, da_B) - np.cross(dOm, a) - np.cross(Om, np.cross(Om, a))
    quad = a_yy * dty**2 + 2 * a_yz * dty * dtz + a_zz * dtz**2
    ddt = np.linalg.solve(np.column_stack([a_y, a_z])[1:], (dda_B - quad)[1:])  # Y, Z rows
    return np.array([dty, dtz, *ddt])
