"""The sampled-data closed loop that the node suite runs (docs/physics.md#sampled).

Between samples the plant is continuous with the current held (zero-order hold) and the base motion held
at its sample (Omega_k, dOmega_k), exactly as the plant node receives it from /base/imu.  One step is

    xp_{k+1} = E_k xp_k + Gamma_k i_k + g_k,    [[E, Gamma, g], [0, I, 0], [0, 0, 1]] = expm(Ts * Aaug_k)

``PlantStepper`` is the one-step propagator of the plant node; ``SampledLoop`` adds the digital controller
(the discrete PID of :mod:`amb_dynamics.amb`, with its filters or the user's state space:
:mod:`amb_dynamics.control_law`) and gives the step maps F_k (for the monodromy) and the offline simulation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from .amb import DiscretePID, DiscretePIDCoefficients
from .config import RotorConfig
from .control_law import discrete_controller, is_plain_pid
from .control_runtime import ControlLaw, new_control_law
from .motion import BaseMotion
from .plant_dynamics import PlantDynamics, StateLayout, open_loop_plant
from .structure import StructuralModel
from .system import COEFFICIENTS, coefficients_from_rates, forcing_from_rates, parametric_matrices

CACHE_LIMIT = 4096  # step matrices kept for repeated base samples (a static or periodic base)


class PlantStepper:
    """Exact ZOH propagation of the open-loop plant xp = [q; q'] (plus amplifier and sensor-filter states,
    :mod:`amb_dynamics.plant_dynamics`) over one sample period Ts.

    Parameters
    ----------
    model : StructuralModel
    cfg : RotorConfig (formulation, drive model, axial stiffening)
    Ts : float, sample period (s)
    forcing : bool or None, include the base-motion forcing f(t) (docs/physics.md#forcing); None: cfg.base_forcing
    dynamics : PlantDynamics or None, amplifier/sensor/shaft-damping additions; None: from cfg
    """

    def __init__(
        self,
        model: StructuralModel,
        cfg: RotorConfig,
        Ts: float,
        forcing: bool | None = None,
        dynamics: PlantDynamics | None = None,
    ):
        forcing = cfg.base_forcing if forcing is None else forcing
        n = model.n
        self.n, self.Ts, self.model = n, Ts, model
        self.spin = cfg.spin_rad_s
        Minv = sla.inv(model.M)
        self.dynamics = PlantDynamics.from_config(cfg) if dynamics is None else dynamics
        if self.dynamics.augmented:  # amplifier lag, sensor filter, shaft damping (plant_dynamics)
            self.Ap0, self.Bp, self.Cm, self.Cy, self.layout = open_loop_plant(model, self.dynamics, Minv)
        else:  # the paper's plant: x_p = [q; q'], ideal current source and sensor
            Kp = (
                model.matrices.shaft_stiffness + model.gains.ks * model.Ba @ model.Ba.T
            )  # negative stiffness, not sampled
            self.Ap0 = np.zeros((2 * n, 2 * n))
            self.Ap0[:n, n:] = np.eye(n)
            self.Ap0[n:, :n] = -Minv @ Kp
            if model.matrices.structural_damping is not None:  # of the shaft (damping.py)
                self.Ap0[n:, n:] = -Minv @ model.matrices.structural_damping
            self.Bp = np.zeros((2 * n, 4))
            self.Bp[n:] = Minv @ model.Ba * model.gains.ki
            self.layout = StateLayout.of(n, self.dynamics)
            self.Cm = self.Cy = None
        N = self.N = self.layout.N
        terms = [
            (COEFFICIENTS.index(name), Kj, Dj)
            for name, (Kj, Dj) in parametric_matrices(model, cfg).items()
            if Kj.any() or Dj.any()
        ]
        # A_p(c) = Ap0 + sum_j c[idx_j] Ap_stack[j]: one tensordot per step instead of a Python sum
        self.Ap_idx = np.array([j for j, _, _ in terms], dtype=int)
        self.Ap_stack = np.zeros((len(terms), N, N))
        for j, (_, Kj, Dj) in enumerate(terms):
            self.Ap_stack[j, n : 2 * n, :n], self.Ap_stack[j, n : 2 * n, n : 2 * n] = -Minv @ Kj, -Minv @ Dj
        self.Bf = np.zeros((N, 4))
        if forcing:
            self.Bf[n : 2 * n] = Minv @ model.forcing
        self._cache: dict[bytes, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}

    def set_bearing_gains(self, ki: np.ndarray, ks: np.ndarray) -> None:
        """Per-axis current gain ki (N/A) and negative stiffness ks (N/m) in place of the config's (the bearing law
        linearised at an operating point: :mod:`amb_dynamics.operating_point`).  Each call replaces the previous
        one (the gains along an orbit: :mod:`amb_dynamics.forced_orbit`)."""
        model, n = self.model, self.n
        if not hasattr(self, "_config_matrices"):
            self._config_matrices = (self.Ap0, self.Bp, sla.inv(model.M) @ model.Ba)
        Ap0, Bp, MinvBa = self._config_matrices
        self.Ap0 = Ap0.copy()
        self.Ap0[n : 2 * n, :n] -= (MinvBa * (np.asarray(ks) - model.gains.ks)) @ model.Ba.T
        force = MinvBa * np.asarray(ki)  # current -> acceleration (columns scaled per axis)
        if self.layout.amp is not None:
            self.Ap0[n : 2 * n, self.layout.amp] = force
        else:
            self.Bp = Bp.copy()
            self.Bp[n : 2 * n] = force
        self._cache.clear()

    @property
    def labels(self) -> tuple[str, ...]:
        """Names of the plant state x_p: q, d_q, then amp_<channel> and sens_<channel> when present."""
        return self.layout.labels(self.model.dof_names, self.model.channels)

    def matrices(self, Omega: np.ndarray, dOmega: np.ndarray):
        """(E, Gamma, g) for base rates held at (Omega, dOmega) over the step."""
        key = np.concatenate([Omega, dOmega]).tobytes()
        hit = self._cache.get(key)
        if hit is not None:
            return hit
        c = coefficients_from_rates(np.asarray(Omega, float), np.asarray(dOmega, float), self.spin)
        a = forcing_from_rates(np.asarray(Omega, float), np.asarray(dOmega, float), self.spin)
        n2 = self.N
        aug = np.zeros((n2 + 5, n2 + 5))
        aug[:n2, :n2] = self.Ap0 + np.tensordot(c[self.Ap_idx], self.Ap_stack, axes=1)
        aug[:n2, n2 : n2 + 4] = self.Bp
        aug[:n2, n2 + 4] = self.Bf @ a
        Phi = sla.expm(self.Ts * aug)
        out = (Phi[:n2, :n2], Phi[:n2, n2 : n2 + 4], Phi[:n2, n2 + 4])
        if len(self._cache) < CACHE_LIMIT:
            self._cache[key] = out
        return out

    def step(self, xp: np.ndarray, current: np.ndarray, Omega: np.ndarray, dOmega: np.ndarray) -> np.ndarray:
        E, G, g = self.matrices(Omega, dOmega)
        return E @ xp + G @ current + g

    def output(self, xp: np.ndarray) -> np.ndarray:
        """What the sensors report (m), channels of model.channels: y = Ba^T q, or the filtered y_f."""
        if self.layout.sens is not None:
            return xp[self.layout.measured].copy()
        return self.model.Ba.T @ xp[: self.n]

    def displacement(self, xp: np.ndarray) -> np.ndarray:
        """True AMB displacements y = Ba^T q (m)."""
        return self.model.Ba.T @ xp[: self.n]


@dataclass
class SampledRun:
    """Offline sampled-data simulation result (k = 0..steps)."""

    t: np.ndarray  # (K+1,) s
    x: np.ndarray  # (K+1, 2n) plant state at t_k
    y: np.ndarray  # (K+1, 4) sampled displacement (m)
    i: np.ndarray  # (K, 4) applied current on [t_k, t_k+1) (A)


class SampledLoop:
    """Plant stepper + digital controller at rate 1/Ts (ZOH, optional one-sample delay)."""

    def __init__(
        self,
        model: StructuralModel,
        cfg: RotorConfig,
        Ts: float | None = None,
        delay_samples: int | None = None,
        forcing: bool | None = None,
        dynamics: PlantDynamics | None = None,
        bearing: tuple[np.ndarray, np.ndarray] | None = None,
    ):
        self.Ts = Ts if Ts is not None else 1.0 / cfg.controller.rate_hz
        self.cfg, self.model = cfg, model
        self.delay = cfg.controller.delay_samples if delay_samples is None else delay_samples
        self.plant = PlantStepper(model, cfg, self.Ts, forcing=forcing, dynamics=dynamics)
        # per-axis (ki, ks) in place of the config's (a nonlinear law at its operating point); kept by sub_loop
        self.bearing = bearing
        if bearing is not None:
            self.plant.set_bearing_gains(*bearing)
        self.pid_coeffs = DiscretePIDCoefficients.from_gains(model.gains, self.Ts)
        self.plain_pid = is_plain_pid(cfg)
        # its linear form: X = [xp; controller state], x_k+1 = Ak x_k + Bk y_k, u_k = Ck x_k + Dk y_k
        self.controller = discrete_controller(cfg, model.gains, self.Ts, self.delay)

    def sub_loop(self, Ts: float) -> SampledLoop:
        """The same loop (model, config, delay, bearing gains; forcing off) sampled at ``Ts``."""
        return SampledLoop(self.model, self.cfg, Ts=Ts, delay_samples=self.delay, forcing=False, bearing=self.bearing)

    def new_controller(self, current_limit: float | None = None) -> DiscretePID | ControlLaw:
        return new_control_law(self.cfg, self.pid_coeffs, current_limit, self.delay)

    def simulate(self, motion: BaseMotion, steps: int, x0: np.ndarray) -> SampledRun:
        """The closed loop exactly as the node suite runs it (lockstep), without saturation."""
        n2 = self.plant.N
        t = np.arange(steps + 1) * self.Ts
        Om, dOm = motion.angular_velocity(t)
        x = np.empty((steps + 1, n2))
        y = np.empty((steps + 1, 4))
        cur = np.empty((steps, 4))
        x[0] = 0.0
        x[0, : len(x0)] = x0  # a [q; q'] initial state leaves the amplifier and filter states at zero
        pid = self.new_controller()
        for k in range(steps):
            y[k] = self.plant.output(x[k])
            cur[k] = pid.step(y[k])
            x[k + 1] = self.plant.step(x[k], cur[k], Om[:, k], dOm[:, k])
        y[steps] = self.plant.output(x[steps])
        return SampledRun(t, x, y, cur)

    def step_map(self, Omega: np.ndarray, dOmega: np.ndarray) -> np.ndarray:
        """F_k on X_k = [xp(t_k); controller state] (docs/physics.md#sampled), for rates held over the step."""
        K = self.controller
        E, Gam, _ = self.plant.matrices(Omega, dOmega)
        n, n2, nm = self.model.n, self.plant.N, K.n_states
        if self.plant.Cm is not None:
            Cy = self.plant.Cm
        else:
            Cy = np.zeros((4, n2))
            Cy[:, :n] = self.model.Ba.T
        F = np.zeros((n2 + nm, n2 + nm))
        F[:n2, :n2] = E + Gam @ K.D @ Cy
        F[:n2, n2:] = Gam @ K.C
        F[n2:, :n2] = K.B @ Cy
        F[n2:, n2:] = K.A
        return F
