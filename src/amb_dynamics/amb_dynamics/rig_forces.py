"""State-dependent node forces of the rig plant: nonlinear bearing law (its departure from the linearisation)
and touchdown (backup) bearing contact, with the contact event log.

Nonlinear law per AMB axis (differential driving about bias i0 and nominal gap g0, pole-angle factor folded into
k = ki g0^2 / (4 i0)): f = k [(i0 + i)^2/(g0 - x)^2 - (i0 - i)^2/(g0 + x)^2], whose linearisation at (0, 0) is
ki i + |ks| x exactly when g0 = i0 ki/|ks| (config check); optional saturation caps each magnet's pull.  The linear
plant carries ki i - ks x, so the node force here is the difference f - (ki i - ks x), O(x^2, i^2, x i).

Touchdown at a node with radial displacement r = (y, z), e = |r|, penetration d = e - c > 0: normal force
Fn = k_c d + c_c max(e', 0) (damping only while approaching) toward the centre, Coulomb friction
mu Fn tanh(v_s / V_EPS) against the slip velocity v_s = t . r' + R Phi of the journal surface (R the shaft radius,
t the tangent, Phi the spin): a spinning rotor in contact is pushed to whirl backward.  The friction torque on the
spin is not fed back (the drive holds the spin profile).
"""

from __future__ import annotations

import math

import numpy as np

from .config import RotorConfig
from .fe import dof_index
from .plant_dynamics import StateLayout
from .structure import StructuralModel

MU0 = 4e-7 * math.pi
V_EPS = 1e-3  # m/s, friction regularisation
NEAR = 0.8  # sub-step while a node is beyond NEAR x clearance (or would get there within a step)
OMEGA_H = 0.2  # sub-step h: sqrt(k_c / m_node) h <= OMEGA_H
MAX_SUBSTEPS = 64


def nonlinear_bearing_force(x, i, ki, ks, i0, g0, f_sat=None):
    """Force (N) of one AMB axis (differential pair) at displacement x (m) and control current i (A)."""
    k = ki * g0 * g0 / (4.0 * i0)
    gp = np.maximum(g0 - x, 1e-3 * g0)
    gm = np.maximum(g0 + x, 1e-3 * g0)
    fp = k * (i0 + i) ** 2 / gp**2
    fm = k * (i0 - i) ** 2 / gm**2
    if f_sat is not None:
        fp, fm = np.minimum(fp, f_sat), np.minimum(fm, f_sat)
    return fp - fm


def contact_force(r, v, clearance, k, c, mu, radius, spin):
    """Force (N, (y, z)) of a backup bearing on the rotor at node displacement r and velocity v; and d (m)."""
    e = math.hypot(r[0], r[1])
    d = e - clearance
    if d <= 0.0:
        return 0.0, 0.0, d
    ny, nz = r[0] / e, r[1] / e
    er = ny * v[0] + nz * v[1]
    fn = k * d + (c * er if er > 0.0 else 0.0)
    slip = -nz * v[0] + ny * v[1] + radius * spin
    ft = -mu * fn * math.tanh(slip / V_EPS)
    return -fn * ny - ft * nz, -fn * nz + ft * ny, d


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
        self.n, self.layout = model.n, layout
        fe = model.fe
        Psi = model.basis if model.basis is not None else np.eye(fe.n)
        rows = [dof_index(node, a) for node in self.nodes for a in (0, 1)]
        self.T = Psi[rows]  # (2 x nodes, n): node (y, z) from q
        self.ki, self.ks, self.i0, self.g0 = b.current_stiffness, b.displacement_stiffness, b.bias_current, b.air_gap
        self.f_sat = None
        if b.saturation_flux_density is not None:
            self.f_sat = math.cos(math.radians(b.pole_angle_deg)) * b.pole_area * b.saturation_flux_density**2 / MU0
        self.amb_idx = np.array([2 * self.nodes.index(nd) + a for nd in self.amb_nodes for a in (0, 1)])
        self.td_idx = [self.nodes.index(nd) for nd in self.td_nodes]
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

    def node_forces(self, x: np.ndarray, i: np.ndarray, spin: float, t: float, log: ContactLog | None) -> np.ndarray:
        """Forces (N) at the force nodes, (y, z) each, for state x and held command i; logs contacts if given."""
        n = self.n
        f = np.zeros(2 * len(self.nodes))
        r = self.T @ x[:n]
        if self.nonlinear:
            y = r[self.amb_idx]
            ic = x[self.layout.amp] if self.layout.amp is not None else i
            fnl = nonlinear_bearing_force(y, ic, self.ki, self.ks, self.i0, self.g0, self.f_sat)
            f[self.amb_idx] += fnl - (self.ki * ic - self.ks * y)
        if self.touchdown:
            v = self.T @ x[n : 2 * n]
            for j, node in zip(self.td_idx, self.td_nodes, strict=True):
                fy, fz, d = contact_force(
                    r[2 * j : 2 * j + 2], v[2 * j : 2 * j + 2], self.clearance, self.k_c, self.c_c, self.mu,
                    self.radius, spin,
                )  # fmt: skip
                f[2 * j] += fy
                f[2 * j + 1] += fz
                if log is not None:
                    log.record(node, t, d, math.hypot(fy, fz))
        return f
