"""Validation integrator (docs/physics.md#floquet): the monodromy by scipy solve_ivp on the matrix ODE X' = A(t) X.

Straightforward and slow on purpose: it is the independent reference for the Magnus integrator and the chart.
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp

from .system import PeriodicSystem


def monodromy_ivp(
    ps: PeriodicSystem,
    rtol: float = 1e-11,
    atol: float = 1e-13,
    method: str = "DOP853",
) -> np.ndarray:
    """Phi(T) by ``solve_ivp`` from X(0) = I (all columns at once)."""
    N = ps.loop.N
    T = ps.period

    def rhs(t, y):
        return (ps.A(np.array([t]))[0] @ y.reshape(N, N)).ravel()

    sol = solve_ivp(rhs, (0.0, T), np.eye(N).ravel(), method=method, rtol=rtol, atol=atol)
    if not sol.success:  # pragma: no cover - reported, never silently used
        raise RuntimeError(f"solve_ivp failed: {sol.message}")
    return sol.y[:, -1].reshape(N, N)


def rho_ivp(ps: PeriodicSystem, **kw) -> float:
    return float(np.max(np.abs(np.linalg.eigvals(monodromy_ivp(ps, **kw)))))
