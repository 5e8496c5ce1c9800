"""Actuator, sensor and shaft-damping dynamics of a real rig, added to the linear plant (continuous and sampled).

Models (each off when its config value is null or 0, and then the loop is exactly the paper's):

* Amplifier as a current loop: i_a' = w_a (i_c - i_a), a first-order lag of bandwidth w_a (rad/s) between the
  commanded current i_c and the coil current i_a; the AMB force is ki i_a + ks y.  The voltage limit (slew rate
  |di_a/dt| <= V/L) and the current clamp are nonlinear and live in the rig stepper (:mod:`amb_dynamics.rig_plant`).
* Sensor anti-alias filter on each AMB displacement y = Ba^T q, corner w_s (rad/s): first order
  y_f' = w_s (y - y_f), or second-order Butterworth y_f'' = w_s^2 (y - y_f) - sqrt(2) w_s y_f'; the controller
  sees y_f (sampled in the digital loop).
* Structural damping of the shaft, viscous, in the non-rotating frame (rotating internal damping, whose
  circulatory term destabilises above the first critical speed, is not modelled): Rayleigh D_s = alpha M + beta K_B
  (K_B the free-free shaft stiffness; a flexural mode of frequency w gets the damping ratio alpha/(2w) + beta w/2,
  so stiffness-proportional damping damps the 6-element mesh's top modes (~3.5e4 rad/s) strongly and the first
  bending modes little), or a loss factor eta (damping ratio eta/2 in every flexural mode of (M, K_B)).

The extra states are appended to the plant state: x_p = [q; q'; i_a (4, with the amplifier); y_f (4, with the
filter); y_f' (4, second-order filter)], labels ``amp_<channel>``, ``sens_<channel>``, ``dsens_<channel>``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from .config import RotorConfig
from .structure import StructuralModel


@dataclass(frozen=True)
class PlantDynamics:
    """The linear real-rig additions; None / 0 switches one off.

    amplifier_rad_s : current-loop bandwidth w_a (rad/s)
    sensor_rad_s : anti-alias corner w_s (rad/s)
    sensor_order : 1 (first order) or 2 (Butterworth, zeta = 1/sqrt 2)
    damping : (model, alpha 1/s, beta s, loss factor) of the shaft, model "none" | "rayleigh" | "loss_factor"
    """

    amplifier_rad_s: float | None = None
    sensor_rad_s: float | None = None
    sensor_order: int = 1
    damping: tuple[str, float, float, float] = ("none", 0.0, 0.0, 0.0)

    @property
    def damped(self) -> bool:
        model, alpha, beta, eta = self.damping
        return (model == "rayleigh" and (alpha != 0.0 or beta != 0.0)) or (model == "loss_factor" and eta != 0.0)

    @property
    def augmented(self) -> bool:
        """True if the plant has states beyond [q; q'] or damping beyond the paper's."""
        return self.amplifier_rad_s is not None or self.sensor_rad_s is not None or self.damped

    @classmethod
    def from_config(cls, cfg: RotorConfig) -> PlantDynamics:
        amp_hz, sens = cfg.actuator.bandwidth_hz, cfg.sensor
        return cls(  # the shaft damping of the config is already in the model's D_s (damping.py)
            None if amp_hz is None else 2 * math.pi * amp_hz,
            None if sens.filter_hz is None else 2 * math.pi * sens.filter_hz,
            sens.filter_order,
        )


def structural_damping(model: StructuralModel, dyn: PlantDynamics) -> np.ndarray | None:
    """D_s of the shaft in the model's coordinates (N s/m), or None when off.

    rayleigh: alpha M + beta K_B (K_B: the free-free shaft, no bearing); loss_factor: M Phi diag(eta w_i) Phi^T M
    over the mass-normalised modes Phi of (M, K_B), i.e. damping ratio eta/2 in every flexural mode, none in the
    rigid-body modes (w_i below 1e-6 of the highest).
    """
    if not dyn.damped:  # from the config: D_s is in the model (damping.py, projected with the modal basis)
        Ds = model.matrices.structural_damping
        return Ds if Ds is not None and Ds.any() else None
    kind, alpha, beta, eta = dyn.damping
    M, K = model.matrices.mass, model.matrices.shaft_stiffness
    if kind == "rayleigh":
        return alpha * M + beta * K
    w2, Phi = sla.eigh(K, M)
    w = np.sqrt(np.clip(w2, 0.0, None))
    w[w < 1e-6 * w.max()] = 0.0
    MP = M @ Phi
    return (MP * (eta * w)) @ MP.T


@dataclass(frozen=True)
class StateLayout:
    """Index blocks of the augmented plant state [q; q'; i_a; y_f] (slices; None = absent)."""

    n: int
    amp: slice | None
    sens: slice | None
    N: int

    @classmethod
    def of(cls, n: int, dyn: PlantDynamics, na: int = 4) -> StateLayout:
        i = 2 * n
        amp = sens = None
        if dyn.amplifier_rad_s is not None:
            amp, i = slice(i, i + na), i + na
        if dyn.sensor_rad_s is not None:
            m = na * dyn.sensor_order
            sens, i = slice(i, i + m), i + m
        return cls(n, amp, sens, i)

    @property
    def measured(self) -> slice | None:
        """The filtered displacements y_f (the first block of the sensor states)."""
        return None if self.sens is None else slice(self.sens.start, self.sens.start + 4)

    def labels(self, dof_names: tuple[str, ...], channels: tuple[str, ...]) -> tuple[str, ...]:
        sens = ()
        if self.sens is not None:
            sens = tuple(f"sens_{c}" for c in channels)
            if self.sens.stop - self.sens.start > len(channels):
                sens += tuple(f"dsens_{c}" for c in channels)
        return (
            *dof_names,
            *(f"d_{d}" for d in dof_names),
            *((f"amp_{c}" for c in channels) if self.amp else ()),
            *sens,
        )


def open_loop_plant(model: StructuralModel, dyn: PlantDynamics, Minv: np.ndarray):
    """Continuous plant x_p' = Ap x_p + Bp i_c, measured y_m = Cm x_p, true y = Cy x_p (no base motion, no spin).

    Returns (Ap, Bp, Cm, Cy, layout); Bp is the input of the commanded current (A), ks acts on the true y.
    """
    n, Ba, g = model.n, model.Ba, model.gains
    lay = StateLayout.of(n, dyn, Ba.shape[1])
    N = lay.N
    Ap = np.zeros((N, N))
    Ap[:n, n : 2 * n] = np.eye(n)
    Ap[n : 2 * n, :n] = -Minv @ (model.matrices.shaft_stiffness + g.ks * Ba @ Ba.T)
    Ds = structural_damping(model, dyn)
    if Ds is not None:
        Ap[n : 2 * n, n : 2 * n] = -Minv @ Ds
    Bp = np.zeros((N, Ba.shape[1]))
    if lay.amp is not None:
        wa = dyn.amplifier_rad_s
        Ap[n : 2 * n, lay.amp] = Minv @ Ba * g.ki
        Ap[lay.amp, lay.amp] = -wa * np.eye(Ba.shape[1])
        Bp[lay.amp] = wa * np.eye(Ba.shape[1])
    else:
        Bp[n : 2 * n] = Minv @ Ba * g.ki
    Cy = np.zeros((Ba.shape[1], N))
    Cy[:, :n] = Ba.T
    if lay.sens is not None:
        ws, na, f = dyn.sensor_rad_s, Ba.shape[1], lay.measured
        I = np.eye(na)
        if dyn.sensor_order == 1:  # y_f' = ws (y - y_f)
            Ap[f, :n] = ws * Ba.T
            Ap[f, f] = -ws * I
        else:  # y_f'' = ws^2 (y - y_f) - sqrt(2) ws y_f'  (Butterworth)
            d = slice(f.stop, f.stop + na)
            Ap[f, d] = I
            Ap[d, :n] = ws * ws * Ba.T
            Ap[d, f] = -ws * ws * I
            Ap[d, d] = -math.sqrt(2.0) * ws * I
        Cm = np.zeros_like(Cy)
        Cm[:, f] = I
    else:
        Cm = Cy
    return Ap, Bp, Cm, Cy, lay


def closed_loop_matrix(model: StructuralModel, dyn: PlantDynamics, Minv: np.ndarray):
    """A0 of the continuous closed loop with the plant dynamics and the continuous PID of docs/physics.md#controller.

    States [q; q'; e (integral, if kI); z (derivative filter, if wf); i_a; y_f].  The PID acts on the measured
    y_m = Cm x: i_c = -(kp y_m + kI e + kd D), D = y_m' (ideal) or wf (y_m - z) (filtered), e' = y_m,
    z' = wf (y_m - z).  Returns (A0, N_plant_layout, controller state counts (ne, nf)).
    """
    Ap, Bp, Cm, _, lay = open_loop_plant(model, dyn, Minv)
    g = model.gains
    na = model.Ba.shape[1]
    use_int, use_filt = g.kI != 0.0, g.omega_f is not None
    ne, nf = (na if use_int else 0), (na if use_filt else 0)
    Np = lay.N
    N = Np + ne + nf
    # the PID states go between [q; q'] and the plant's extra states, as in the paper's loop
    order = np.r_[0 : 2 * lay.n, Np:N, 2 * lay.n : Np]

    def widen(Mat):  # plant columns -> full columns (controller columns zero)
        out = np.zeros((Mat.shape[0], N))
        out[:, :Np] = Mat
        return out

    Sm = widen(Cm)  # measured signal
    Sdot = widen(Cm @ Ap)  # its derivative (Cm Bp = 0: the measured signal never feeds through the input)
    E = np.zeros((na, N))
    Z = np.zeros((na, N))
    if use_int:
        E[:, Np : Np + na] = np.eye(na)
    if use_filt:
        Z[:, Np + ne : N] = np.eye(na)
    D = g.omega_f * (Sm - Z) if use_filt else Sdot
    Kc = -(g.kp * Sm + g.kI * E + g.kd * D)  # commanded current as a function of the state
    A = np.zeros((N, N))
    A[:Np, :Np] = Ap
    A[:Np] += Bp @ Kc
    if use_int:
        A[Np : Np + na] = Sm
    if use_filt:
        A[Np + ne : N] = g.omega_f * (Sm - Z)
    A = A[np.ix_(order, order)]
    return A, lay, ne, nf
