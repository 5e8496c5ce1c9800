"""State-dependent node forces of the rig plant: nonlinear bearing law (its departure from the linearisation)
and touchdown (backup) bearing contact, with the contact event log.

Nonlinear law per AMB axis: ``magnet.BearingLaw`` (differential driving about i0, g0, pole-angle factor, optional
saturation), whose linearisation at the centre is ki i - ks x; the linear plant carries that, so the node force
here is the law's departure from it, odd in (x, i) and therefore third order.

Touchdown: ``touchdown.contact_forces`` (penalty normal force, damping, regularised Coulomb friction against the
journal's slip velocity: a spinning rotor in contact is pushed to whirl backward).  The friction torque on the
spin is not fed back (the drive holds the spin profile).
"""

from __future__ import annotations

import math

import numpy as np

from .config import RotorConfig
from .fe import dof_index
from .magnet import BearingLaw
from .plant_dynamics import StateLayout
from .structure import StructuralModel
from .touchdown import contact_forces

NEAR = 0.8  # sub-step while a node is beyond NEAR x clearance (or would get there within a step)
OMEGA_H = 0.2  # sub-step h: sqrt(k_c / m_node) h <= OMEGA_H
MAX_SUBSTEPS = 64


class ContactLog:
    """Touchdown events: (t_start s, node, max penetration m, peak force N, t_end s or None)."""

    def __init__(self, nodes):
        self.nodes = tuple(nodes)
        self.events: list[list] = []
        self.open: dict[int, list] = {}

    def record(self, node: int, t: float, d: float, f: float) -> None:
        ev = self.open.get(node)
        if d > 0.0:
            if ev is None:
                ev = self.open[node] = [t, node, d, f, None]
                self.events.append(ev)
            ev[2], ev[3] = max(ev[2], d), max(ev[3], f)
        elif ev is not None:
            ev[4] = t
            del self.open[node]


class RigForces:
    """Node forces of the rig plant that depend on the state (nonlinear law, touchdown)."""

    def __init__(self, model: StructuralModel, cfg: RotorConfig, layout: StateLayout):
        b, td = cfg.bearings, cfg.touchdown
        self.disk_nodes = tuple(d.node for d in cfg.disks)
        self.amb_nodes = tuple(b.nodes)
        self.td_nodes = tuple(td.nodes)
        self.nodes = tuple(sorted(set(self.disk_nodes) | set(self.amb_nodes) | set(self.td_nodes)))
        self.nonlinear = b.force_law == "nonlinear"
        self.touchdown = bool(td.nodes)
        self.active = self.nonlinear or self.touchdown
        # the law's current is the amplifier's state when it has one: then the forces do not need the command
        self.uses_command = self.nonlinear and layout.amp is None
        self.n, self.layout = model.n, layout
        fe = model.fe
        Psi = model.basis if model.basis is not None else np.eye(fe.n)
        rows = [dof_index(node, a) for node in self.nodes for a in (0, 1)]
        self.T = Psi[rows]  # (2 x nodes, n): node (y, z) from q
        self.amb_idx = np.array([2 * self.nodes.index(nd) + a for nd in self.amb_nodes for a in (0, 1)])
        self.T_amb = np.ascontiguousarray(self.T[self.amb_idx])
        self.td_idx = [self.nodes.index(nd) for nd in self.td_nodes]
        self.td_rows = np.array([2 * j + a for j in self.td_idx for a in (0, 1)], dtype=int)
        self.T_td = np.ascontiguousarray(self.T[self.td_rows])
        self.law = BearingLaw.from_config(b) if self.nonlinear else None
        self.clearance, self.k_c = td.clearance, td.stiffness
        self.c_c, self.mu, self.radius = td.damping, td.friction, cfg.shaft.diameter / 2
        self.substeps = 1
        # effective mass of each touchdown node for a point force: 1 / (T M^-1 T^T)_yy (consistent mass)
        inv_m = np.einsum("ij,ji->i", self.T, np.linalg.solve(model.M, self.T.T))
        self._node_mass = [1.0 / inv_m[2 * self.nodes.index(nd)] for nd in self.td_nodes]
        self._f = np.zeros(2 * len(self.nodes))

    def set_rate(self, Ts: float) -> None:
        """Sub-steps per sample for sample period Ts (s)."""
        if self.touchdown:
            m_node = min(self._node_mass)
            self.substeps = int(min(MAX_SUBSTEPS, max(1, math.ceil(math.sqrt(self.k_c / m_node) * Ts / OMEGA_H))))

    def new_contact_log(self) -> ContactLog:
        return ContactLog(self.td_nodes)

    def near(self, x: np.ndarray, Ts: float) -> bool:
        """True if a touchdown node is (or may within Ts get) beyond NEAR x clearance."""
        if not self.touchdown:
            return False
        n = self.n
        r = self.T @ x[:n]
        v = self.T @ x[n : 2 * n]
        for j in self.td_idx:
            e = math.hypot(r[2 * j], r[2 * j + 1]) + Ts * math.hypot(v[2 * j], v[2 * j + 1])
            if e > NEAR * self.clearance:
                return True
        return False

    def amb_correction(self, x: np.ndarray, i: np.ndarray | None) -> np.ndarray:
        """The bearing law's departure from its linearisation ki i + |ks| x at the AMB axes (N, 4): magnet.BearingLaw
        at the amplifier's current (its state, or the held command i when the amplifier is ideal)."""
        y = self.T_amb @ x[: self.n]
        return self.law.correction(y, x[self.layout.amp] if self.layout.amp is not None else i)

    def node_forces(
        self, x: np.ndarray, i: np.ndarray, spin: float, t: float, log: ContactLog | None, near: bool = True
    ) -> np.ndarray:
        """Forces (N) at the force nodes, (y, z) each, for state x and held command i; logs contacts if given.

        ``near`` False (no touchdown node within NEAR x clearance, see ``near()``): no contact is evaluated."""
        n = self.n
        f = np.zeros(2 * len(self.nodes))
        if self.nonlinear:
            f[self.amb_idx] += self.amb_correction(x, i)
        if self.touchdown and near:  # touchdown.contact_forces at every backup-bearing node at once
            c = contact_forces(
                (self.T_td @ x[:n]).reshape(-1, 2), (self.T_td @ x[n : 2 * n]).reshape(-1, 2), spin, self.radius,
                self.clearance, self.k_c, self.c_c, self.mu,
            )  # fmt: skip
            f[self.td_rows] += c.force.ravel()
            if log is not None:
                for node, d, fy, fz in zip(self.td_nodes, c.penetration, c.force[:, 0], c.force[:, 1], strict=True):
                    log.record(node, t, float(d), math.hypot(fy, fz))
        return f
