"""Monodromy matrices and Floquet multipliers (docs/physics.md#floquet).

Continuous closed loop: fourth-order Magnus with N fixed steps per period (h = T/N), the step exponentials
batched, N doubled until rho changes by less than tol/10.  Sampled-data loop: the product of the step maps
F_k over the hybrid period p*Ts = r*T.  Aperiodic cases get the largest Lyapunov exponent (QR products).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from fractions import Fraction

import numpy as np

from .errors import InputError
from .matrix_exp import balancing_scale, expm_stack
from .motion import BaseMotion
from .sampled import SampledLoop
from .system import PeriodicSystem

VERDICT_TOL = 1e-6
MAX_HYBRID_DENOMINATOR = 64
SQRT3 = np.sqrt(3.0)
GAUSS_C = (0.5 - SQRT3 / 6.0, 0.5 + SQRT3 / 6.0)


@dataclass(frozen=True)
class FloquetResult:
    """Multipliers of one period; ``multipliers`` sorted by decreasing modulus (complex array)."""

    period: float  # s, period the multipliers refer to
    multipliers: np.ndarray  # (N,) complex
    method: str
    steps: int
    converged: bool = True
    notes: tuple[str, ...] = field(default=())

    @property
    def max_abs(self) -> float:
        return float(np.abs(self.multipliers[0]))

    @property
    def exponents(self) -> np.ndarray:
        """Floquet exponents ln(mu)/T (1/s); ln(0) guarded to -inf real part."""
        with np.errstate(divide="ignore"):
            return np.log(self.multipliers.astype(complex)) / self.period

    @property
    def critical_frequency(self) -> float:
        """|arg mu|/T of the critical multiplier (rad/s): tells which resonance it is (mod 2 pi/T)."""
        return float(abs(np.angle(self.multipliers[0])) / self.period)

    @property
    def verdict(self) -> str:
        return verdict(self.max_abs)

    @property
    def stable(self) -> bool:
        return self.verdict == "stable"

    def to_dict(self, top: int | None = None) -> dict:
        mu = self.multipliers if top is None else self.multipliers[:top]
        return {
            "period_s": self.period,
            "multipliers": [[float(z.real), float(z.imag)] for z in mu],
            "max_abs_multiplier": self.max_abs,
            "growth_rate_1_s": float(np.log(max(self.max_abs, 1e-300)) / self.period),
            "critical_frequency_rad_s": self.critical_frequency,
            "stable": self.stable,
            "verdict": self.verdict,
            "method": self.method,
            "steps": self.steps,
            "converged": self.converged,
            "notes": list(self.notes),
        }


def verdict(rho: float, tol: float = VERDICT_TOL) -> str:
    if rho < 1.0 - tol:
        return "stable"
    if rho > 1.0 + tol:
        return "unstable"
    return "marginal"


def sort_multipliers(mu: np.ndarray) -> np.ndarray:
    mu = np.asarray(mu, dtype=complex)
    return mu[np.lexsort((-mu.imag, -np.abs(mu)))]


def magnus_step_matrices(
    ps: PeriodicSystem,
    T: float,
    N: int,
    t0: float = 0.0,
    scale: np.ndarray | None = None,
) -> np.ndarray:
    """exp(Omega_4) of the N Magnus steps over [t0, t0+T], shape (N, dim, dim).

    With ``scale`` (a balancing vector d), the steps are returned in the balanced coordinates D^-1 x.
    """
    h = T / N
    tk = t0 + h * np.arange(N)
    A1 = ps.A(tk + GAUSS_C[0] * h)
    A2 = ps.A(tk + GAUSS_C[1] * h)
    if scale is not None:
        A1 = A1 / scale[:, None] * scale[None, :]
        A2 = A2 / scale[:, None] * scale[None, :]
    Om = (h / 2.0) * (A1 + A2) + (SQRT3 / 12.0) * h * h * (A2 @ A1 - A1 @ A2)
    return expm_stack(Om)


def chain_product(steps: np.ndarray) -> np.ndarray:
    """steps[N-1] @ ... @ steps[0] by pairwise (tree) reduction: log2(N) batched products."""
    mats = steps
    while mats.shape[0] > 1:
        if mats.shape[0] % 2:
            tail = mats[-1:]
            mats = np.concatenate([mats[1:-1:2] @ mats[0:-1:2], tail])
        else:
            mats = mats[1::2] @ mats[0::2]
    return mats[0]


def monodromy(ps: PeriodicSystem, N: int, T: float | None = None) -> np.ndarray:
    """Phi(T) of x' = A(t) x by N Magnus-4 steps (docs/physics.md#floquet)."""
    T = ps.period if T is None else T
    if T is None:
        raise InputError("this base motion has no period: no Floquet analysis (use the Lyapunov exponent)")
    d = balancing_scale(ps.A0)
    P = chain_product(magnus_step_matrices(ps, T, N, scale=d))
    return P * d[:, None] / d[None, :]  # back from the balanced coordinates


def floquet(
    ps: PeriodicSystem,
    N0: int | None = None,
    tol: float = VERDICT_TOL,
    max_steps: int = 8192,
) -> FloquetResult:
    """Multipliers by Magnus-4, doubling N until rho changes by less than tol/10."""
    T = ps.period
    if T is None:
        raise InputError("static or aperiodic base motion: Floquet multipliers need a periodic A(t)")
    N = N0 or (128 if "Ox" in ps.names else 64)
    prev = None
    while True:
        mu = sort_multipliers(np.linalg.eigvals(monodromy(ps, N)))
        rho = float(np.abs(mu[0]))
        if prev is not None and abs(rho - prev) < tol / 10:
            return FloquetResult(T, mu, "magnus4", N)
        if 2 * N > max_steps:
            return FloquetResult(
                T, mu, "magnus4", N, converged=False, notes=(f"rho changed by {abs(rho - prev):.2e} at N={N}",)
            )
        prev, N = rho, 2 * N


# ---- sampled-data loop -----------------------------------------------------------------------------------------
def hybrid_period(T: float, Ts: float) -> tuple[int, int] | None:
    """(p, r) with p*Ts = r*T, r <= 64, or None if T/Ts is not such a ratio (to 1e-9)."""
    ratio = T / Ts
    frac = Fraction(ratio).limit_denominator(MAX_HYBRID_DENOMINATOR)
    if abs(float(frac) - ratio) > 1e-9 * ratio:
        return None
    return frac.numerator, frac.denominator


def sampled_step_maps(loop: SampledLoop, motion: BaseMotion, steps: int) -> np.ndarray:
    """F_0 .. F_{steps-1} for the base rates held at t_k = k Ts, shape (steps, dim, dim)."""
    t = np.arange(steps) * loop.Ts
    Om, dOm = motion.angular_velocity(t)
    return np.array([loop.step_map(Om[:, k], dOm[:, k]) for k in range(steps)])


def sampled_floquet(
    loop: SampledLoop,
    motion: BaseMotion,
    period: float | None,
    snap: bool = False,
) -> FloquetResult:
    """Multipliers of the digital loop per base period (docs/physics.md#floquet).

    For T/Ts = p/r the monodromy is F_{p-1}...F_0 over r base periods, reported as |mu|^(1/r) per base period
    with angles divided by r.  ``snap`` replaces Ts by T/round(T/Ts) for other ratios (and says so).
    Static base: the multipliers of one sample step.
    """
    Ts = loop.Ts
    if period is None:
        F = loop.step_map(np.zeros(3), np.zeros(3))
        return FloquetResult(Ts, sort_multipliers(np.linalg.eigvals(F)), "sampled-step", 1)
    pr = hybrid_period(period, Ts)
    notes: tuple[str, ...] = ()
    if pr is None:
        if not snap:
            raise InputError(
                f"T/Ts = {period / Ts:.9g} is not a ratio p/r with r <= {MAX_HYBRID_DENOMINATOR}: "
                "use --snap to set Ts = T/round(T/Ts), or the Lyapunov exponent"
            )
        p = max(1, round(period / Ts))
        new_Ts = period / p
        notes = (f"Ts snapped from {Ts:.9g} s to T/{p} = {new_Ts:.9g} s",)
        loop = SampledLoop(
            loop.model, loop.cfg, Ts=new_Ts, delay_samples=loop.delay, forcing=False, dynamics=loop.plant.dynamics
        )
        pr = (p, 1)
    p, r = pr
    Psi = chain_product(sampled_step_maps(loop, motion, p))
    mu = np.linalg.eigvals(Psi)
    # per-base-period equivalent: modulus^(1/r), phase/r (principal branch)
    mu = np.abs(mu) ** (1.0 / r) * np.exp(1j * np.angle(mu) / r)
    return FloquetResult(period, sort_multipliers(mu), f"sampled-product(p={p},r={r})", p, notes=notes)


def lyapunov_exponent(step_maps, n_steps: int, dt: float, burn_in: int = 0) -> float:
    """Largest Lyapunov exponent (1/s) from QR-orthonormalised products of the maps ``step_maps(j)``.

    The first ``burn_in`` steps only align the basis: transient (non-normal) growth is not counted.
    """
    Q = None
    total = 0.0
    for j in range(n_steps):
        F = step_maps(j)
        if Q is None:
            Q = np.eye(F.shape[0])
        Q, R = np.linalg.qr(F @ Q)
        if j >= burn_in:
            total += np.log(max(abs(R[0, 0]), 1e-300))
    return total / ((n_steps - burn_in) * dt)


def sampled_lyapunov(loop: SampledLoop, motion: BaseMotion, periods: int, period: float) -> float:
    """Largest Lyapunov exponent (1/s) of the digital loop over ``periods`` base periods (incommensurate Ts)."""
    steps = int(np.ceil(periods * period / loop.Ts))
    t = np.arange(steps) * loop.Ts
    Om, dOm = motion.angular_velocity(t)
    return lyapunov_exponent(lambda j: loop.step_map(Om[:, j], dOm[:, j]), steps, loop.Ts, burn_in=steps // 2)


def aperiodic_exponents(ps: PeriodicSystem, duration: float, h: float, chunk: int = 128) -> dict:
    """No period (incommensurate or recorded motion, docs/physics.md#aperiodic): growth of Phi(t, 0) over ``duration``.

    Returns the finite-time Lyapunov exponent (1/t) ln ||Phi(t,0)||_2, the largest Lyapunov exponent from
    QR-orthonormalised products (second half of the run), and max_t ||Phi(t,0)||_2 (sampled every ``chunk`` steps).
    """
    steps = max(1, int(np.ceil(duration / h)))
    d = balancing_scale(ps.A0)
    P = np.eye(ps.loop.N)
    Q = np.eye(ps.loop.N)
    log_scale, lyap, max_norm, done = 0.0, 0.0, 1.0, 0
    while done < steps:
        n = min(chunk, steps - done)
        for E in magnus_step_matrices(ps, n * h, n, t0=done * h, scale=d):
            P = E @ P
            Q, R = np.linalg.qr(E @ Q)
            if done >= steps // 2:
                lyap += np.log(max(abs(R[0, 0]), 1e-300))
            done += 1
        s = np.linalg.norm(P, 2)
        P /= s
        log_scale += np.log(s)
        phys = np.linalg.norm(P * d[:, None] / d[None, :], 2) * np.exp(log_scale)  # back to physical coordinates
        max_norm = max(max_norm, float(phys))
    t = steps * h
    return {
        "duration_s": t,
        "steps": steps,
        "ftle_1_s": float(np.log(phys) / t),
        "lyapunov_exponent_1_s": float(lyap / ((steps - steps // 2) * h)),
        "max_transition_norm": max_norm,
    }
