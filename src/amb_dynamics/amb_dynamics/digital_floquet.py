"""Floquet multipliers of the digital loop for any ratio T/Ts, with the method and its error per point.

* T/Ts = p/r (r small): exact, the product of the p step maps of ``SampledLoop`` over the hybrid period r T.
* otherwise (the common, incommensurate case): the loop's rho per base period is a smooth function of the sampling
  ratio x = T/Ts (measured: second differences ~4e-9 per unit of x at the paper's pitch point).  It is computed
  exactly at the three integer ratios m nearest to x (Ts' = T/m, each an exact one-period product) and interpolated
  by the parabola through them.  Error bound: 2 |quadratic - linear| (the leading term of the linear interpolant's
  error, which the quadratic removes) plus ``BOUND_FLOOR`` for rounding; tested against exact hybrid products at
  rational ratios p/r with r = 2, 3, 5 in between (tests/test_digital_floquet.py).

``estimate_point`` works for any periodic base motion through ``floquet.sampled_floquet``; the chart kernel
(:mod:`amb_dynamics.digital_chart`) computes the same integer-ratio values for whole grid rows at once.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import InputError
from .floquet import MAX_HYBRID_DENOMINATOR, FloquetResult, hybrid_period, sampled_floquet
from .motion import BaseMotion
from .sampled import SampledLoop

BOUND_FLOOR = 1e-11  # rounding of rho in a product of ~1e4 step maps (measured spread < 1e-12)
BOUND_SAFETY = 2.0


@dataclass(frozen=True)
class RatioPlan:
    """How rho at the ratio x = T/Ts is obtained: ``exact`` (one hybrid product) or ``interp`` (three integers)."""

    x: float
    kind: str  # "exact" | "interp"
    ratios: tuple[tuple[int, int], ...]  # (p, r): Ts' = r T / p, p steps over r base periods

    def combine(self, rhos) -> tuple[float, float]:
        """(rho, error bound) at x from rho at ``ratios`` (same order)."""
        if self.kind == "exact":
            return float(rhos[0]), 0.0
        rho, bound = interpolate_ratio(self.x, [p for p, _ in self.ratios], rhos)
        return rho, bound

    @property
    def method(self) -> str:
        if self.kind == "exact":
            p, r = self.ratios[0]
            return f"sampled-product(p={p},r={r})"
        ms = ",".join(str(p) for p, _ in self.ratios)
        return f"ratio-interpolation(T/Ts={self.x:.6f}; exact at T/Ts={ms})"


def plan_ratio(x: float, max_r: int = MAX_HYBRID_DENOMINATOR) -> RatioPlan:
    """The plan for the sampling ratio x = T/Ts: exact if x = p/r with r <= max_r (to 1e-9), else interpolation."""
    if not np.isfinite(x) or x <= 0:
        raise InputError(f"the sampling ratio T/Ts must be a positive number (got {x})")
    pr = hybrid_period(x, 1.0)
    if pr is not None and pr[1] <= max_r:
        return RatioPlan(x, "exact", (pr,))
    m0 = max(1, math.floor(x))
    third = m0 - 1 if (x - m0 < 0.5 and m0 > 1) else m0 + 2
    ms = sorted({m0, m0 + 1, third})
    return RatioPlan(x, "interp", tuple((m, 1) for m in ms))


def interpolate_ratio(x: float, ms, rhos) -> tuple[float, float]:
    """Quadratic Lagrange value at x through (m_i, rho_i) and the bound 2 |quadratic - linear| + floor.

    The linear interpolant uses the two integers bracketing x (the first two of ``ms`` that do).
    """
    ms = np.asarray(ms, dtype=float)
    rhos = np.asarray(rhos, dtype=float)
    quad = 0.0
    for i in range(3):
        li = 1.0
        for j in range(3):
            if j != i:
                li *= (x - ms[j]) / (ms[i] - ms[j])
        quad += li * rhos[i]
    lo = int(np.searchsorted(ms, x, side="right") - 1)
    lo = min(max(lo, 0), 1)
    lin = rhos[lo] + (x - ms[lo]) * (rhos[lo + 1] - rhos[lo]) / (ms[lo + 1] - ms[lo])
    return float(quad), float(BOUND_SAFETY * abs(quad - lin) + BOUND_FLOOR)


def estimate_point(loop: SampledLoop, motion: BaseMotion, period: float) -> dict:
    """max|mu| per base period of the digital loop at the loop's own Ts, exact or estimated with a bound.

    Returns the ``FloquetResult.to_dict`` fields plus ``error_bound`` (absolute, on max|mu|), ``sampling_ratio``
    (T/Ts) and, for an estimate, ``ratio_values`` (rho at each integer ratio used).  The multipliers listed for
    an estimate are those of the nearest integer ratio (their moduli, not the estimate, are exact there).
    """
    x = period / loop.Ts
    plan = plan_ratio(x)
    if plan.kind == "exact":
        res = sampled_floquet(loop, motion, period)
        data = res.to_dict()
        data.update(error_bound=0.0, sampling_ratio=x)
        return data
    results: list[FloquetResult] = []
    for p, r in plan.ratios:
        sub = loop.sub_loop(r * period / p)
        results.append(sampled_floquet(sub, motion, period))
    rho, bound = plan.combine([res.max_abs for res in results])
    nearest = min(range(3), key=lambda i: abs(plan.ratios[i][0] - x))
    data = results[nearest].to_dict()
    stable, verdict = verdict_of(rho, bound)
    data.update(
        max_abs_multiplier=rho,
        growth_rate_1_s=float(np.log(max(rho, 1e-300)) / period),
        stable=stable,
        verdict=verdict,
        method=plan.method,
        steps=int(sum(p for p, _ in plan.ratios)),
        error_bound=bound,
        sampling_ratio=x,
        ratio_values=[[p, res.max_abs] for (p, _), res in zip(plan.ratios, results, strict=True)],
        notes=[
            f"T/Ts = {x:.6f} is not p/r with r <= {MAX_HYBRID_DENOMINATOR}: max|mu| interpolated in T/Ts from exact "
            f"products at T/Ts = {', '.join(str(p) for p, _ in plan.ratios)} (error bound {bound:.2g}); "
            f"multipliers listed: T/Ts = {plan.ratios[nearest][0]}"
        ],
    )
    return data


def verdict_of(rho: float, bound: float) -> tuple[bool, str]:
    """(stable, "stable" | "unstable" | "marginal") of max|mu| = rho +- bound."""
    if rho + bound < 1.0 - 1e-6:
        return True, "stable"
    return False, "unstable" if rho - bound > 1.0 + 1e-6 else "marginal"


def spectral_radius_at_rest(loop: SampledLoop) -> float:
    """max|mu| of one sample step with the base at rest (< 1: the digital loop is stable)."""
    F = loop.step_map(np.zeros(3), np.zeros(3))
    return float(np.abs(np.linalg.eigvals(F)).max())
