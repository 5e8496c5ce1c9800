"""Disk unbalance: the synchronous force in base coordinates and the steady-state response of the linear loop.

Each disk carries an unbalance U = m_u e (kg m) at the angle ``unbalance_phase_deg`` from the shaft's +Y axis
toward +Z when the spin angle phi (relative to the base) is zero: its position relative to the disk centre is
r_e = e (0, cos(phi + p), sin(phi + p)) in the base frame.  Its inertial force on the disk node (docs/physics.md
4.7) is f_u = -m_u [r_e'' + 2 Omega x r_e' + Omega' x r_e + Omega x (Omega x r_e)], of which the (Y, Z) components
act on (v, w); the axial component has no degree of freedom.  On a base at rest and at constant spin it is
U phi'^2 (cos, sin)(phi + p): the complex amplitude U e^{ip} (1, -i) phi'^2 on (v, w), with y(t) = Re(y^ e^{i phi}).

The steady state of the continuous closed loop x' = A(phi') x + B f^ phi'^2 e^{i phi' t} (base at rest) is
x^ = (i phi' I - A)^-1 B f^ phi'^2, with A = A0 + phi' A_Phi (``SynchronousResponse``, all speeds at once).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from .config import RotorConfig
from .config_rig import disk_unbalance
from .errors import InputError
from .fe import dof_index
from .structure import StructuralModel
from .system import ClosedLoop


@dataclass(frozen=True)
class Unbalance:
    """Unbalances of a rotor: disk nodes (1-based), U (kg m) and phase p (rad) per disk."""

    nodes: tuple[int, ...]
    U: np.ndarray
    phase: np.ndarray

    @classmethod
    def from_config(cls, cfg: RotorConfig) -> Unbalance:
        pairs = [disk_unbalance(d, cfg.shaft.density, cfg.max_speed_rpm) for d in cfg.disks]
        return cls(tuple(d.node for d in cfg.disks), np.array([u for u, _ in pairs]), np.array([p for _, p in pairs]))

    @property
    def any(self) -> bool:
        return bool(np.any(self.U != 0.0))

    def amplitude_fe(self, n_fe: int) -> np.ndarray:
        """(n_fe,) complex amplitude per unit phi'^2: U e^{ip} on v, -i U e^{ip} on w of each disk node."""
        f = np.zeros(n_fe, dtype=complex)
        for node, U, p in zip(self.nodes, self.U, self.phase, strict=True):
            f[dof_index(node, 0)] += U * np.exp(1j * p)
            f[dof_index(node, 1)] += -1j * U * np.exp(1j * p)
        return f

    def force_fe(self, n_fe: int, phi, phi_dot, phi_ddot=0.0, Omega=None, dOmega=None) -> np.ndarray:
        """Time-domain unbalance load on the FE DOFs, (n_fe,) or (k, n_fe) for arrays of time samples.

        phi, phi_dot, phi_ddot : spin angle (rad), rate (rad/s), acceleration (rad/s^2) relative to the base.
        Omega, dOmega : base angular velocity and acceleration in the base frame (3,) or (3, k); None = at rest.
        """
        scalar = np.ndim(phi) == 0
        phi = np.atleast_1d(np.asarray(phi, dtype=float))
        k = phi.size
        phid = np.broadcast_to(np.asarray(phi_dot, dtype=float), (k,))
        phidd = np.broadcast_to(np.asarray(phi_ddot, dtype=float), (k,))
        Om = np.zeros((3, k)) if Omega is None else np.broadcast_to(np.asarray(Omega, float).reshape(3, -1), (3, k))
        dOm = np.zeros((3, k)) if dOmega is None else np.broadcast_to(np.asarray(dOmega, float).reshape(3, -1), (3, k))
        f = np.zeros((k, n_fe))
        for node, U, p in zip(self.nodes, self.U, self.phase, strict=True):
            if U == 0.0:
                continue
            a = phi + p
            c, s = np.cos(a), np.sin(a)
            z = np.zeros(k)
            r = np.stack([z, c, s])  # r_e / e
            rd = np.stack([z, -s, c]) * phid  # relative velocity / e
            rdd = np.stack([z, -s, c]) * phidd - r * phid**2  # relative acceleration / e
            acc = rdd + 2 * np.cross(Om, rd, axis=0) + np.cross(dOm, r, axis=0)
            acc += np.cross(Om, np.cross(Om, r, axis=0), axis=0)
            f[:, dof_index(node, 0)] += -U * acc[1]
            f[:, dof_index(node, 1)] += -U * acc[2]
        return f[0] if scalar else f


def input_matrix(model: StructuralModel, loop: ClosedLoop) -> np.ndarray:
    """(N, n_fe): state derivative per unit FE load, x' = ... + Bu f_fe (generalised: basis^T f_fe)."""
    n = model.n
    P = np.eye(model.fe.n) if model.basis is None else model.basis.T
    Bu = np.zeros((loop.N, model.fe.n))
    Bu[n : 2 * n] = np.linalg.solve(model.M, P)
    return Bu


class SynchronousResponse:
    """Steady state of the continuous closed loop under synchronous unbalance, base at rest, for many speeds.

    L(w) x = w^2 b with L(w) = i w I - A0 - w A_Phi = w E - A0, E = i I - A_Phi.  The pencil (A0, E) is
    diagonalised once: A0 V = E V diag(lambda), so L(w)^-1 = V diag(1/(w - lambda)) V^-1 E^-1 and each speed
    costs O(N^2).  Two steps of iterative refinement against the exact residual w^2 b - L(w) x bring the
    result to the accuracy of a direct solve.  The lambda_j are the complex synchronous resonance speeds: a
    lightly damped mode that unbalance excites has Re(lambda) = its critical speed (rad/s).
    """

    REFINE = 1

    def __init__(self, model: StructuralModel, loop: ClosedLoop, ub: Unbalance):
        if not ub.any:
            raise InputError(
                "the config has no unbalance: set disks[i].unbalance or balance_grade (with max_speed_rpm)"
            )
        self.model, self.loop = model, loop
        self.A0 = loop.A0.astype(complex)
        self.E = 1j * np.eye(loop.N) - loop.A_terms.get("Phi", np.zeros_like(loop.A0))
        self.EA_T = np.hstack([self.E.T, self.A0.T])  # one product gives x E^T and x A0^T
        self.b = input_matrix(model, loop) @ ub.amplitude_fe(model.fe.n)
        self.lam, self.V = sla.eig(self.A0, self.E)
        self.Vinv_Einv = np.linalg.solve(self.E @ self.V, np.eye(loop.N))  # (E V)^-1
        self.coef = self.Vinv_Einv @ self.b
        self.residue = self.V * self.coef  # column j: V_j (V^-1 E^-1 b)_j

    def _apply_inverse(self, w: np.ndarray, R: np.ndarray) -> np.ndarray:
        """L(w_k)^-1 R_k for rows R_k, (k, N)."""
        return ((R @ self.Vinv_Einv.T) / (w[:, None] - self.lam[None, :])) @ self.V.T

    def states(self, speeds_rpm) -> np.ndarray:
        """Complex state amplitudes x^ (k, N) per unit of the configured unbalance."""
        w = np.asarray(speeds_rpm, dtype=float).ravel() * np.pi / 30.0
        N = self.loop.N
        x = ((w**2)[:, None] * self.coef[None, :] / (w[:, None] - self.lam[None, :])) @ self.V.T
        for _ in range(self.REFINE):
            xEA = x @ self.EA_T
            res = (w**2)[:, None] * self.b[None, :] - w[:, None] * xEA[:, :N] + xEA[:, N:]
            x = x + self._apply_inverse(w, res)
        return x

    def displacements(self, speeds_rpm) -> np.ndarray:
        """Complex FE displacement amplitudes (k, n_fe): y(t) = Re(y^ e^{i phi(t)}), 0-peak |y^| (m)."""
        return self.model.to_fe(self.states(speeds_rpm)[:, : self.model.n])

    def critical_speeds_rpm(self, lo_rpm: float, hi_rpm: float, max_damping: float = 0.3) -> list[float]:
        """Re(lambda) in rpm of the resonances unbalance excites (residue at the FE DOFs not negligible)."""
        q = np.abs(self.model.to_fe(self.residue[: self.model.n].T)).max(axis=1)
        keep = (
            (self.lam.real * 30 / np.pi >= lo_rpm)
            & (self.lam.real * 30 / np.pi <= hi_rpm)
            & (np.abs(self.lam.imag) <= max_damping * np.abs(self.lam))
            & (q > 1e-6 * q.max())
        )
        return sorted(float(v) for v in self.lam.real[keep] * 30 / np.pi)


def channels(cfg: RotorConfig) -> list[tuple[str, int]]:
    """(name, FE DOF index) of the reported channels: the AMB nodes, then the disk nodes, y then z."""
    out = []
    for prefix, nodes in (("amb", cfg.bearings.nodes), ("disk", tuple(d.node for d in cfg.disks))):
        for node in nodes:
            for j, ax in enumerate(("y", "z")):
                out.append((f"{prefix}{node}_{ax}", dof_index(node, j)))
    return out
