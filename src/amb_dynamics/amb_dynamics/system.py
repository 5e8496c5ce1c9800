"""The closed loop x' = A(t) x + b(t) of the rotor on its AMBs on a moving base (docs/physics.md#eom, #controller).

A(t) = A0 + sum_j c_j(t) A_j with the coefficients ``COEFFICIENTS`` of the base motion and spin; the
constant matrices A_j come from the formulation (``derived`` or ``seed``).  Controller states (integral
and derivative filter) are appended to x = [q; q'] when they are used.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from .config import RotorConfig
from .control_law import continuous_controller, is_plain_pid
from .motion import BaseMotion
from .plant_dynamics import PlantDynamics, closed_loop_matrix, open_loop_plant
from .state_space import StateSpace, close_loop
from .structure import StructuralModel

# c_j(t) in A(t) = A0 + sum c_j A_j  (Phi = phi_dot + Omega_x is the total spin)
COEFFICIENTS = ("Phi", "Ox", "dOx", "Ox2", "OxPhi", "Oy2", "Oz2", "OyOz", "dPhi", "Oyz2")


def coefficients_from_rates(Om: np.ndarray, dOm: np.ndarray, spin, spin_accel=0.0) -> np.ndarray:
    """c_j for base rates Omega, dOmega (3,) or (3, k), spin phi_dot (rad/s) and phi_ddot (rad/s^2).

    Returns shape (len(COEFFICIENTS), ...).  Phi = phi_dot + Omega_x, dPhi = phi_ddot + dOmega_x.
    """
    Ox, Oy, Oz = Om
    Phi = spin + Ox
    dPhi = spin_accel + dOm[0]
    return np.array([Phi, Ox, dOm[0], Ox * Ox, Ox * Phi, Oy * Oy, Oz * Oz, Oy * Oz, dPhi, Oy * Oy + Oz * Oz])


def forcing_from_rates(Om: np.ndarray, dOm: np.ndarray, spin: float) -> np.ndarray:
    """a1..a4 of docs/physics.md#forcing: (dOz + Ox Oy, dOy - Ox Oz, Phi Oz, Phi Oy), shape (4, ...)."""
    Ox, Oy, Oz = Om
    Phi = spin + Ox
    return np.array([dOm[2] + Ox * Oy, dOm[1] - Ox * Oz, Phi * Oz, Phi * Oy])


def coefficient_values(motion: BaseMotion, spin: float, t) -> np.ndarray:
    """c_j(t), shape (len(COEFFICIENTS), len(t)); spin = phi_dot relative to the base (rad/s)."""
    return coefficients_from_rates(*motion.angular_velocity(t), spin)


def forcing_values(motion: BaseMotion, spin: float, t) -> np.ndarray:
    """a1..a4 of docs/physics.md#forcing, shape (4, len(t))."""
    return forcing_from_rates(*motion.angular_velocity(t), spin)


def parametric_matrices(model: StructuralModel, cfg: RotorConfig) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """(K_j, D_j) multiplying each coefficient: K(t) = K_const + sum c_j K_j, D(t) = ... + sum c_j D_j."""
    m = model.matrices
    z = np.zeros_like(m.mass)
    if cfg.formulation == "seed":
        G, P, K11, K22, K12 = m.seed_gyroscopic, z, m.seed_centrifugal_z, m.seed_centrifugal_y, m.seed_centrifugal_yz
        H = -m.seed_spin_acceleration
    else:
        G, P, K11, K22, K12 = m.gyroscopic, m.spin_roll, m.centrifugal_z, m.centrifugal_y, m.centrifugal_yz
        H = m.spin_acceleration if cfg.drive_model == "cardan" else z
    KG = m.axial_stiffening if cfg.axial_stiffening else z
    return {
        "Phi": (z, G),
        "Ox": (z, 2 * m.coriolis),
        "dOx": (m.coriolis, z),
        "Ox2": (-m.mass, z),
        "OxPhi": (P, z),
        "Oy2": (-K22, z),
        "Oz2": (-K11, z),
        "OyOz": (K12, z),
        "dPhi": (H, z),
        "Oyz2": (KG, z),
    }


@dataclass(frozen=True)
class ClosedLoop:
    """Continuous closed loop: x' = (A0 + sum_j c_j(t) A_j) x + Bf a(t).

    A0 : (N, N) bearings and controller, no base motion and no spin.
    A_terms : dict coefficient name -> (N, N).
    Bf : (N, 4) forcing input for a1..a4.
    n : number of generalised coordinates (x[:n] = q, x[n:2n] = q').
    """

    A0: np.ndarray
    A_terms: dict[str, np.ndarray]
    Bf: np.ndarray
    n: int
    labels: tuple[str, ...]

    @property
    def N(self) -> int:
        return self.A0.shape[0]

    def matrix(self, c: np.ndarray) -> np.ndarray:
        """A for coefficient values c (len(COEFFICIENTS),) or a batch (len, k) -> (k, N, N)."""
        c = np.asarray(c, dtype=float)
        if c.ndim == 1:
            return self.A0 + sum(c[COEFFICIENTS.index(k)] * Aj for k, Aj in self.A_terms.items())
        out = np.broadcast_to(self.A0, (c.shape[1], self.N, self.N)).copy()
        for k, Aj in self.A_terms.items():
            out += c[COEFFICIENTS.index(k)][:, None, None] * Aj
        return out


def closed_loop(model: StructuralModel, cfg: RotorConfig, dynamics: PlantDynamics | None = None) -> ClosedLoop:
    """Assemble the continuous closed loop of docs/physics.md#controller (collocated PID, ideal or filtered;
    with notch / lead-lag filters or the user's state space: :mod:`amb_dynamics.control_law`).

    ``dynamics``: amplifier, sensor filter and shaft damping (default: from ``cfg``, :mod:`.plant_dynamics`).
    """
    g, Ba = model.gains, model.Ba
    M = model.M
    Minv = sla.inv(M)  # n <= a few hundred; M is factored once here, never in a loop
    dyn = PlantDynamics.from_config(cfg) if dynamics is None else dynamics
    if not is_plain_pid(cfg):
        A0, labels = _general_closed_loop(model, cfg, dyn, Minv)
        return _with_terms(model, cfg, A0, Minv, labels)
    use_int = g.kI != 0.0
    use_filt = g.omega_f is not None
    na = Ba.shape[1]  # AMB axes
    ne, nf = (na if use_int else 0), (na if use_filt else 0)
    if dyn.augmented:  # amplifier, sensor filter or shaft damping (plant_dynamics); else the paper's loop below
        A0, lay, _, _ = closed_loop_matrix(model, dyn, Minv)
    else:
        A0 = _paper_closed_loop(model, Minv, ne, nf)
    labels = (
        *model.dof_names,
        *(f"d_{d}" for d in model.dof_names),
        *(f"int_{c}" for c in model.channels[:ne]),
        *(f"filt_{c}" for c in model.channels[:nf]),
    )
    if dyn.augmented:
        labels += lay.labels((), model.channels)
    return _with_terms(model, cfg, A0, Minv, labels)


def _general_closed_loop(
    model: StructuralModel, cfg: RotorConfig, dyn: PlantDynamics, Minv: np.ndarray
) -> tuple[np.ndarray, tuple[str, ...]]:
    """A0 of any linear controller u = K(s) y_m around the plant: states [plant; controller]."""
    Ap, Bp, Cm, _, lay = open_loop_plant(model, dyn, Minv)
    K = continuous_controller(cfg, model.gains, model.Ba.shape[1])
    A0 = close_loop(StateSpace(Ap, Bp, Cm, np.zeros((Cm.shape[0], Bp.shape[1]))), K).A
    labels = lay.labels(model.dof_names, model.channels) + tuple(f"ctrl_{i}" for i in range(K.n_states))
    return A0, labels


def _with_terms(
    model: StructuralModel, cfg: RotorConfig, A0: np.ndarray, Minv: np.ndarray, labels: tuple[str, ...]
) -> ClosedLoop:
    """The ClosedLoop of A0 with the base-motion and spin terms on the rows of q'' (x[n:2n])."""
    n, N = model.n, A0.shape[0]
    terms = {}
    for name, (Kj, Dj) in parametric_matrices(model, cfg).items():
        if not Kj.any() and not Dj.any():
            continue
        Aj = np.zeros((N, N))
        Aj[n : 2 * n, :n] = -Minv @ Kj
        Aj[n : 2 * n, n : 2 * n] = -Minv @ Dj
        terms[name] = Aj
    Bf = np.zeros((N, 4))
    Bf[n : 2 * n] = Minv @ model.forcing
    return ClosedLoop(A0, terms, Bf, n, labels)


def _paper_closed_loop(model: StructuralModel, Minv: np.ndarray, ne: int, nf: int) -> np.ndarray:
    """A0 of docs/physics.md#controller: ideal current source, ideal sensor, undamped shaft."""
    n, g, Ba = model.n, model.gains, model.Ba
    use_int, use_filt = ne > 0, nf > 0
    N = 2 * n + ne + nf
    Ky = g.ki * g.kp + g.ks + (g.ki * g.kd * g.omega_f if use_filt else 0.0)
    Dy = 0.0 if use_filt else g.ki * g.kd
    K0 = model.matrices.shaft_stiffness + Ky * Ba @ Ba.T
    Ds = model.matrices.structural_damping  # of the shaft (damping.py)
    D0 = Dy * Ba @ Ba.T + (0.0 if Ds is None else Ds)
    A0 = np.zeros((N, N))
    A0[:n, n : 2 * n] = np.eye(n)
    A0[n : 2 * n, :n] = -Minv @ K0
    A0[n : 2 * n, n : 2 * n] = -Minv @ D0
    i = 2 * n
    if use_int:
        A0[n : 2 * n, i : i + 4] = -Minv @ Ba * (g.ki * g.kI)
        A0[i : i + 4, :n] = Ba.T
        i += 4
    if use_filt:
        A0[n : 2 * n, i : i + 4] = Minv @ Ba * (g.ki * g.kd * g.omega_f)
        A0[i : i + 4, :n] = g.omega_f * Ba.T
        A0[i : i + 4, i : i + 4] = -g.omega_f * np.eye(4)
    return A0


@dataclass(frozen=True)
class PeriodicSystem:
    """A(t) = A0 + sum_j c_j(t) A_j of one base motion and spin, with constant terms folded into A0."""

    loop: ClosedLoop
    A0: np.ndarray
    names: tuple[str, ...]  # time-varying coefficient names
    A_stack: np.ndarray  # (k, N, N)
    coef: Callable[[np.ndarray], np.ndarray]  # t -> (k, len(t))
    forcing: Callable[[np.ndarray], np.ndarray]  # t -> (4, len(t))
    period: float | None  # period of A(t); None if static or aperiodic
    motion: BaseMotion
    spin: float

    def A(self, t) -> np.ndarray:
        """A(t) for an array of times, shape (len(t), N, N)."""
        c = self.coef(np.atleast_1d(t))
        return self.A0 + np.einsum("kt,kij->tij", c, self.A_stack)


def periodic_system(loop: ClosedLoop, motion: BaseMotion, spin: float) -> PeriodicSystem:
    """Split A(t) into the constant part and the varying coefficients of this motion."""
    names_all = [k for k in COEFFICIENTS if k in loop.A_terms]
    idx = [COEFFICIENTS.index(k) for k in names_all]

    def all_coef(t):
        return coefficient_values(motion, spin, t)[idx]

    T0 = motion.fundamental_period()
    probe = np.linspace(0.0, T0 if T0 else 1.0, 41)
    values = all_coef(probe)
    varying = [j for j in range(len(idx)) if np.ptp(values[j]) > 1e-14 * max(1.0, np.abs(values[j]).max())]
    A0 = loop.A0 + sum(values[j, 0] * loop.A_terms[names_all[j]] for j in range(len(idx)) if j not in varying)
    names = tuple(names_all[j] for j in varying)
    A_stack = np.array([loop.A_terms[k] for k in names]).reshape(len(names), loop.N, loop.N)
    vidx = np.array([idx[j] for j in varying], dtype=int)

    def coef(t):
        return coefficient_values(motion, spin, t)[vidx]

    def forcing(t):
        return forcing_values(motion, spin, t)

    period = None if not names and T0 is None else motion.parametric_period(coef)
    if not names:
        period = None
    return PeriodicSystem(loop, A0, names, A_stack, coef, forcing, period, motion, spin)
