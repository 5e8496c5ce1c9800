"""Touchdown (backup) bearing contact: a pure function of the rotor's state at the backup-bearing nodes.

Radial contact with a fixed ring of radial clearance c.  At a node with displacement r = (y, z) and velocity
v, the penetration is delta = |r| - c.  In contact (delta > 0), with n = r/|r| and t = (-n_z, n_y) (the
direction the spin turns, from +Y toward +Z):

- normal force   F_n = max(k delta + d (v . n), 0) along -n (penalty stiffness and damping, no adhesion);
- slip velocity  v_s = v . t + Phi R (the journal surface, radius R, spinning at Phi, against the fixed race);
- friction       F_t = -mu F_n tanh(v_s / V_SLIP) along t (Coulomb, smoothed below V_SLIP).

For a positive spin the friction pushes the journal along -t: it drives backward whirl, as a rotor that
lands on its backup bearings does.  The friction torque on the spin is not fed back (the spin follows its
prescribed profile).  Units: m, m/s, rad/s, N.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

V_SLIP = 1e-3  # m/s, width of the smoothed Coulomb law


@dataclass(frozen=True)
class ContactForces:
    """Per node: force (m, 2) N on (y, z), penetration (m,) m (<= 0: no contact), normal force (m,) N."""

    force: np.ndarray
    penetration: np.ndarray
    normal: np.ndarray


def contact_forces(
    r: np.ndarray,
    v: np.ndarray,
    spin: float,
    radius: float,
    clearance: float,
    stiffness: float,
    damping: float = 0.0,
    friction: float = 0.0,
) -> ContactForces:
    """Backup-bearing forces at m nodes: r, v (m, 2) displacement (m) and velocity (m/s) on (y, z).

    spin : total spin rate Phi (rad/s); radius : journal radius R (m).
    """
    r = np.atleast_2d(np.asarray(r, dtype=float))
    v = np.atleast_2d(np.asarray(v, dtype=float))
    # per node in floats: the plant evaluates a few nodes twice per sub-step, where numpy's per-call overhead on
    # arrays of two rows was most of the cost of a step in contact
    slide = spin * radius
    force, delta, normal = [], [], []
    for (y, z), (vy, vz) in zip(r.tolist(), v.tolist(), strict=True):
        rho = math.hypot(y, z)
        d = rho - clearance
        delta.append(d)
        if d <= 0.0:
            force.append((0.0, 0.0))
            normal.append(0.0)
            continue
        ny, nz = y / rho, z / rho  # n; t = (-nz, ny)
        fn = max(stiffness * d + damping * (vy * ny + vz * nz), 0.0)
        ft = -friction * fn * math.tanh((-vy * nz + vz * ny + slide) / V_SLIP)
        force.append((-fn * ny - ft * nz, -fn * nz + ft * ny))
        normal.append(fn)
    return ContactForces(np.array(force).reshape(-1, 2), np.array(delta), np.array(normal))
