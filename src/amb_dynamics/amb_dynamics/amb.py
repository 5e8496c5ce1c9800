"""The digital AMB controller: discrete PID per axis with filtered derivative (docs/physics.md#sampled).

``DiscretePID`` is the one implementation used by the controller node and by the offline sampled-data
simulation, so that both produce the same numbers.  ``pid_update_matrices`` is its linear form for the
monodromy.  Saturation and integrator clamping are outside the linear analysis (node suite only).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .structure import AMBGains


@dataclass(frozen=True)
class DiscretePIDCoefficients:
    """eta_k = a eta_{k-1} + b (y_k - y_{k-1});  eps_k = eps_{k-1} + Ts y_k;  u_k = -(kp y + kI eps + kd eta)."""

    Ts: float
    kp: float
    kI: float
    kd: float
    a: float
    b: float

    @classmethod
    def from_gains(cls, gains: AMBGains, Ts: float) -> DiscretePIDCoefficients:
        wf = gains.omega_f
        if wf is None:  # backward difference
            a, b = 0.0, 1.0 / Ts
        else:
            a, b = 1.0 / (1.0 + wf * Ts), wf / (1.0 + wf * Ts)
        return cls(Ts, gains.kp, gains.kI, gains.kd, a, b)


class DiscretePID:
    """Discrete PID for ``n_axes`` axes; ``step(y_k)`` returns the current (A) to apply after sample y_k (m):
    u_k, or u_{k-1} with a one-sample computation delay.

    Parameters
    ----------
    coeffs : DiscretePIDCoefficients
    n_axes : int
    current_limit : float or None
        Amplifier saturation (A); the integrator is clamped so that it alone cannot exceed it.
    clip : bool
        Clip the output at current_limit (False when filters follow: :mod:`amb_dynamics.control_runtime`).
    """

    def __init__(
        self,
        coeffs: DiscretePIDCoefficients,
        n_axes: int = 4,
        current_limit: float | None = None,
        delay: int = 0,
        clip: bool = True,
    ):
        self.c = coeffs
        self.clip = clip
        self.n_axes = n_axes
        self.current_limit = current_limit
        self.delay = delay
        self.reset()

    def reset(self) -> None:
        self.eps = np.zeros(self.n_axes)
        self.eta = np.zeros(self.n_axes)
        self.y_prev: np.ndarray | None = None
        self.saturated = np.zeros(self.n_axes, dtype=bool)
        self.u_prev = np.zeros(self.n_axes)

    def step(self, y: np.ndarray) -> np.ndarray:
        c = self.c
        y = np.asarray(y, dtype=float)
        y_prev = y if self.y_prev is None else self.y_prev  # y_{-1} = y_0
        self.eps = self.eps + c.Ts * y
        if self.current_limit is not None and c.kI != 0.0:
            lim = self.current_limit / abs(c.kI)
            self.eps = np.clip(self.eps, -lim, lim)
        self.eta = c.a * self.eta + c.b * (y - y_prev)
        self.y_prev = y.copy()
        u = -(c.kp * y + c.kI * self.eps + c.kd * self.eta)
        if self.current_limit is not None and self.clip:
            self.saturated = np.abs(u) > self.current_limit
            u = np.clip(u, -self.current_limit, self.current_limit)
        if self.delay:  # one-sample computation delay: apply u_{k-1}
            u, self.u_prev = self.u_prev, u
        return u


def pid_update_matrices(coeffs: DiscretePIDCoefficients, n_axes: int, use_int: bool, use_eta: bool, use_delay: bool):
    """Linear form of one controller update on the memory m_{k-1} = [eps; y; eta; u]_{k-1} (used parts).

    Returns (Py, Pm, Uy, Um, parts): m_k = Py y_k + Pm m_{k-1} and u_k = Uy y_k + Um m_{k-1};
    ``parts`` names the blocks of m in order.
    """
    c = coeffs
    Id = np.eye(n_axes)
    parts = [
        p
        for p, on in (
            ("eps", use_int),
            ("y", use_eta),
            ("eta", use_eta and c.a != 0.0),
            ("u", use_delay),
        )
        if on
    ]
    nm = n_axes * len(parts)
    blk = {p: slice(n_axes * i, n_axes * (i + 1)) for i, p in enumerate(parts)}
    Py, Pm = np.zeros((nm, n_axes)), np.zeros((nm, nm))
    # eps_k, eta_k as maps of (y_k, m_{k-1})
    eps_y, eps_m = c.Ts * Id, np.zeros((n_axes, nm))
    if "eps" in blk:
        eps_m[:, blk["eps"]] = Id
    eta_y, eta_m = c.b * Id, np.zeros((n_axes, nm))
    if "y" in blk:
        eta_m[:, blk["y"]] = -c.b * Id
    if "eta" in blk:
        eta_m[:, blk["eta"]] = c.a * Id
    Uy = -(c.kp * Id + (c.kI * eps_y if use_int else 0.0) + (c.kd * eta_y if use_eta else 0.0))
    Um = -((c.kI * eps_m if use_int else 0.0) + (c.kd * eta_m if use_eta else 0.0)) + np.zeros((n_axes, nm))
    if "eps" in blk:
        Py[blk["eps"]], Pm[blk["eps"]] = eps_y, eps_m
    if "y" in blk:
        Py[blk["y"]] = Id
    if "eta" in blk:
        Py[blk["eta"]], Pm[blk["eta"]] = eta_y, eta_m
    if "u" in blk:
        Py[blk["u"]], Pm[blk["u"]] = Uy, Um
    return Py, Pm, Uy, Um, tuple(parts)
