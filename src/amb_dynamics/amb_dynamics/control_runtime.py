"""The digital controller as the rig runs it when it is more than the PID: filters after the PID, or the user's
state space; then the amplifier limit and the optional one-sample delay (the order of
:func:`amb_dynamics.control_law.discrete_controller`, whose linear form the analyses use).

A linear stage starts at the steady state of its first input with its integrating modes at zero, the rule of the
PID (``y_-1 = y_0``: no derivative kick, empty integrator), so that a state space equal to the PID runs as the PID.
"""

from __future__ import annotations

import numpy as np

from .amb import DiscretePID, DiscretePIDCoefficients
from .config import RotorConfig
from .control_law import discrete_filters, discrete_user, is_plain_pid
from .state_space import StateSpace


class LinearStage:
    """x_k+1 = A x_k + B y_k, u_k = C x_k + D y_k, starting at x_0 = pinv(I - A) B y_0."""

    def __init__(self, ss: StateSpace):
        self.A, self.B, self.C, self.D = ss.A, ss.B, ss.C, ss.D
        n = ss.n_states
        self.start = np.linalg.pinv(np.eye(n) - ss.A) @ ss.B if n else np.zeros((0, ss.B.shape[1]))
        self.reset()

    @property
    def start_gain(self) -> np.ndarray:
        """u_0 / y_0 of the start rule: the static gain with the integrating modes left out."""
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
