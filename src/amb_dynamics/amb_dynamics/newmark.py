"""Newmark-beta time response (average acceleration) of the closed loop, docs/physics.md#newmark.

The second-order matrices are read back from the closed loop A(t) itself ([K, D, Kz] = -M A[q'' rows]), so the
time response and the Floquet analysis integrate the same equations.  Controller states z (integral, derivative
filter) use the trapezoidal rule, solved jointly with the accelerations.  Linear in the state, so a matrix of
initial states (one per column) is propagated at once (used for the one-period Newmark map).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from .structure import StructuralModel
from .system import PeriodicSystem

BETA, GAMMA = 0.25, 0.5


@dataclass
class NewmarkRun:
    t: np.ndarray  # (K+1,) s
    x: np.ndarray  # (K+1, N) or (K+1, N, cols): [q, q', z]


def newmark(
    ps: PeriodicSystem, M: np.ndarray, x0: np.ndarray, h: float, steps: int, every: int = 1, forcing: bool = False
) -> NewmarkRun:
    """Integrate x' = A(t) x (+ forcing) with Newmark average acceleration, fixed step h (s).

    x0 : (N,) or (N, cols) initial state [q; q'; z].  Stores every ``every``-th step.
    """
    n, N = ps.loop.n, ps.loop.N
    nz = N - 2 * n
    x = np.array(x0, dtype=float)
    vec = x.ndim == 1
    if vec:
        x = x[:, None]
    q, qd, z = x[:n].copy(), x[n : 2 * n].copy(), x[2 * n :].copy()

    def parts(t):
        A = ps.A(np.array([t]))[0]
        KDZ = -M @ A[n : 2 * n]
        K, D, Kz = KDZ[:, :n], KDZ[:, n : 2 * n], KDZ[:, 2 * n :]
        f = M @ (ps.loop.Bf[n : 2 * n] @ ps.forcing(np.array([t]))[:, 0]) if forcing else np.zeros(n)
        return K, D, Kz, A[2 * n :, :n], A[2 * n :, 2 * n :], f

    K, D, Kz, Zq, Zz, f = parts(0.0)
    qdd = sla.solve(M, f[:, None] - D @ qd - K @ q - Kz @ z, assume_a="pos")
    out_t = [0.0]
    out_x = [np.vstack([q, qd, z])]
    I_z = np.eye(nz)
    for k in range(steps):
        t1 = (k + 1) * h
        qt = q + h * qd + h * h * (0.5 - BETA) * qdd
        qdt = qd + h * (1 - GAMMA) * qdd
        K, D, Kz, Zq1, Zz1, f = parts(t1)
        S = M + GAMMA * h * D + BETA * h * h * K
        r1 = f[:, None] - D @ qdt - K @ qt
        if nz:
            lhs = np.block([[S, Kz], [-0.5 * h * BETA * h * h * Zq1, I_z - 0.5 * h * Zz1]])
            r2 = z + 0.5 * h * (Zq @ q + Zz @ z) + 0.5 * h * Zq1 @ qt
            sol = sla.solve(lhs, np.vstack([r1, r2]))
            qdd, z = sol[:n], sol[n:]
            Zq, Zz = Zq1, Zz1
        else:
            qdd = sla.solve(S, r1)
        q = qt + BETA * h * h * qdd
        qd = qdt + GAMMA * h * qdd
        if (k + 1) % every == 0:
            out_t.append(t1)
            out_x.append(np.vstack([q, qd, z]))
    xs = np.array(out_x)
    return NewmarkRun(np.array(out_t), xs[..., 0] if vec else xs)


def newmark_period_map(ps: PeriodicSystem, M: np.ndarray, steps_per_period: int) -> np.ndarray:
    """The one-period Newmark map (the scheme applied to the N unit vectors): its rho -> Floquet rho, O(h^2)."""
    run = newmark(ps, M, np.eye(ps.loop.N), ps.period / steps_per_period, steps_per_period, every=steps_per_period)
    return run.x[-1]


def disk_initial_state(model: StructuralModel, N: int, node: int, amplitude: float = 1e-3) -> np.ndarray:
    """The seed paper's initial condition: v = w = amplitude (m) at ``node``, everything else 0."""
    q_fe = np.zeros(model.fe.n)
    q_fe[4 * (node - 1)] = amplitude
    q_fe[4 * (node - 1) + 1] = amplitude
    x0 = np.zeros(N)
    x0[: model.n] = model.from_fe(q_fe)
    return x0


def fit_growth_rate(t: np.ndarray, norms: np.ndarray, window: float = 0.5) -> tuple[float, float, np.ndarray]:
    """Least-squares slope of ln(norm) vs t over the last ``window`` fraction: (sigma 1/s, intercept, t used)."""
    k0 = int(len(t) * (1 - window))
    tt, yy = t[k0:], np.log(np.maximum(norms[k0:], 1e-300))
    slope, c0 = np.polyfit(tt, yy, 1)
    return float(slope), float(c0), tt
