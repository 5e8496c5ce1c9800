"""Gravity in the base frame and the static load it puts on the AMBs (issue 15).

Axes of the base frame B: X along the undeformed shaft, Y vertical up and Z horizontal when the base is
level.  Gravity is g_B = R^T (0, -g, 0), R the base->inertial rotation, so that pitch (about Z) and roll
(about X) turn it; the X component is axial and the model has no axial degree of freedom (it is carried by
the thrust bearing).  The rotor on its two AMB supports is statically determinate: the AMB loads follow from
equilibrium alone, whatever the shaft stiffness or the controller gains.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .config import RotorConfig
from .fe import FEModel, assemble
from .structure import selection_matrix


def gravity_base_frame(quat_xyzw: np.ndarray | None, g: float = 9.81) -> np.ndarray:
    """g_B (m/s^2) for base attitudes given as quaternions (x, y, z, w) of base->inertial, shape (..., 3).

    ``None`` is the level base: (0, -g, 0).
    """
    down = np.array([0.0, -g, 0.0])
    if quat_xyzw is None:
        return down
    from scipy.spatial.transform import Rotation  # here: ~0.2 s to import, and no node's start needs it

    q = np.asarray(quat_xyzw, dtype=float)
    return Rotation.from_quat(q.reshape(-1, 4)).inv().apply(down).reshape((*q.shape[:-1], 3))


def gravity_yz(q: tuple[float, float, float, float], g: float) -> tuple[float, float]:
    """(Y, Z) components of g_B = R^T (0, -g, 0) for one base->inertial quaternion q = (x, y, z, w), in floats (the
    plant's per-step path; :func:`gravity_base_frame` is the array form)."""
    x, y, z, w = q
    # second row of R (inertial Y in base axes) times -g: R^T e_Y = (R[1, 0], R[1, 1], R[1, 2])
    return -g * (1.0 - 2.0 * (x * x + z * z)), -g * 2.0 * (y * z - w * x)


def attitude_step(q: tuple[float, ...], w: tuple[float, float, float], dt: float) -> tuple[float, ...]:
    """The attitude q (x, y, z, w; base->inertial) after turning at the body rate w (rad/s) for dt: q (x) exp(w dt/2),
    the exact rotation of a rate held over the step, renormalised."""
    wx, wy, wz = w
    norm = math.sqrt(wx * wx + wy * wy + wz * wz)
    if norm == 0.0:
        return q
    s = math.sin(0.5 * norm * dt) / norm
    bx, by, bz, bw = wx * s, wy * s, wz * s, math.cos(0.5 * norm * dt)
    ax, ay, az, aw = q
    out = (
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    )
    n = math.sqrt(sum(c * c for c in out))
    return tuple(c / n for c in out)


def translation_patterns(fe: FEModel) -> np.ndarray:
    """(n_fe, 2): rigid unit translation along Y (v DOFs) and Z (w DOFs), rotations zero."""
    T = np.zeros((fe.n, 2))
    T[0::4, 0] = 1.0
    T[1::4, 1] = 1.0
    return T


def gravity_load_shapes(fe: FEModel) -> np.ndarray:
    """(n_fe, 2): consistent FE load of a unit acceleration field along Y and Z: f = M T.

    The shape functions reproduce a rigid translation with zero slope, so M T is the distributed weight
    (shaft and disks) lumped consistently, nodal moments included.  The load of g_B is shapes @ g_B[1:].
    """
    return fe.matrices.mass @ translation_patterns(fe)


@dataclass(frozen=True)
class StaticLoad:
    """Static equilibrium of the rotor on ideal supports at the AMB nodes.

    forces : (4,) N, force each AMB axis exerts on the rotor (channels amb<i>_y, amb<i>_z), + along +Y/+Z.
    currents : (4,) A, control current that produces it at the centred rotor (force +ki i).
    deflection : (n_fe,) FE DOFs of the sag between and beyond the supports (m, rad).
    """

    forces: np.ndarray
    currents: np.ndarray
    deflection: np.ndarray


def static_amb_load(cfg: RotorConfig, quat_xyzw: np.ndarray | None = None, fe: FEModel | None = None) -> StaticLoad:
    """AMB loads that hold the rotor centred at its AMBs under gravity at one base attitude (base at rest).

    Solves K_B q = f_g + Ba R with Ba^T q = 0 (the AMB nodes held at the centre): the reactions R are the
    forces the AMBs must deliver, the same for any shaft stiffness (two supports: statically determinate).
    """
    fe = fe if fe is not None else assemble(cfg)
    g_B = gravity_base_frame(quat_xyzw, cfg.gravity.g)
    f = gravity_load_shapes(fe) @ g_B[1:]
    Ba = selection_matrix(fe.n, cfg.bearings.nodes)
    n, m = fe.n, Ba.shape[1]
    S = np.zeros((n + m, n + m))
    S[:n, :n] = fe.matrices.shaft_stiffness
    S[:n, n:] = -Ba
    S[n:, :n] = Ba.T
    sol = np.linalg.solve(S, np.concatenate([f, np.zeros(m)]))
    forces = sol[n:]
    return StaticLoad(forces, forces / cfg.bearings.current_stiffness, sol[:n])
