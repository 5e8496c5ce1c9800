"""Offline snapshots for the Floquet estimator: the lockstep loop with excitation, fast for periodic motion.

``SampledLoop.simulate`` recomputes a matrix exponential whenever the base sample is new; for a periodic
base motion whose period is a whole number K of samples the step maps repeat, so this module computes the
K closed-loop maps F_k = ``loop.step_map`` once and then steps

    X_{k+1} = F_{k mod K} X_k + [g_k + Gamma_k e_k; 0]

with X = [q; q'; controller memory] (docs/physics.md#sampled), g_k the base-motion forcing and e_k an optional random
current added to the controller output (the node suite's excitation injection, or amplifier noise).  It is
the same closed loop as ``SampledLoop.simulate`` (tests compare them) plus the excitation, and it can start
on the forced periodic orbit (a fully decayed rotor).  Measurement noise is added to the snapshots only.
"""

from __future__ import annotations

import numpy as np

from ..amb import pid_update_matrices
from ..errors import InputError
from ..motion import BaseMotion
from ..sampled import SampledLoop, SampledRun

PERIOD_MATCH_TOL = 1e-9  # relative: T/Ts must be this close to an integer for the cyclic step maps


class SnapshotSimulator:
    """Closed loop of ``loop`` under a periodic ``motion`` with step maps reused every ``cycle`` samples.

    Parameters
    ----------
    loop : SampledLoop
        Plant stepper and discrete PID (ZOH, optional one-sample delay).
    motion : BaseMotion
        Periodic base motion whose fundamental period is an integer number of samples.
    """

    def __init__(self, loop: SampledLoop, motion: BaseMotion):
        T0 = motion.fundamental_period()
        if T0 is None:
            raise InputError("the snapshot simulator needs a periodic base motion")
        ratio = T0 / loop.Ts
        K = round(ratio)
        if K < 1 or abs(ratio - K) > PERIOD_MATCH_TOL * ratio:
            raise InputError(f"base period / Ts = {ratio:.9g} is not an integer: choose omega with T = N*Ts")
        if not loop.plain_pid:
            raise InputError("the snapshot simulator runs the plain PID (no controller.filters or state_space)")
        self.loop, self.motion, self.cycle = loop, motion, K
        g = loop.model.gains
        self.parts = pid_update_matrices(loop.pid_coeffs, 4, g.kI != 0.0, g.kd != 0.0, loop.delay > 0)[4]
        t = np.arange(K) * loop.Ts
        Om, dOm = motion.angular_velocity(t)
        n2 = 2 * loop.model.n
        self.n2 = n2
        self.F = np.array([loop.step_map(Om[:, k], dOm[:, k]) for k in range(K)])  # (K, dim, dim)
        mats = [loop.plant.matrices(Om[:, k], dOm[:, k]) for k in range(K)]
        self.Gamma = np.array([m[1] for m in mats])  # (K, 2n, 4) current input (A -> state)
        self.g = np.array([m[2] for m in mats])  # (K, 2n) base-motion forcing over the step
        self.dim = self.F.shape[1]

    def initial_state(self, x0: np.ndarray) -> np.ndarray:
        """Closed-loop state X_0 for plant state x0 with the simulator's start rule (y_{-1} = y_0, rest 0)."""
        x0 = np.asarray(x0, dtype=float)
        if x0.shape != (self.n2,):
            raise InputError(f"initial plant state must have shape ({self.n2},), got {x0.shape}")
        X = np.zeros(self.dim)
        X[: self.n2] = x0
        if "y" in self.parts:
            j = self.parts.index("y")
            X[self.n2 + 4 * j : self.n2 + 4 * j + 4] = self.loop.plant.output(x0)
        return X

    def periodic_orbit(self) -> np.ndarray:
        """Closed-loop state X* at t = 0 of the forced periodic response (the rotor after all transients).

        X* = (I - Phi_K)^-1 h_K with Phi_K = F_{K-1}...F_0 and h_K the response to the forcing from rest.
        """
        Phi = np.eye(self.dim)
        h = np.zeros(self.dim)
        for k in range(self.cycle):
            Phi = self.F[k] @ Phi
            h = self.F[k] @ h
            h[: self.n2] += self.g[k]
        return np.linalg.solve(np.eye(self.dim) - Phi, h)

    def run(
        self,
        steps: int,
        X0: np.ndarray,
        excitation_std: float = 0.0,
        rng: np.random.Generator | None = None,
    ) -> tuple[SampledRun, np.ndarray]:
        """Simulate ``steps`` samples from closed-loop state X0 (use ``initial_state`` or ``periodic_orbit``).

        Parameters
        ----------
        excitation_std : float
            Standard deviation (A) of the white random current added to each axis' command per sample.

        Returns
        -------
        run : SampledRun
            t (K+1,), plant states x (K+1, 2n), outputs y (K+1, 4), applied currents i (K, 4) (A).
        X : np.ndarray, shape (K+1, dim)
            Closed-loop states (plant state and controller memory).
        """
        if steps < 1:
            raise InputError("steps must be >= 1")
        if excitation_std < 0 or not np.isfinite(excitation_std):
            raise InputError(f"excitation_std must be a finite number >= 0 (got {excitation_std})")
        rng = rng if rng is not None else np.random.default_rng()
        K, n2 = self.cycle, self.n2
        e = excitation_std * rng.standard_normal((steps, 4)) if excitation_std > 0 else np.zeros((steps, 4))
        X = np.empty((steps + 1, self.dim))
        X[0] = X0
        for k in range(steps):
            j = k % K
            X[k + 1] = self.F[j] @ X[k]
            X[k + 1, :n2] += self.g[j] + self.Gamma[j] @ e[k]
        x = X[:, :n2]
        y = x[:, : self.loop.model.n] @ self.loop.model.Ba
        cur = self._currents(X[:-1], y[:-1]) + e
        t = np.arange(steps + 1) * self.loop.Ts
        return SampledRun(t, x.copy(), y, cur), X

    def _currents(self, X: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Controller output (A) of each step from the closed-loop states (for reports; linear PID)."""
        g = self.loop.model.gains
        _, _, Uy, Um, parts = pid_update_matrices(
            self.loop.pid_coeffs, 4, g.kI != 0.0, g.kd != 0.0, self.loop.delay > 0
        )
        mem = X[:, self.n2 :]
        if self.loop.delay:
            j = parts.index("u")
            return mem[:, 4 * j : 4 * j + 4]
        return y @ Uy.T + mem @ Um.T


def add_measurement_noise(S: np.ndarray, relative: float, rng: np.random.Generator) -> np.ndarray:
    """S + white noise with per-channel std ``relative`` * RMS of that channel over the record.

    S : (K, c) snapshots (rows = samples); returns a new array of the same shape.
    """
    rms = np.sqrt(np.mean(np.square(S), axis=0))
    return S + relative * rms * rng.standard_normal(S.shape)
