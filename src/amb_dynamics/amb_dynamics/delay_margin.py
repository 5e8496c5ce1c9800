"""Delay margin of the digital loop: how much more input delay than its own the loop at rest tolerates.

A real target applies each command some time after the sample it answers: its computation, a DAC's update, a
network link in a hardware-in-the-loop rig.  The rig's loop has a whole number of samples of delay
(``controller.delay_samples``); a command that acts at t_k + tau instead, tau = (d + f) Ts with 0 <= f < 1, changes
the ZOH step (the modified z-transform): over [t_k, t_k+1] the current answering sample k - d - 1 acts for f Ts,
then the one answering sample k - d for the rest,

    x_k+1 = Phi x_k + Gamma_1 u_k-d + e^(A (1 - f) Ts) Gamma_f u_k-d-1,

with Phi = e^(A Ts), Gamma_1 = int_0^((1 - f) Ts) e^(A s) ds B and Gamma_f = int_0^(f Ts) e^(A s) ds B, A and B the
continuous plant's (:func:`amb_dynamics.sensitivity.plant_state_space`, at the levitated operating point the
preflight uses).  Closed with the discrete controller (:func:`amb_dynamics.control_law.discrete_controller`
without its delay) the loop's step map has a spectral radius rho(tau); at tau = d Ts it is the preflight's.  The
delay margin is the extra delay from d Ts to the first tau where rho reaches 1: a grid of ``GRID`` points per
sample, then bisection.  The margin is the whole-loop counterpart of a phase margin per axis, and for a digital
loop the relevant one: jitter, a late DAC update or a network hop adds delay, not phase at one frequency.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import scipy.linalg as sla

from .config import RotorConfig
from .control_law import discrete_controller
from .sensitivity import plant_state_space
from .state_space import StateSpace
from .structure import StructuralModel

GRID = 10  # grid points per sample of extra delay, before the bisection
BISECTIONS = 12  # the crossing to 1/GRID / 2^12 of a sample
MAX_EXTRA_SAMPLES = 2.0  # a margin beyond this is reported as "more than"
MARGIN = 1e-12  # rho below 1 - MARGIN is stable (as the preflight)


def _zoh(A: np.ndarray, B: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
    """(e^(A t), int_0^t e^(A s) ds B) from one exponential of the augmented matrix."""
    n, m = B.shape
    M = np.zeros((n + m, n + m))
    M[:n, :n], M[:n, n:] = A, B
    E = sla.expm(M * t)
    return E[:n, :n], E[:n, n:]


def step_map(plant: StateSpace, controller: StateSpace, Ts: float, tau: float) -> np.ndarray:
    """Step map of the loop whose command answering sample k acts from t_k + tau (tau >= 0, s).

    State [x_k; u_k-1; ...; u_k-h; xc_k], h = floor(tau / Ts) + 1 stored commands; u_k = Cc xc_k + Dc C x_k.
    """
    A, B, C = plant.A, plant.B, plant.C
    n, m = B.shape
    nd = int(np.floor(tau / Ts + 1e-12))
    f = max(tau / Ts - nd, 0.0)
    h = nd + 1
    nc = controller.A.shape[0]
    N = n + h * m + nc
    Phi, _ = _zoh(A, B, Ts)
    E_rest, G_rest = _zoh(A, B, (1.0 - f) * Ts)
    _, G_first = _zoh(A, B, f * Ts)
    U = np.zeros((m, N))  # u_k as a function of the state
    U[:, :n] = controller.D @ C
    U[:, n + h * m :] = controller.C

    def command(j: int) -> np.ndarray:  # u_k-j as a function of the state
        if j == 0:
            return U
        R = np.zeros((m, N))
        R[:, n + (j - 1) * m : n + j * m] = np.eye(m)
        return R

    F = np.zeros((N, N))
    F[:n, :n] = Phi
    F[:n] += G_rest @ command(nd) + E_rest @ G_first @ command(nd + 1)
    F[n : n + m] = U
    for j in range(2, h + 1):
        F[n + (j - 1) * m : n + j * m] = command(j - 1)
    F[n + h * m :, :n] = controller.B @ C
    F[n + h * m :, n + h * m :] = controller.A
    return F


def spectral_radius(plant: StateSpace, controller: StateSpace, Ts: float, tau: float) -> float:
    return float(np.abs(np.linalg.eigvals(step_map(plant, controller, Ts, tau))).max())


def delay_margin(model: StructuralModel, cfg: RotorConfig, speed_rpm: float | None = None) -> dict:
    """The extra input delay beyond ``controller.delay_samples`` that the loop at rest (spin speed ``speed_rpm``,
    default the config's) tolerates: ``margin_samples`` (None: more than MAX_EXTRA_SAMPLES), ``margin_us``, and
    the spectral radius at the loop's own delay (``rho_own``) and at one more sample (``rho_one_more``)."""
    at = cfg if speed_rpm is None else dataclasses.replace(cfg, spin_speed_rpm=float(speed_rpm))
    Ts = 1.0 / at.controller.rate_hz
    d = at.controller.delay_samples
    P = plant_state_space(model, at)
    K = discrete_controller(at, model.gains, Ts, 0, model.Ba.shape[1])

    def rho(extra: float) -> float:
        return spectral_radius(P, K, Ts, (d + extra) * Ts)

    out = {"rate_hz": at.controller.rate_hz, "delay_samples": d, "spin_speed_rpm": at.spin_speed_rpm,
           "rho_own": rho(0.0), "rho_one_more": rho(1.0)}  # fmt: skip
    if out["rho_own"] >= 1.0 - MARGIN:  # unstable at its own delay: no margin
        return {**out, "margin_samples": 0.0, "margin_us": 0.0}
    lo = 0.0
    for k in range(1, int(MAX_EXTRA_SAMPLES * GRID) + 1):
        hi = k / GRID
        if rho(hi) >= 1.0 - MARGIN:
            break
        lo = hi
    else:
        return {**out, "margin_samples": None, "margin_us": None}
    for _ in range(BISECTIONS):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if rho(mid) < 1.0 - MARGIN else (lo, mid)
    return {**out, "margin_samples": lo, "margin_us": lo * Ts * 1e6}


def margin_text(m: dict) -> str:
    """One phrase for the preflight line."""
    if m["margin_samples"] is None:
        return f"delay margin more than {MAX_EXTRA_SAMPLES:g} samples beyond its {m['delay_samples']}"
    return (f"delay margin {m['margin_samples']:.3g} samples ({m['margin_us']:.0f} us) beyond its "
            f"{m['delay_samples']}")  # fmt: skip
