"""Stability charts: max|mu| over a (omega, A) grid of a single-axis base motion, fast.

Per frequency row, every grid point needs N Magnus-4 step exponentials expm(Omega_4(A)).  Omega_4 is an entire
function of the amplitude A, so the exponentials are computed at Chebyshev nodes in A only and interpolated
(barycentric) to the grid amplitudes; the N step matrices of all amplitudes are then multiplied by batched tree
reduction.  The commutator of Omega_4 comes from precomputed pair commutators of the basis matrices, and a
diagonal similarity (matrix balancing) keeps ||h A|| small.  Rows run in parallel processes.
Agreement with single-point Magnus and with scipy solve_ivp is shown in tests and in ``make bench``.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass

import numpy as np

from .floquet import GAUSS_C, SQRT3
from .matrix_exp import balancing_scale, expm_stack
from .motion import BaseMotion
from .system import COEFFICIENTS, ClosedLoop, coefficient_values, periodic_system

CHART_STEPS = 32  # Magnus steps per period: converged to < 2e-7 in rho on the seed rotor (tests)
CHEB_NODES = 16  # amplitude nodes per row: interpolation error < 1e-10 in rho (tests)


@dataclass(frozen=True)
class ChartResult:
    kind: str
    omegas: np.ndarray  # (n_w,) rad/s
    amplitudes: np.ndarray  # (n_A,) rad
    rho: np.ndarray  # (n_w, n_A) max|mu| per period of A(t)
    critical: np.ndarray  # (n_w, n_A) |arg mu|/T of the critical multiplier (rad/s)
    steps: int
    nodes: int
    seconds: float

    def to_dict(self) -> dict:
        return {
            "motion": self.kind,
            "omega_rad_s": self.omegas.tolist(),
            "amplitude_rad": self.amplitudes.tolist(),
            "max_abs_multiplier": self.rho.tolist(),
            "critical_frequency_rad_s": self.critical.tolist(),
            "unstable_points": int((self.rho > 1 + 1e-6).sum()),
            "points": int(self.rho.size),
            "method": {
                "integrator": "magnus4",
                "steps_per_period": self.steps,
                "amplitude_chebyshev_nodes": self.nodes,
            },
            "wall_time_s": self.seconds,
        }


def _cheb_nodes(lo: float, hi: float, m: int) -> np.ndarray:
    j = np.arange(m)
    return (lo + hi) / 2 + (hi - lo) / 2 * np.cos(np.pi * (2 * j + 1) / (2 * m))


def _bary_weights(nodes: np.ndarray, x: np.ndarray) -> np.ndarray:
    """(len(x), m) barycentric interpolation matrix for Chebyshev points of the first kind."""
    m = nodes.size
    j = np.arange(m)
    w = (-1.0) ** j * np.sin(np.pi * (2 * j + 1) / (2 * m))
    diff = x[:, None] - nodes[None, :]
    exact = np.isclose(diff, 0.0, rtol=0, atol=1e-15)
    diff[exact] = 1.0
    W = w / diff
    W /= W.sum(axis=1, keepdims=True)
    rows = exact.any(axis=1)
    W[rows] = exact[rows].astype(float)
    return W


def _tree_product(S: np.ndarray) -> np.ndarray:
    """S[..., N-1, :, :] @ ... @ S[..., 0, :, :] for a stack (..., N, d, d)."""
    while S.shape[-3] > 1:
        if S.shape[-3] % 2:
            S = np.concatenate([S[..., 1:-1:2, :, :] @ S[..., 0:-1:2, :, :], S[..., -1:, :, :]], axis=-3)
        else:
            S = S[..., 1::2, :, :] @ S[..., 0::2, :, :]
    return S[..., 0, :, :]


class _Row:
    """Everything needed to evaluate one omega row (picklable, built once per chart)."""

    def __init__(self, loop: ClosedLoop, kind: str, spin: float, amplitudes: np.ndarray, steps: int, nodes: int):
        self.loop, self.kind, self.spin, self.amps, self.steps = loop, kind, spin, amplitudes, steps
        lo, hi = float(amplitudes.min()), float(amplitudes.max())
        self.nodes = amplitudes.copy() if amplitudes.size <= nodes or hi == lo else _cheb_nodes(lo, hi, nodes)
        self.W = _bary_weights(self.nodes, amplitudes) if self.nodes is not amplitudes else None
        # diagonal similarity from the constant part (multipliers are invariant)
        self.scale = balancing_scale(loop.A0)

    def evaluate(self, omega: float) -> tuple[np.ndarray, np.ndarray]:
        ps = periodic_system(self.loop, BaseMotion.single(self.kind, 1.0, omega), self.spin)
        T, N = ps.period, self.steps
        s = self.scale
        basis = np.concatenate([ps.A0[None], ps.A_stack]) / s[None, :, None] * s[None, None, :]
        k = basis.shape[0]
        pairs = [(i, j) for i in range(k) for j in range(i + 1, k)]
        comm = np.array([basis[i] @ basis[j] - basis[j] @ basis[i] for i, j in pairs])
        d = basis.shape[-1]
        mats = np.concatenate([basis, comm.reshape(len(pairs), d, d)]).reshape(-1, d * d)
        h = T / N
        tk = h * np.arange(N)
        t1, t2 = tk + GAUSS_C[0] * h, tk + GAUSS_C[1] * h
        exps = []
        for A in self.nodes:
            mo = BaseMotion.single(self.kind, float(A), omega)
            c1 = np.vstack([np.ones(N), self._coef(mo, t1, ps.names)])
            c2 = np.vstack([np.ones(N), self._coef(mo, t2, ps.names)])
            lin = (h / 2) * (c1 + c2)  # (k, N)
            com = np.array([c2[i] * c1[j] - c2[j] * c1[i] for i, j in pairs]).reshape(len(pairs), N)
            weights = np.vstack([lin, (SQRT3 / 12) * h * h * com])  # Omega_4 = sum_m weights[m, n] * mats[m]
            exps.append((weights.T @ mats).reshape(N, d, d))
        E = expm_stack(np.concatenate(exps)).reshape(len(self.nodes), N, d, d)
        S = E if self.W is None else (self.W @ E.reshape(len(self.nodes), -1)).reshape(-1, N, d, d)
        P = _tree_product(S)
        mu = np.linalg.eigvals(P)
        i = np.argmax(np.abs(mu), axis=1)
        crit = mu[np.arange(mu.shape[0]), i]
        return np.abs(crit), np.abs(np.angle(crit)) / T

    def _coef(self, motion: BaseMotion, t: np.ndarray, names: tuple[str, ...]) -> np.ndarray:
        c = coefficient_values(motion, self.spin, t)
        return c[[COEFFICIENTS.index(nm) for nm in names]]


_ROW: _Row | None = None


def _init(row: _Row) -> None:
    global _ROW
    _ROW = row


def _eval(i_omega: tuple[int, float]):
    i, omega = i_omega
    rho, crit = _ROW.evaluate(omega)
    return i, rho, crit


def stability_chart(
    loop: ClosedLoop,
    kind: str,
    omegas,
    amplitudes,
    spin: float,
    steps: int = CHART_STEPS,
    nodes: int = CHEB_NODES,
    workers: int | None = None,
    progress: bool = False,
) -> ChartResult:
    """max|mu| over omegas x amplitudes for a single-axis motion ``kind`` (roll | pitch | yaw)."""
    omegas = np.asarray(omegas, dtype=float)
    amplitudes = np.asarray(amplitudes, dtype=float)
    t0 = time.perf_counter()
    row = _Row(loop, kind, spin, amplitudes, steps, nodes)
    rho = np.empty((omegas.size, amplitudes.size))
    crit = np.empty_like(rho)
    workers = workers or min(os.cpu_count() or 1, omegas.size)
    done = 0

    def report():
        if progress:
            bar = "#" * int(30 * done / omegas.size)
            print(f"\rchart {bar:<30} {done}/{omegas.size} rows", end="", file=sys.stderr, flush=True)

    if workers <= 1:
        for i, w in enumerate(omegas):
            rho[i], crit[i] = row.evaluate(w)
            done += 1
            report()
    else:
        ctx = mp.get_context("fork")
        with ProcessPoolExecutor(workers, mp_context=ctx, initializer=_init, initargs=(row,)) as pool:
            futures = [pool.submit(_eval, (i, w)) for i, w in enumerate(omegas)]
            for fut in as_completed(futures):
                i, r, c = fut.result()
                rho[i], crit[i] = r, c
                done += 1
                report()
    if progress:
        print(file=sys.stderr)
    return ChartResult(kind, omegas, amplitudes, rho, crit, steps, row.nodes.size, time.perf_counter() - t0)
