"""Stability charts: max|mu| over a (omega, A) grid of a single-axis base motion, fast.

Per frequency row, the monodromy Psi(A) of a grid point is the product of N Magnus-4 step exponentials
expm(Omega_4(A)).  Along a single-axis motion the base rates are linear in A, so Psi is an entire function of A
(of A^2 for pitch and yaw, whose coefficients are products of two rates).  The products are therefore formed at a
few Chebyshev amplitudes plus two check amplitudes (the grid amplitudes farthest from the nodes) and Psi is
interpolated (barycentric) to the grid; the nodes are doubled until rho at the check amplitudes agrees to
``AMP_TOL`` (:func:`interpolated_row`, shared with the digital-loop chart).  The commutator of Omega_4 comes from
precomputed pair commutators of the basis matrices, and a diagonal similarity (matrix balancing) keeps ||h A||
small.  Exponentials are batched in bounded blocks.  The eigenvalues are those of the monodromies compressed to
the span of their columns (:func:`reduce_to_range`): a damped rotor's monodromy has many multipliers at rounding
level, and an eigenvalue problem of their numerical rank (14-37 of 56 states on the paper rotor) costs a fraction
of the full one.  Rows run in parallel processes.
Agreement with single-point Magnus and with scipy solve_ivp is shown in tests and in ``make bench``.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import sys
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass

import numpy as np

from .floquet import GAUSS_C, SQRT3
from .matrix_exp import balancing_scale, expm_stack
from .motion import BaseMotion
from .system import COEFFICIENTS, ClosedLoop, PeriodicSystem, coefficient_values, periodic_system

CHART_STEPS = 32  # Magnus steps per period: converged to < 2e-7 in rho on the seed rotor (tests)
A_NODES = 6  # first number of Chebyshev amplitudes per row (doubled until the check amplitudes agree)
AMP_TOL = 1e-10  # |rho_interp - rho_exact| at the check amplitudes
AMP_BLOCK = 4  # amplitudes whose step maps are held at once (bounded temporaries)
RANGE_TOL = 1e-15  # singular values of the monodromies' columns kept for the eigenvalues (relative to the largest)
EVEN_COEFFICIENTS = frozenset({"Ox2", "Oy2", "Oz2", "OyOz", "Oyz2"})  # products of two base rates: even in A


def continuous_method(steps: int = CHART_STEPS) -> dict:
    """The continuous chart's method, as written in its JSON."""
    return {
        "integrator": "magnus4",
        "steps_per_period": steps,
        "amplitude": f"monodromy interpolated from {A_NODES} Chebyshev nodes (in A^2 for pitch and yaw, in A for "
        f"roll), nodes doubled until rho at two check amplitudes agrees to {AMP_TOL:g}",
        "eigenvalues": f"of the monodromies compressed to their common numerical range (singular values above "
        f"{RANGE_TOL:g} of the largest)",
    }


@dataclass(frozen=True)
class ChartResult:
    kind: str
    omegas: np.ndarray  # (n_w,) rad/s
    amplitudes: np.ndarray  # (n_A,) rad
    rho: np.ndarray  # (n_w, n_A) max|mu| per period of A(t)
    critical: np.ndarray  # (n_w, n_A) |arg mu|/T of the critical multiplier (rad/s)
    steps: int
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
            "method": continuous_method(self.steps),
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


def amplitude_nodes(amps: np.ndarray, n: int, even: bool):
    """(node amplitudes, interpolation matrix grid <- nodes or None if exact, indices of the check amplitudes)."""
    if amps.size <= n:
        return amps.copy(), None, np.empty(0, dtype=int)
    lo, hi = float(amps.min()), float(amps.max())
    if even:
        s_nodes = _cheb_nodes(lo * lo, hi * hi, n)
        nodes, W = np.sqrt(s_nodes), _bary_weights(s_nodes, amps * amps)
        dist = np.abs(amps[:, None] ** 2 - s_nodes[None, :]).min(axis=1)
    else:
        nodes = _cheb_nodes(lo, hi, n)
        W = _bary_weights(nodes, amps)
        dist = np.abs(amps[:, None] - nodes[None, :]).min(axis=1)
    return nodes, W, np.sort(np.argsort(-dist, kind="stable")[:2])


def reduce_to_range(*stacks: np.ndarray) -> tuple[np.ndarray, ...]:
    """The stacks compressed to the common numerical range of all their matrices: U^T P U for each P.

    Every matrix of the stacks, and every linear combination of them (the interpolated monodromies), maps into the
    span of their columns; with U an orthonormal basis of that span, P = U (U^T P), so the nonzero eigenvalues of
    P are those of U^T P U (r x r).  Directions whose singular value is below ``RANGE_TOL`` times the largest
    are dropped: a change of P below its own rounding error.
    """
    d = stacks[0].shape[-1]
    cols = np.concatenate([s.transpose(1, 0, 2).reshape(d, -1) for s in stacks], axis=1)
    U, sv, _ = np.linalg.svd(cols, full_matrices=False)
    r = int((sv > RANGE_TOL * sv[0]).sum()) if sv.size and sv[0] > 0 else d
    if r >= d:
        return stacks
    U = U[:, :r]
    return tuple(U.T @ s @ U for s in stacks)


def interpolated_row(
    monodromies: Callable[[np.ndarray], np.ndarray],
    amps: np.ndarray,
    even: bool,
    critical: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]],
) -> tuple[np.ndarray, np.ndarray, float]:
    """(rho, critical frequency, check error) at every amplitude of ``amps`` from ``monodromies(A)`` formed at
    Chebyshev amplitudes only; ``critical(Psi stack)`` gives (rho, critical frequency)."""
    n = A_NODES
    while True:
        nodes, W, checks = amplitude_nodes(amps, n, even)
        Psi = monodromies(np.concatenate([nodes, amps[checks]]))
        Pn, Pc = Psi[: nodes.size], Psi[nodes.size :]
        if W is None:
            rho, crit = critical(Pn)
            return rho, crit, 0.0
        Pn, Pc = reduce_to_range(Pn, Pc)
        Pg = (W @ Pn.reshape(nodes.size, -1)).reshape(amps.size, *Pn.shape[1:])
        rho, crit = critical(Pg)
        err = float(np.abs(critical(Pc)[0] - rho[checks]).max())
        if err <= AMP_TOL or 2 * n >= amps.size:
            if err > AMP_TOL:  # as many nodes as grid amplitudes: compute every amplitude exactly
                rho, crit = critical(monodromies(amps))
                err = 0.0
            return rho, crit, err
        n *= 2


class _Row:
    """Everything needed to evaluate one omega row (picklable, built once per chart)."""

    def __init__(self, loop: ClosedLoop, kind: str, spin: float, amplitudes: np.ndarray, steps: int):
        self.loop, self.kind, self.spin, self.steps = loop, kind, spin, steps
        self.amps = np.asarray(amplitudes, dtype=float)
        # diagonal similarity from the constant part (multipliers are invariant)
        self.scale = balancing_scale(loop.A0)

    def evaluate(self, omega: float, exact: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """(rho, critical frequency) per grid amplitude; ``exact``: every amplitude's own product, no interpolation."""
        ps = periodic_system(self.loop, BaseMotion.single(self.kind, 1.0, omega), self.spin)
        T = ps.period

        def critical(P):
            mu = np.linalg.eigvals(P)
            c = mu[np.arange(mu.shape[0]), np.argmax(np.abs(mu), axis=1)]
            return np.abs(c), np.abs(np.angle(c)) / T

        def monodromies(amps):
            return self.monodromies(ps, omega, amps)

        if exact:
            return critical(monodromies(self.amps))
        rho, crit, _ = interpolated_row(monodromies, self.amps, set(ps.names) <= EVEN_COEFFICIENTS, critical)
        return rho, crit

    def monodromies(self, ps: PeriodicSystem, omega: float, amps: np.ndarray) -> np.ndarray:
        """Psi(A) for each amplitude of ``amps``: products of the N Magnus-4 step exponentials, (len(amps), d, d)."""
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
        out = np.empty((len(amps), d, d))
        for a0 in range(0, len(amps), AMP_BLOCK):
            weights = []
            for A in amps[a0 : a0 + AMP_BLOCK]:
                mo = BaseMotion.single(self.kind, float(A), omega)
                c1 = np.vstack([np.ones(N), self._coef(mo, t1, ps.names)])
                c2 = np.vstack([np.ones(N), self._coef(mo, t2, ps.names)])
                lin = (h / 2) * (c1 + c2)  # (k, N)
                com = np.array([c2[i] * c1[j] - c2[j] * c1[i] for i, j in pairs]).reshape(len(pairs), N)
                weights.append(np.vstack([lin, (SQRT3 / 12) * h * h * com]).T)  # Omega_4 = weights @ mats
            E = expm_stack((np.concatenate(weights) @ mats).reshape(-1, N, d, d))
            out[a0 : a0 + AMP_BLOCK] = _tree_product(E)
        return out

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
    workers: int | None = None,
    progress: bool = False,
) -> ChartResult:
    """max|mu| over omegas x amplitudes for a single-axis motion ``kind`` (roll | pitch | yaw)."""
    omegas = np.asarray(omegas, dtype=float)
    amplitudes = np.asarray(amplitudes, dtype=float)
    t0 = time.perf_counter()
    row = _Row(loop, kind, spin, amplitudes, steps)
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
    return ChartResult(kind, omegas, amplitudes, rho, crit, steps, time.perf_counter() - t0)
