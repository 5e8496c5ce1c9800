"""A model-based digital controller for the rig: LQG on the sampled plant, with the loop's computation delay.

The plant is the digital loop's own (:func:`amb_dynamics.sensitivity.sampled_plant_state_space`: the full FE rotor
with its amplifier, sensor filter and shaft damping, ZOH at the controller's rate), x_k+1 = F x_k + G i_k,
y_k = H x_k.  With one sample of computation delay the current computed from y_k acts from t_k+1 on, so the design
plant carries the delay as four more states; four more carry a low-pass of the displacements, z_k+1 = a z_k +
(1 - a) y_k (a = exp(-2 pi f_z Ts)), the frequency weight that gives the bearing its static stiffness without
a large gain at high frequency: xa = [x; i_k-1; z].

- State feedback u_k = -L xa_k|k minimises sum(q_y |y_k|^2 + q_z |z_k|^2 + q_v |q'_k|^2 + |u_k|^2) (q' the
  structural velocities, which damp every mode): L from the discrete algebraic Riccati equation.
- Kalman filter with current-sample correction: xa_k|k = xa_k|k-1 + M (y_k - Ha xa_k|k-1), noises sigma_i^2 G G^T
  at the amplifier input and sigma_y^2 I on the sensors.  Gyroscopic robustness: the spin speed changes F, so
  the filter also assumes process noise q_Omega (dF0 dF0^T + dF1 dF1^T), dF0 = F(0) - F(design speed) and
  dF1 = F(max speed) - F(design speed): an observer that trusts the design speed's model less where the speed
  changes it (without this term a design at mid speed loses stability at the ends of the range).

The controller (x_c = xa_k|k-1, input y_k, output the current for the next sample) is returned as a discrete
state space to be run with ``controller.delay_samples: 1``; ``tools/lqg_design.py`` writes it into a rotor file
and checks it on perturbed plants.

Without delay the design may weigh the current's increment instead of the current (``increment_weight`` r_d > 0):
xa = [x; i_k-1; z], input du_k = i_k - i_k-1, cost ... + |i_k-1|^2 + r_d |du_k|^2.  A real amplifier slews (the
coil's voltage limit), and a controller that asks for large steps each sample saturates it: at 1 kHz the
plain design did (docs/real-rig.md).  The controller's output is then i_k = i_k-1|k + du_k.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from .config import RotorConfig
from .errors import InputError
from .sensitivity import sampled_plant_state_space
from .state_space import StateSpace
from .structure import StructuralModel


@dataclass(frozen=True)
class LqgWeights:
    """Design weights (SI): currents in A, displacements in m."""

    output_weight: float  # q_y, A^2/m^2: weight of the measured displacements against the currents
    low_frequency_weight: float  # q_z, A^2/m^2: weight of the displacements' low-pass z (static stiffness)
    low_frequency_corner_hz: float  # f_z, Hz: the low-pass's corner
    velocity_weight: float  # q_v, A^2 s^2/m^2: weight of the structural velocities (damps every mode)
    input_noise_a: float  # sigma_i, A rms: process noise at the amplifier inputs
    sensor_noise_m: float  # sigma_y, m rms: sensor noise the filter assumes
    speed_noise: float  # q_Omega: weight of the speed-dependent part of the step matrix
    design_speed_rpm: float = 1500.0
    delay_samples: int = 1
    increment_weight: float = 0.0  # r_d: weight of the current's increment u_k - u_k-1 (0: none; needs no delay)

    def __post_init__(self):
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if not np.isfinite(v) or v < 0:
                raise InputError(f"LQG weight {f.name} must be finite and >= 0 (got {v!r})")
        if self.delay_samples not in (0, 1):
            raise InputError(f"LQG delay_samples must be 0 or 1 (got {self.delay_samples!r})")
        if self.increment_weight and self.delay_samples:
            raise InputError("LQG increment_weight needs delay_samples 0 (the increment form stores the last current)")


def design_plant(F: np.ndarray, G: np.ndarray, H: np.ndarray, delay: int, a: float, increment: bool = False):
    """(Fa, Ga, Ha): the plant with ``delay`` samples (0 or 1) of input delay and the low-pass z (pole a) of its
    outputs as extra states, [x; i_k-1; z] (no i_k-1 without delay).  ``increment`` (no delay): [x; i_k-1; z]
    with the increment i_k - i_k-1 as the input, i_k = i_k-1 + du_k acting at once."""
    n, m = G.shape
    d = m if delay or increment else 0
    Fa = np.zeros((n + d + m, n + d + m))
    Fa[:n, :n] = F
    Ga = np.zeros((n + d + m, m))
    if delay or increment:
        Fa[:n, n : n + d] = G
        Ga[n : n + d] = np.eye(m)
    if increment:
        Fa[n : n + d, n : n + d] = np.eye(m)
    if not delay:
        Ga[:n] = G
    Fa[n + d :, :n] = (1.0 - a) * H
    Fa[n + d :, n + d :] = a * np.eye(m)
    Ha = np.zeros((m, n + d + m))
    Ha[:, :n] = H
    return Fa, Ga, Ha


def lqg_controller(model: StructuralModel, cfg: RotorConfig, w: LqgWeights) -> StateSpace:
    """The discrete controller u = K(z) y_m at the config's rate (feedback sign included); run it with
    controller.delay_samples = w.delay_samples."""
    Ts = 1.0 / cfg.controller.rate_hz
    at = dataclasses.replace(cfg, spin_speed_rpm=w.design_speed_rpm)
    P = sampled_plant_state_space(model, at, Ts, w.design_speed_rpm)
    F, G, H = P.A, P.B, P.C
    a = float(np.exp(-2.0 * np.pi * w.low_frequency_corner_hz * Ts))
    increment = w.increment_weight > 0
    Fa, Ga, Ha = design_plant(F, G, H, w.delay_samples, a, increment)
    n, na, m = F.shape[0], Fa.shape[0], G.shape[1]
    Q = w.output_weight * Ha.T @ Ha
    vel = np.arange(model.n, 2 * model.n)  # the plant state is [q; q'; amplifier; sensor]
    Q[vel, vel] += w.velocity_weight
    Q[na - m :, na - m :] += w.low_frequency_weight * np.eye(m)
    if increment:  # the current's own weight (1, as R below otherwise), a sample late; R weighs the increment
        Q[n : n + m, n : n + m] += np.eye(m)
    Q += 1e-14 * np.trace(Q) / na * np.eye(na)  # positive definite: every state is weighted a little
    R = (w.increment_weight if increment else 1.0) * np.eye(m)
    W = np.zeros((na, na))
    W[:n, :n] = w.input_noise_a**2 * G @ G.T
    for rpm in (0.0, max(cfg.max_speed_rpm or 0.0, w.design_speed_rpm)):  # the ends of the speed range
        dF = sampled_plant_state_space(model, dataclasses.replace(at, spin_speed_rpm=rpm), Ts, rpm).A - F
        W[:n, :n] += w.speed_noise * dF @ dF.T
    W += 1e-24 * np.eye(na)
    V = w.sensor_noise_m**2 * np.eye(m)
    try:
        X = sla.solve_discrete_are(Fa, Ga, Q, R)
        Y = sla.solve_discrete_are(Fa.T, Ha.T, W, V)
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise InputError(f"LQG design failed (Riccati equation: {exc}); change the weights") from None
    L = np.linalg.solve(R + Ga.T @ X @ Ga, Ga.T @ X @ Fa)
    M = Y @ Ha.T @ np.linalg.inv(Ha @ Y @ Ha.T + V)
    closed = Fa - Ga @ L
    update = np.eye(na) - M @ Ha
    out = -L  # the current from xa_k|k: -L xa, or with increments i_k-1 - L xa (i_k-1 is the controller's own)
    if increment:
        out[:, n : n + m] += np.eye(m)
    return StateSpace(closed @ update, closed @ M, out @ update, out @ M, Ts)
