"""The structural model the dynamics run on: FE matrices + AMB axes, optionally modally reduced.

``StructuralModel`` holds the constant matrices of docs/physics.md#fe to #formulations in generalised coordinates
(FE DOFs, or modal coordinates below ``modal_cutoff``), the AMB selection Ba and the forcing shapes.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
import scipy.linalg as sla

from .config import RotorConfig
from .damping import structural_damping_matrix
from .errors import InputError
from .fe import DiskElement, DiskProps, FEModel, Section, assemble, dof_index
from .rotor_matrices import RotorMatrices

AXIS_NAMES = ("y", "z")


@dataclass(frozen=True)
class AMBGains:
    """Per-axis AMB and PID constants (all four axes equal)."""

    ki: float  # N/A
    ks: float  # N/m (negative: open-loop unstable)
    kp: float  # A/m
    kI: float  # A/(m s)
    kd: float  # A s/m
    omega_f: float | None  # derivative filter corner (rad/s); None = ideal / backward difference

    @property
    def k_eq(self) -> float:
        """Equivalent base-fixed stiffness ki kp + ks (N/m), ideal derivative."""
        return self.ki * self.kp + self.ks

    @property
    def c_eq(self) -> float:
        """Equivalent base-fixed damping ki kd (N s/m)."""
        return self.ki * self.kd

    @classmethod
    def from_config(cls, cfg: RotorConfig) -> AMBGains:
        b, c = cfg.bearings, cfg.controller
        wf = None if c.derivative_filter_hz is None else 2 * np.pi * c.derivative_filter_hz
        return cls(
            b.current_stiffness,
            b.displacement_stiffness,
            c.proportional_gain,
            c.integral_gain,
            c.derivative_gain,
            wf,
        )


@dataclass(frozen=True)
class StructuralModel:
    """Matrices in generalised coordinates q (n of them).

    matrices : :class:`RotorMatrices` (n, n), structural damping included.
    Ba : (n, 4) AMB selection, y = Ba^T q for channels ``channels``.
    forcing : (n, 4) load shapes for a1..a4 (docs/physics.md#forcing).
    basis : (n_fe, n) modal basis Psi_r (q_fe = Psi_r q), or None for the full FE model.
    """

    matrices: RotorMatrices
    Ba: np.ndarray
    forcing: np.ndarray
    gains: AMBGains
    channels: tuple[str, ...]
    fe: FEModel
    basis: np.ndarray | None = None
    dof_names: tuple[str, ...] = field(default=())

    @property
    def n(self) -> int:
        return self.matrices.n

    @property
    def M(self) -> np.ndarray:
        return self.matrices.mass

    def to_fe(self, q: np.ndarray) -> np.ndarray:
        """FE nodal DOFs from generalised coordinates (last axis)."""
        return q if self.basis is None else q @ self.basis.T

    def from_fe(self, q_fe: np.ndarray) -> np.ndarray:
        """Generalised coordinates of FE nodal DOFs: least squares in the mass metric."""
        if self.basis is None:
            return q_fe
        return q_fe @ (self.fe.matrices.mass @ self.basis)  # Psi^T M q with Psi^T M Psi = I


def selection_matrix(n: int, nodes: tuple[int, ...]) -> np.ndarray:
    """Ba (n x 4): columns AMB1-Y, AMB1-Z, AMB2-Y, AMB2-Z selecting v and w at the AMB nodes."""
    Ba = np.zeros((n, 2 * len(nodes)))
    for k, node in enumerate(nodes):
        Ba[dof_index(node, 0), 2 * k] = 1.0
        Ba[dof_index(node, 1), 2 * k + 1] = 1.0
    return Ba


def channel_names(nodes: tuple[int, ...]) -> tuple[str, ...]:
    return tuple(f"amb{node}_{ax}" for node in nodes for ax in AXIS_NAMES)


def build_structure(cfg: RotorConfig, fe: FEModel | None = None) -> StructuralModel:
    """Assemble the FE rotor with its AMB axes and apply ``modal_cutoff`` if set."""
    fe = fe if fe is not None else assemble(cfg)
    gains = AMBGains.from_config(cfg)
    Ba = selection_matrix(fe.n, cfg.bearings.nodes)
    fm = fe.matrices
    mats = replace(
        fm, structural_damping=structural_damping_matrix(fm.mass, fm.shaft_stiffness, cfg.structural_damping)
    )
    model = StructuralModel(
        mats,
        Ba,
        fe.forcing.copy(),
        gains,
        channel_names(cfg.bearings.nodes),
        fe,
        None,
        tuple(fe.dof_names()),
    )
    if cfg.modal_cutoff is not None:
        model = reduce_modal(model, cfg.modal_cutoff)
    return model


def rigid_disk_model(
    m: float,
    Id: float,
    Ip: float,
    K_B: np.ndarray,
    c: float = 0.0,
    cfg: RotorConfig | None = None,
) -> StructuralModel:
    """A one-node rotor (rigid disk on base-fixed springs, docs/physics.md#checks) through the production assembly.

    K_B : (4, 4) stiffness on [v, w, theta_y, theta_z] (N/m, N m/rad); c : base-fixed damping on v, w (N s/m).
    The damper enters as an ideal-derivative 'bearing' on v and w (ki kd = c, ki kp + ks = 0).
    """

    disk = DiskElement(DiskProps(1, m, Ip, Id), cfg.seed_disk_H if cfg is not None else "literal")
    mats = replace(disk.matrices, shaft_stiffness=np.array(K_B, dtype=float))
    fe = FEModel(
        matrices=mats,
        forcing=disk.forcing(0.0),  # the disk sits at the base-rotation centre x = 0
        node_x=np.zeros(1),
        disks=(disk.props,),
        section=Section(0.0, 0.0, 0.0, 0.0, np.inf, 0.0),
    )
    gains = AMBGains(ki=1.0, ks=0.0, kp=0.0, kI=0.0, kd=float(c), omega_f=None)
    Ba = selection_matrix(4, (1,))
    return StructuralModel(mats, Ba, fe.forcing.copy(), gains, channel_names((1,)), fe, None, tuple(fe.dof_names()))


def reduce_modal(model: StructuralModel, cutoff: float) -> StructuralModel:
    """Project on the mass-normalised modes of (M, K_B + K_brg) below ``cutoff`` (rad/s)."""
    K = model.matrices.shaft_stiffness + model.gains.k_eq * model.Ba @ model.Ba.T
    w2, vecs = sla.eigh(K, model.M)
    keep = np.sqrt(np.clip(w2, 0.0, None)) < cutoff
    if not keep.any():
        raise InputError(f"modal_cutoff {cutoff:g} rad/s keeps no mode (lowest {np.sqrt(max(w2[0], 0)):.4g})")
    Psi = vecs[:, keep]
    mats = model.matrices.map(lambda X: Psi.T @ X @ Psi)
    names = tuple(f"mode{j + 1}" for j in range(Psi.shape[1]))
    return StructuralModel(
        mats,
        Psi.T @ model.Ba,
        Psi.T @ model.forcing,
        model.gains,
        model.channels,
        model.fe,
        Psi,
        names,
    )
