"""Digital-loop stability chart: max|mu| per base period over an (omega, A) grid of a single-axis base motion.

One grid row (fixed omega, all amplitudes) at a time, built on ``SampledLoop.step_map`` only:

1. The sampling ratio x = T/Ts picks the plan (:func:`digital_floquet.plan_ratio`): one exact hybrid product
   (T/Ts = p/r, r <= ``CHART_MAX_R``) or three integer ratios interpolated in x, with the error bound.
2. Along a single-axis motion the step map depends on the base rate w = Omega_axis (and its derivative v) only,
   and for pitch and yaw only on w^2 (both detected numerically from ``step_map``).  F is therefore interpolated
   (:class:`rate_family.RateFamily`: Chebyshev, barycentric) from a few step maps in u = w^2 (or in (w, v) for roll)
   instead of one expm per step per point; the interpolation error is measured at probe points and the nodes
   doubled until it is below ``STEP_TOL`` relative.
3. The monodromy Psi(A) is an entire function of A^2 (pitch, yaw) or A (roll): the products are formed at
   ``chart.A_NODES`` Chebyshev amplitudes plus two check amplitudes and interpolated to the grid
   (:func:`chart.interpolated_row`, as in the continuous chart).  The measured check difference is added to the
   point's error bound.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .chart import interpolated_row
from .digital_floquet import RatioPlan, plan_ratio
from .motion import BaseMotion
from .rate_family import STEP_TOL, RateFamily
from .sampled import SampledLoop

CHART_MAX_R = 4  # exact hybrid products in a chart only for r <= 4 (cost r T/Ts steps); otherwise interpolation
BLOCK = 64  # steps multiplied per batch (memory: 1.5 x amplitudes x BLOCK x dim^2 doubles, reused)
METHOD_CODES = {"exact": 0, "interp": 1}


@dataclass
class RowResult:
    rho: np.ndarray  # (n_A,)
    bound: np.ndarray  # (n_A,) absolute error bound on rho
    critical: np.ndarray  # (n_A,) rad/s
    method: int  # METHOD_CODES
    steps: int  # step maps per point (sum over the ratios)


def ratio_monodromies(fam: RateFamily, kind: str, omega: float, p: int, Ts: float, amps: np.ndarray) -> np.ndarray:
    """Psi(A) = F_{p-1} ... F_0 for each amplitude in ``amps`` (t_k = k Ts), shape (len(amps), d, d).

    The steps are taken ``BLOCK`` at a time into buffers allocated once per call: fresh multi-megabyte temporaries
    per block cost page faults that two workers side by side pay twice (the 1 -> 2 workers speed-up)."""
    unit = BaseMotion.single(kind, 1.0, omega)
    d = fam.Fn.shape[-1]
    n_a, width = amps.size, min(BLOCK, p)
    Psi = np.broadcast_to(np.eye(d), (n_a, d, d)).copy()
    nxt = np.empty_like(Psi)
    maps = np.empty((n_a * width, d * d))
    half = np.empty((n_a, (width + 1) // 2, d, d))
    for k0 in range(0, p, BLOCK):
        t = Ts * np.arange(k0, min(p, k0 + BLOCK))
        Om, dOm = unit.angular_velocity(t)
        w1, v1 = fam.e @ Om, fam.e @ dOm  # rates along the axis for A = 1 (linear in A)
        w = (amps[:, None] * w1[None, :]).ravel()
        v = (amps[:, None] * v1[None, :]).ravel()
        F = np.matmul(fam.weights(w, v), fam.Fflat, out=maps[: w.size]).reshape(n_a, t.size, d, d)
        np.matmul(_tree_product_into(F, half), Psi, out=nxt)
        Psi, nxt = nxt, Psi
    return Psi


def _tree_product_into(S: np.ndarray, spare: np.ndarray) -> np.ndarray:
    """S[:, N-1] @ ... @ S[:, 0] for a stack (n_a, N, d, d), pairwise, in S and ``spare`` (room for N/2 rounded up
    per amplitude) without new arrays; both are overwritten."""
    n = S.shape[1]
    while n > 1:
        h = n // 2
        np.matmul(S[:, 1 : 2 * h : 2], S[:, 0 : 2 * h : 2], out=spare[:, :h])
        if n % 2:
            spare[:, h] = S[:, n - 1]
            h += 1
        S, spare, n = spare, S, h
    return S[:, 0]


def _crit(Psi: np.ndarray, r: int, T: float) -> tuple[np.ndarray, np.ndarray]:
    mu = np.linalg.eigvals(Psi)
    i = np.argmax(np.abs(mu), axis=1)
    c = mu[np.arange(mu.shape[0]), i]
    return np.abs(c) ** (1.0 / r), np.abs(np.angle(c)) / (r * T)


def ratio_row(loop: SampledLoop, kind: str, omega: float, T: float, p: int, r: int, amps: np.ndarray):
    """rho and critical frequency per base period at the exact ratio T/Ts' = p/r, with the amplitude check error."""
    Ts = r * T / p
    sub = loop.sub_loop(Ts)
    axis = np.zeros(3)
    axis[{"roll": 0, "yaw": 1, "pitch": 2}[kind]] = 1.0
    amax = float(np.abs(amps).max())
    fam = RateFamily(sub.step_map, axis, amax * omega, amax * omega * omega, tol=STEP_TOL)
    return interpolated_row(
        lambda a: ratio_monodromies(fam, kind, omega, p, Ts, a), amps, fam.even, lambda P: _crit(P, r, T)
    )


def digital_row(loop: SampledLoop, kind: str, omega: float, amps: np.ndarray, max_r: int = CHART_MAX_R) -> RowResult:
    """One chart row: rho, error bound and critical frequency for every amplitude at base frequency ``omega``."""
    amps = np.asarray(amps, dtype=float)
    T = parametric_period(loop, kind, omega)
    plan: RatioPlan = plan_ratio(T / loop.Ts, max_r)
    outs = [ratio_row(loop, kind, omega, T, p, r, amps) for p, r in plan.ratios]
    nearest = min(range(len(outs)), key=lambda i: abs(plan.ratios[i][0] / plan.ratios[i][1] - plan.x))
    rho = np.empty(amps.size)
    bound = np.empty(amps.size)
    for j in range(amps.size):
        rho[j], bound[j] = plan.combine([o[0][j] for o in outs])
    bound += max(o[2] for o in outs)
    steps = sum(p for p, _ in plan.ratios)
    return RowResult(rho, bound, outs[nearest][1], METHOD_CODES[plan.kind], steps)


def parametric_period(loop: SampledLoop, kind: str, omega: float) -> float:
    """Period of the step maps along the motion: pi/omega if they depend on the rate squared only (pitch and yaw,
    detected from ``step_map``), else 2 pi/omega."""
    axis = np.zeros(3)
    axis[{"roll": 0, "yaw": 1, "pitch": 2}[kind]] = 1.0
    w, v = omega * 0.1, omega * omega * 0.1
    F = loop.step_map(w * axis, 0.0 * axis)
    even = np.array_equal(F, loop.step_map(w * axis, v * axis)) and np.array_equal(
        F, loop.step_map(-w * axis, 0 * axis)
    )
    return (np.pi if even else 2 * np.pi) / omega
