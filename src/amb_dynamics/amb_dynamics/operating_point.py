"""The rotor at rest on its controller under gravity: the levitated operating point, and the bearing law's
tangent there (docs/physics.md#operating-point).

With gravity the controller holds the rotor with static currents (its bias offsets and kp times the sag), so a
nonlinear bearing (``bearings.force_law: nonlinear``) works about (y_s, i_s), not about the centre: its current
gain is dF/di and its negative stiffness -dF/dy there (ks (1 + (i_s/i0)^2) at the centred rotor, 22 % more
negative on the real rig's heavier AMB).  The sensitivity model of the running loop uses that tangent.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .config import RotorConfig
from .gravity import gravity_base_frame, gravity_load_shapes
from .magnet import BearingLaw
from .structure import StructuralModel


@dataclass(frozen=True)
class OperatingPoint:
    q: np.ndarray  # (n,) generalised coordinates at rest
    y: np.ndarray  # (4,) AMB displacements (m)
    i: np.ndarray  # (4,) control currents (A)


def operating_point(model: StructuralModel, cfg: RotorConfig, start_gain: np.ndarray) -> OperatingPoint:
    """Steady state of the controller's start gain K0 (i = offset + K0 y; the PID: offset - kp y) with the
    bias-current offset under gravity at a level base: (K_B + ks Ba Ba^T - ki Ba K0 Ba^T) q = f_g + ki Ba offset.
    Zero without gravity (and without offsets)."""
    g = model.gains
    Ba, n = model.Ba, model.n
    off = np.array(cfg.controller.bias_current_offset or (0.0,) * Ba.shape[1], dtype=float)
    if not cfg.gravity.enabled:
        return OperatingPoint(np.zeros(n), np.zeros(Ba.shape[1]), np.zeros(Ba.shape[1]))
    Psi = model.basis if model.basis is not None else np.eye(model.fe.n)
    f_g = Psi.T @ gravity_load_shapes(model.fe) @ gravity_base_frame(None, cfg.gravity.g)[1:]
    K = model.matrices.shaft_stiffness + g.ks * Ba @ Ba.T - g.ki * Ba @ start_gain @ Ba.T
    q = np.linalg.solve(K, f_g + g.ki * Ba @ off)
    y = Ba.T @ q
    return OperatingPoint(q, y, off + start_gain @ y)


def tangent_gains(cfg: RotorConfig, op: OperatingPoint) -> tuple[np.ndarray, np.ndarray]:
    """(ki, ks) per AMB axis of the bearing law linearised at the operating point: the config's constants for a
    linear law, the tangent dF/di, -dF/dy of the nonlinear law (magnet saturation and current clipping aside)."""
    g = cfg.bearings
    ki = np.full(op.y.shape, g.current_stiffness)
    ks = np.full(op.y.shape, g.displacement_stiffness)
    if g.force_law != "nonlinear":
        return ki, ks
    law = BearingLaw.from_config(g)
    return law.current_gain(op.y, op.i), law.negative_stiffness(op.y, op.i)
