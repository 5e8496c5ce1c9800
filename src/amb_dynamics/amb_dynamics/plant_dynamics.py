"""Actuator, sensor and shaft-damping dynamics of a real rig, added to the linear plant (continuous and sampled).

Models (each off when its config value is null or 0, and then the loop is exactly the paper's):

* Amplifier as a current loop: i_a' = w_a (i_c - i_a), a first-order lag of bandwidth w_a (rad/s) between the
  commanded current i_c and the coil current i_a; the AMB force is ki i_a + ks y.  The voltage limit (slew rate
  |di_a/dt| <= V/L) and the current clamp are nonlinear and live in the rig stepper (:mod:`amb_dynamics.rig_plant`).
* Sensor anti-alias filter: y_f' = w_s (y - y_f), first-order low-pass of corner w_s (rad/s) on each AMB
  displacement y = Ba^T q; the controller sees y_f (sampled in the digital loop).
* Structural damping of the shaft: D_s = beta K_B, stiffness-proportional (Rayleigh beta) viscous damping of the
  free-free shaft stiffness, in the non-rotating frame (rotating internal damping, which destabilises above the
  first critical speed, is not modelled).  A mode of frequency w gets the damping ratio beta w / 2: the 6-element
  mesh's top modes (~3.5e4 rad/s) are damped strongly, the rotor's first bending modes hardly at all.

The extra states are appended to the plant state: x_p = [q; q'; i_a (4, with the amplifier); y_f (4, with the
filter)], labels ``amp_<channel>`` and ``sens_<channel>``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .config import RotorConfig
from .structure import StructuralModel


@dataclass(frozen=True)
class PlantDynamics:
    """The linear real-rig additions; None / 0 switches one off.

    amplifier_rad_s : current-loop bandwidth w_a (rad/s)
    sensor_rad_s : anti-alias corner w_s (rad/s)
    beta_s : stiffness-proportional shaft damping beta (s)
    """

    amplifier_rad_s: float | None = None
    sensor_rad_s: float | None = None
    beta_s: float = 0.0

    @property
    def augmented(self) -> bool:
        """True if the plant has states beyond [q; q'] or damping beyond the paper's."""
        return self.amplifier_rad_s is not None or self.sensor_rad_s is not None or self.beta_s != 0.0

    @classmethod
    def from_config(cls, cfg: RotorConfig) -> PlantDynamics:
        amp = getattr(cfg, "amplifier", None)
        sens = getattr(cfg, "sensor", None)
        shaft = cfg.shaft
        amp_hz = getattr(amp, "bandwidth_hz", None) if amp is not None and getattr(amp, "enabled", True) else None
        sens_hz = getattr(sens, "antialias_hz", None) if sens is not None and getattr(sens, "enabled", True) else None
        beta = float(getattr(shaft, "damping_beta", 0.0) or 0.0)
        return cls(
            None if not amp_hz else 2 * math.pi * amp_hz,
            None if not sens_hz else 2 * math.pi * sens_hz,
            beta,
        )


def structural_damping(model: StructuralModel, dyn: PlantDynamics) -> np.ndarray | None:
    """D_s = beta K_B in the model's coordinates (N s/m), or None when off."""
    if dyn.beta_s == 0.0:
        return None
    return dyn.beta_s * model.mats["K_B"]


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
            sens, i = slice(i, i + na), i + na
        return cls(n, amp, sens, i)

    def labels(self, dof_names: tuple[str, ...], channels: tuple[str, ...]) -> tuple[str, ...]:
        return (
            *dof_names,
            *(f"d_{d}" for d in dof_names),
            *((f"amp_{c}" for c in channels) if self.amp else ()),
            *((f"sens_{c}" for c in channels) if self.sens else ()),
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
    Ap[n : 2 * n, :n] = -Minv @ (model.mats["K_B"] + g.ks * Ba @ Ba.T)
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
        ws = dyn.sensor_rad_s
        Ap[lay.sens, :n] = ws * Ba.T
        Ap[lay.sens, lay.sens] = -ws * np.eye(Ba.shape[1])
        Cm = np.zeros_like(Cy)
        Cm[:, lay.sens] = np.eye(Ba.shape[1])
    else:
        Cm = Cy
    return Ap, Bp, Cm, Cy, lay


def closed_loop_matrix(model: StructuralModel, dyn: PlantDynamics, Minv: np.ndarray):
    """A0 of the continuous closed loop with the plant dynamics and the continuous PID of PHYSICS.md 3.2.

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
