"""Finite-element matrices of the rotor in the moving base frame (docs/physics.md#fe).

Node DOFs are [v, w, theta_y, theta_z] with theta_y = -w', theta_z = +v'.  Element integrals use
4-point Gauss-Legendre quadrature, exact for the cubic (Euler-Bernoulli or Timoshenko) shape functions.
Every matrix is returned for both formulations: ``derived`` (default) and ``seed`` (the paper's print).
``ShaftElement`` and ``DiskElement`` give an element's :class:`RotorMatrices`; ``assemble`` adds them up.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .config import DiskConfig, RotorConfig
from .rotor_matrices import RotorMatrices

J2 = np.array([[0.0, -1.0], [1.0, 0.0]])
S2 = np.array([[0.0, 1.0], [1.0, 0.0]])
E11 = np.diag([1.0, 0.0])
E22 = np.diag([0.0, 1.0])
UPPER = np.array([[0.0, 1.0], [0.0, 0.0]])  # [[0,1],[0,0]]: H1 (derived, cardan)
LOWER = np.array([[0.0, 0.0], [1.0, 0.0]])  # [[0,0],[1,0]]: Hs (seed, as printed)
GAUSS_POINTS = 4
DOF_NAMES = ("v", "w", "ty", "tz")


@dataclass(frozen=True)
class Section:
    """Uniform shaft section properties per unit length."""

    rho_A: float  # mass per length (kg/m)
    i_d: float  # diametral inertia per length, rho*I (kg m)
    i_p: float  # polar inertia per length, 2 rho*I (kg m)
    EI: float  # bending stiffness (N m^2)
    kGA: float  # shear stiffness kappa*G*A (N); inf for Euler-Bernoulli
    length: float  # element length Le (m)


def section_of(cfg: RotorConfig) -> Section:
    s = cfg.shaft
    area = np.pi * s.diameter**2 / 4.0
    inertia = np.pi * s.diameter**4 / 64.0
    rot = 1.0 if s.rotary_inertia else 0.0
    if s.model == "timoshenko":
        nu = s.youngs_modulus / (2.0 * s.shear_modulus) - 1.0
        kappa = 6.0 * (1.0 + nu) / (7.0 + 6.0 * nu)
        kGA = kappa * s.shear_modulus * area
    else:
        kGA = np.inf
    return Section(
        rho_A=s.density * area,
        i_d=rot * s.density * inertia,
        i_p=rot * 2 * s.density * inertia,
        EI=s.youngs_modulus * inertia,
        kGA=kGA,
        length=s.length / s.elements,
    )


def shape_functions(xi: float, Le: float, phi_s: float = 0.0):
    """psi (2x8), psi' (2x8), psi_theta (2x8), psi_theta' (2x8) at xi = s/Le.

    phi_s = 12 EI/(kappa G A Le^2) selects Timoshenko (0: Euler-Bernoulli, psi_theta = J psi').
    """
    d = 1.0 + phi_s
    x2, x3 = xi * xi, xi**3
    N = (
        np.array(
            [
                1 - 3 * x2 + 2 * x3 + phi_s * (1 - xi),
                Le * (xi - 2 * x2 + x3 + phi_s * (xi - x2) / 2),
                3 * x2 - 2 * x3 + phi_s * xi,
                Le * (-x2 + x3 - phi_s * (xi - x2) / 2),
            ]
        )
        / d
    )
    dN = np.array(
        [
            -6 * xi + 6 * x2 - phi_s,
            Le * (1 - 4 * xi + 3 * x2 + phi_s * (1 - 2 * xi) / 2),
            6 * xi - 6 * x2 + phi_s,
            Le * (-2 * xi + 3 * x2 - phi_s * (1 - 2 * xi) / 2),
        ]
    ) / (d * Le)
    P = (
        np.array(
            [
                6 * (x2 - xi) / Le,
                1 - 4 * xi + 3 * x2 + phi_s * (1 - xi),
                -6 * (x2 - xi) / Le,
                -2 * xi + 3 * x2 + phi_s * xi,
            ]
        )
        / d
    )
    dP = np.array([6 * (2 * xi - 1) / Le, -4 + 6 * xi - phi_s, -6 * (2 * xi - 1) / Le, -2 + 6 * xi + phi_s]) / (d * Le)
    return _rows(N), _rows(dN), _theta_rows(P), _theta_rows(dP)


def _rows(N: np.ndarray) -> np.ndarray:
    """psi from the four shape functions: row v = [N1,0,0,N2,N3,0,0,N4], row w with w' = -theta_y."""
    psi = np.zeros((2, 8))
    psi[0, [0, 3, 4, 7]] = N
    psi[1, [1, 2, 5, 6]] = [N[0], -N[1], N[2], -N[3]]
    return psi


def _theta_rows(P: np.ndarray) -> np.ndarray:
    """psi_theta in the places and signs of J psi': row theta_y, row theta_z."""
    pt = np.zeros((2, 8))
    pt[0, [1, 2, 5, 6]] = [-P[0], P[1], -P[2], P[3]]
    pt[1, [0, 3, 4, 7]] = P
    return pt


class ShaftElement:
    """A uniform beam element between two nodes (8 DOFs), Euler-Bernoulli or Timoshenko (as ROSS's ShaftElement).

    ``matrices``: its :class:`RotorMatrices` (8 x 8, no axial stiffening: the tension depends on where the element
    sits); ``axial_stiffening(x0)`` and ``forcing(x0)`` for an element starting at axial position x0.
    All integrals by Gauss-Legendre quadrature, exact for the cubic shape functions.
    """

    def __init__(self, section: Section):
        self.section = sec = section
        Le = sec.length
        phi_s = 0.0 if np.isinf(sec.kGA) else 12.0 * sec.EI / (sec.kGA * Le**2)
        xg, wg = np.polynomial.legendre.leggauss(GAUSS_POINTS)
        out: dict[str, np.ndarray] = {}

        def acc(name: str, value: np.ndarray) -> None:
            out[name] = out.get(name, 0.0) + value

        ra, i_d, i_p = sec.rho_A, sec.i_d, sec.i_p
        for x, w in zip((xg + 1) / 2, wg * Le / 2, strict=True):
            psi, dpsi, pt, dpt = shape_functions(x, Le, phi_s)
            gamma = dpsi - J2.T @ pt
            s = x * Le
            acc("translational_mass", w * ra * psi.T @ psi)
            acc("rotary_mass", w * i_d * pt.T @ pt)
            acc("shaft_stiffness", w * sec.EI * dpt.T @ dpt)
            if phi_s:
                acc("shaft_stiffness", w * sec.kGA * gamma.T @ gamma)
            acc("gyroscopic", -w * i_p * pt.T @ J2 @ pt)
            acc("coriolis", w * (ra * psi.T @ J2 @ psi + i_d * pt.T @ J2 @ pt))
            acc("spin_roll", w * i_p * pt.T @ pt)
            acc("centrifugal_z", w * (ra * psi.T @ E11 @ psi + (i_p - i_d) * pt.T @ E11 @ pt))
            acc("centrifugal_y", w * (ra * psi.T @ E22 @ psi + (i_p - i_d) * pt.T @ E22 @ pt))
            acc("centrifugal_yz", w * (ra * psi.T @ S2 @ psi + (i_p - i_d) * pt.T @ S2 @ pt))
            acc("spin_acceleration", w * i_p * pt.T @ UPPER @ pt)
            # seed formulation: shaft rotary terms in slopes psi'
            acc("seed_gyroscopic", w * i_p * dpsi.T @ J2 @ dpsi)
            acc("seed_centrifugal_z", w * (ra * psi.T @ E11 @ psi + i_p * dpsi.T @ E22 @ dpsi))
            acc("seed_centrifugal_y", w * (ra * psi.T @ E22 @ psi + i_p * dpsi.T @ E11 @ dpsi))
            acc("seed_centrifugal_yz", w * (ra * psi.T @ S2 @ psi + (i_p - i_d) * dpsi.T @ S2 @ dpsi))
            acc("seed_spin_acceleration", w * i_p * dpsi.T @ LOWER @ dpsi)
            # tension shape integrals for n(x) = a0 + a1 x + a2 x^2 (per unit Omega^2), local s
            acc("tension_0", w * dpsi.T @ dpsi)
            acc("tension_1", w * s * dpsi.T @ dpsi)
            acc("tension_2", w * s * s * dpsi.T @ dpsi)
            # forcing shape vectors: columns (v, w, theta_y, theta_z) integrated with 1 and s
            acc("forcing_0", w * np.vstack([psi, pt]).T)
            acc("forcing_1", w * s * np.vstack([psi, pt]).T)
        self.tension = (out.pop("tension_0"), out.pop("tension_1"), out.pop("tension_2"))  # int s^k psi'^T psi'
        self.forcing_shapes = (out.pop("forcing_0"), out.pop("forcing_1"))  # (8, 4): int psi, int s psi
        out["mass"] = out["translational_mass"] + out["rotary_mass"]
        self.matrices = RotorMatrices(**out, axial_stiffening=np.zeros((8, 8)))

    def axial_stiffening(self, x0: float, tension_at_x0: float) -> np.ndarray:
        """K_G of the element at [x0, x0 + Le] under the tension per unit (Oy^2 + Oz^2) of docs/physics.md#forcing,
        n(x) = rho A (L^2 - x^2) / 2 + the disks beyond: ``tension_at_x0`` is n(x0)."""
        t0, t1, t2 = self.tension
        ra = self.section.rho_A
        return tension_at_x0 * t0 - ra * x0 * t1 - ra / 2 * t2

    def forcing(self, x0: float) -> np.ndarray:
        """(8, 4) load shapes for a1..a4 of an element starting at x0 (integrated with x = x0 + s)."""
        F0, F1 = self.forcing_shapes  # columns v, w, theta_y, theta_z
        Fx = x0 * F0 + F1
        ra, i_d, i_p = self.section.rho_A, self.section.i_d, self.section.i_p
        f = np.zeros((8, 4))
        f[:, 0] = -ra * Fx[:, 0] - i_d * F0[:, 3]
        f[:, 1] = ra * Fx[:, 1] - i_d * F0[:, 2]
        f[:, 2] = -i_p * F0[:, 2]
        f[:, 3] = i_p * F0[:, 3]
        return f


@dataclass(frozen=True)
class DiskProps:
    node: int  # 1-based node
    m: float  # kg
    Ip: float  # kg m^2
    Id: float  # kg m^2


def disk_props(disk: DiskConfig, density: float) -> DiskProps:
    D, d, t = disk.diameter, disk.bore, disk.thickness
    m = density * np.pi * (D**2 - d**2) * t / 4.0
    Ip = m * (D**2 + d**2) / 8.0
    Id = Ip / 2.0 + m * t**2 / 12.0
    return DiskProps(disk.node, m, Ip, Id)


class DiskElement:
    """A rigid disk on one node (4 DOFs [v, w, theta_y, theta_z]), as ROSS's DiskElement.

    ``seed_disk_H``: ``literal`` gives the seed formulation's Hs the printed pattern, ``consistent`` the derived
    H1's sign (docs/physics.md#formulations).
    """

    def __init__(self, props: DiskProps, seed_disk_H: str = "literal"):
        self.props = props
        m, Ip, Id = props.m, props.Ip, props.Id
        z2 = np.zeros((2, 2))

        def blk(a, b):
            return np.block([[a, z2], [z2, b]])

        self.matrices = RotorMatrices(
            mass=np.diag([m, m, Id, Id]),
            translational_mass=np.diag([m, m, 0.0, 0.0]),
            rotary_mass=np.diag([0.0, 0.0, Id, Id]),
            shaft_stiffness=np.zeros((4, 4)),
            gyroscopic=blk(z2, -Ip * J2),
            coriolis=blk(m * J2, Id * J2),
            spin_roll=np.diag([0.0, 0.0, Ip, Ip]),
            centrifugal_z=np.diag([m, 0.0, Ip - Id, 0.0]),
            centrifugal_y=np.diag([0.0, m, 0.0, Ip - Id]),
            centrifugal_yz=blk(m * S2, (Ip - Id) * S2),
            spin_acceleration=blk(z2, Ip * UPPER),
            seed_gyroscopic=blk(z2, Ip * J2),
            seed_centrifugal_z=np.diag([m, 0.0, Ip, 0.0]),
            seed_centrifugal_y=np.diag([0.0, m, 0.0, Ip]),
            seed_centrifugal_yz=blk(m * S2, (Ip - Id) * S2),
            seed_spin_acceleration=blk(z2, Ip * LOWER if seed_disk_H == "literal" else -Ip * UPPER),
            axial_stiffening=np.zeros((4, 4)),
        )

    def forcing(self, xd: float) -> np.ndarray:
        """(4, 4) load shapes for a1..a4 of the disk at axial position xd (m)."""
        return disk_forcing(self.props, xd)


def disk_forcing(dp: DiskProps, xd: float) -> np.ndarray:
    """(4, 4) load shapes of a disk at axial position xd (m) on [v, w, theta_y, theta_z] for a1..a4 (4.7).

    a1 = dOz + Ox Oy, a2 = dOy - Ox Oz, a3 = Phi Oz, a4 = Phi Oy.
    """
    f = np.zeros((4, 4))
    f[0, 0], f[3, 0] = -dp.m * xd, -dp.Id
    f[1, 1], f[2, 1] = dp.m * xd, -dp.Id
    f[2, 2] = -dp.Ip
    f[3, 3] = dp.Ip
    return f


@dataclass(frozen=True)
class FEModel:
    """Global constant matrices (n x n, n = 4 * nodes) and forcing shapes of the free rotor.

    ``matrices``: :class:`RotorMatrices` (no structural damping yet); ``forcing`` is (n, 4): the load vectors
    f1..f4 of docs/physics.md#forcing for the coefficients a1 = dOz + Ox*Oy, a2 = dOy - Ox*Oz, a3 = Phi*Oz,
    a4 = Phi*Oy.
    """

    matrices: RotorMatrices
    forcing: np.ndarray
    node_x: np.ndarray
    disks: tuple[DiskProps, ...]
    section: Section

    @property
    def n(self) -> int:
        return self.matrices.n

    def dof_names(self) -> list[str]:
        return [f"n{k + 1}_{d}" for k in range(len(self.node_x)) for d in DOF_NAMES]


def dof_index(node: int, dof: int) -> int:
    """Global 0-based index of node (1-based) and DOF j (0..3)."""
    return 4 * (node - 1) + dof


def assemble(cfg: RotorConfig) -> FEModel:
    """Assemble the constant matrices of the shaft and disks (no bearings)."""
    sec = section_of(cfg)
    ne, Le = cfg.shaft.elements, sec.length
    n = 4 * (ne + 1)
    shaft = ShaftElement(sec)  # a uniform shaft: every element is the same
    mats = RotorMatrices.zeros(n)
    forcing = np.zeros((n, 4))
    node_x = np.arange(ne + 1) * Le
    disks = tuple(DiskElement(disk_props(d, cfg.shaft.density), cfg.seed_disk_H) for d in cfg.disks)
    L = cfg.shaft.length
    for e in range(ne):
        idx = slice(4 * e, 4 * e + 8)
        mats.add_block(idx, shaft.matrices)
        x0 = node_x[e]
        # tension per unit (Oy^2 + Oz^2) with the thrust bearing at x = 0 (docs/physics.md#forcing):
        # n(x) = rhoA (L^2 - x^2)/2 + sum of m x_d over disks beyond x; x = x0 + s
        disk_term = sum(d.props.m * node_x[d.props.node - 1] for d in disks if node_x[d.props.node - 1] > x0 + 1e-12)
        mats.axial_stiffening[idx, idx] += shaft.axial_stiffening(x0, sec.rho_A * (L**2 - x0**2) / 2 + disk_term)
        forcing[idx] += shaft.forcing(x0)
    for disk in disks:
        idx = slice(4 * (disk.props.node - 1), 4 * disk.props.node)
        mats.add_block(idx, disk.matrices)
        forcing[idx] += disk.forcing(node_x[disk.props.node - 1])
    return FEModel(matrices=mats, forcing=forcing, node_x=node_x, disks=tuple(d.props for d in disks), section=sec)
