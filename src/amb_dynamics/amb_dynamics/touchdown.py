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
    rho = np.hypot(r[:, 0], r[:, 1])
    delta = rho - clearance
    force = np.zeros_like(r)
    normal = np.zeros(len(r))
    hit = delta > 0.0
    if hit.any():
        n = r[hit] / rho[hit, None]
        t = np.stack([-n[:, 1], n[:, 0]], axis=1)
        vn = np.sum(v[hit] * n, axis=1)
        fn = np.maximum(stiffness * delta[hit] + damping * vn, 0.0)
        vs = np.sum(v[hit] * t, axis=1) + spin * radius
        ft = -friction * fn * np.tanh(vs / V_SLIP)
        force[hit] = -fn[:, None] * n + ft[:, None] * t
        normal[hit] = fn
    return ContactForces(force, delta, normal)
