"""The digital controller as the rig runs it when it is more than the PID: filters after the PID, or the user's
state space; then the amplifier limit and the optional one-sample delay (the order of
:func:`amb_dynamics.control_law.discrete_controller`, whose linear form the analyses use).

A linear stage starts at the steady state of its first input in its fast modes and at zero in its slow stable ones
(:func:`start_map`): the rule of the PID (``y_-1 = y_0``: no derivative kick, empty integrator), so that a state
space equal to the PID runs as the PID, and what an observer-based controller needs (its low-frequency weights are
slow modes: preloading them from one noisy sample kicked the real rig's LQG by 0.3 mm).
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import schur, solve_sylvester

from .amb import DiscretePID, DiscretePIDCoefficients
from .config import RotorConfig
from .control_law import discrete_filters, discrete_user, is_plain_pid
from .state_space import StateSpace

SLOW_MODE = 0.02  # |1 - lambda| below this: a mode slower than ~50 samples (integrators, low-frequency weights)


def start_map(A: np.ndarray, B: np.ndarray, slow: float = SLOW_MODE) -> np.ndarray:
    """x_0 = S y_0: the fixed point x = A x + B y_0 in the modes with |1 - lambda| >= ``slow``, zero in the slower
    stable (or integrating) modes.

    One sample cannot stand for the level a slow mode averages over (it carries the sensor noise and the runout of
    one instant), so those start empty, as the PID's integrator does.  Unstable modes start at their fixed point
    whatever their speed: started anywhere else they run away while the input is held (a realtime plant holds the
    rotor until the loop keeps up).  Computed on an ordered real Schur form, the kept modes decoupled from the cut
    ones by a Sylvester equation: no eigenvector basis, which a controller's non-normal A makes ill-conditioned.
    """
    n = A.shape[0]
    if n == 0:
        return np.zeros((0, B.shape[1]))

    def kept(re, im):
        lam = complex(re, im)
        return abs(1.0 - lam) >= slow or abs(lam) > 1.0 + 1e-6  # an integrator's 1 may come out as 1 + 1e-16

    T, Z, m = schur(A, output="real", sort=kept)
    if m == 0:
        return np.zeros_like(B)
    Z1, Z2 = Z[:, :m], Z[:, m:]
    B1 = Z1.T @ B
    if m < n:  # T = S diag(T11, T22) S^-1 with S = [[I, X], [0, I]]: the kept modes' part of B
        X = solve_sylvester(T[:m, :m], -T[m:, m:], -T[:m, m:])
        B1 = B1 - X @ (Z2.T @ B)
    return Z1 @ np.linalg.solve(np.eye(m) - T[:m, :m], B1)


class LinearStage:
    """x_k+1 = A x_k + B y_k, u_k = C x_k + D y_k, starting at x_0 = :func:`start_map` (A, B) y_0."""

    def __init__(self, ss: StateSpace):
        self.A, self.B, self.C, self.D = ss.A, ss.B, ss.C, ss.D
        self.start = start_map(ss.A, ss.B)
        self.reset()

    @property
    def start_gain(self) -> np.ndarray:
        """u_0 / y_0 of the start rule: the static gain with the slow stable modes left out."""
        return self.D + self.C @ self.start

    def reset(self) -> None:
        self.x: np.ndarray | None = None

    def step(self, y: np.ndarray) -> np.ndarray:
        if self.x is None:
            self.x = self.start @ y
        u = self.C @ self.x + self.D @ y
        self.x = self.A @ self.x + self.B @ y
        return u


class ControlLaw:
    """PID (or the user's state space) -> filters -> clip at current_limit -> optional one-sample delay.

    ``c`` (the PID coefficients) can be changed at run time when there is a PID; ``saturated`` flags the axes
    clipped at the last step, as :class:`amb_dynamics.amb.DiscretePID` does.
    """

    def __init__(
        self,
        cfg: RotorConfig,
        coeffs: DiscretePIDCoefficients,
        current_limit: float | None,
        delay: int = 0,
        n_axes: int = 4,
    ):
        Ts = coeffs.Ts
        self.pid = None
        if cfg.controller.state_space is not None:
            self.first = LinearStage(discrete_user(cfg, Ts, n_axes))
        else:  # the integrator is clamped at the limit; the output is clipped after the filters
            self.pid = DiscretePID(coeffs, n_axes, current_limit, clip=False)
        filters = discrete_filters(cfg, Ts, n_axes)
        self.filters = None if filters is None else LinearStage(filters)
        self.current_limit, self.delay, self.n_axes = current_limit, delay, n_axes
        self.reset()

    @property
    def c(self) -> DiscretePIDCoefficients | None:
        return None if self.pid is None else self.pid.c

    @c.setter
    def c(self, coeffs: DiscretePIDCoefficients) -> None:
        if self.pid is None:
            raise ValueError("the controller is the user's state space: it has no PID gains")
        self.pid.c = coeffs

    @property
    def start_gain(self) -> np.ndarray:
        """Current per displacement of the first step (the PD part of a PID): levitation at rest uses it."""
        K = -self.pid.c.kp * np.eye(self.n_axes) if self.pid is not None else self.first.start_gain
        return K if self.filters is None else self.filters.start_gain @ K

    def reset(self) -> None:
        (self.pid if self.pid is not None else self.first).reset()
        if self.filters is not None:
            self.filters.reset()
        self.saturated = np.zeros(self.n_axes, dtype=bool)
        self.u_prev = np.zeros(self.n_axes)

    def step(self, y: np.ndarray) -> np.ndarray:
        y = np.asarray(y, dtype=float)
        u = self.pid.step(y) if self.pid is not None else self.first.step(y)
        if self.filters is not None:
            u = self.filters.step(u)
        if self.current_limit is not None:
            self.saturated = np.abs(u) > self.current_limit
            u = np.clip(u, -self.current_limit, self.current_limit)
        if self.delay:
            u, self.u_prev = self.u_prev, u
        return u


def new_control_law(
    cfg: RotorConfig, coeffs: DiscretePIDCoefficients, current_limit: float | None, delay: int
) -> DiscretePID | ControlLaw:
    """The digital controller of cfg: the plain DiscretePID, or the ControlLaw of its filters or state space."""
    if is_plain_pid(cfg):
        return DiscretePID(coeffs, 4, current_limit, delay=delay)
    return ControlLaw(cfg, coeffs, current_limit, delay)
