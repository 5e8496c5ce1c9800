"""The digital loop on the rig plant, offline: the controller the node runs (``RigController``) closed around
``RigPlant`` exactly as the lockstep node suite closes it (y_k measured, i_k = controller(y_k), x_{k+1} =
plant.step(x_k, i_k, base rates of sample k)).  The Newmark simulation stays the independent check of the
continuous analyses; this is the sampled-data loop with every real-rig effect.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .amb import DiscretePID, DiscretePIDCoefficients
from .config import RotorConfig
from .control_runtime import ControlLaw, new_control_law
from .motion import BaseMotion
from .operating_point import operating_point, tangent_gains
from .rig_plant import RigPlant
from .structure import StructuralModel


class RigController:
    """Discrete PID (with its filters, or the user's state space: :class:`amb_dynamics.control_runtime.ControlLaw`)
    + static bias-current offset, clamped at current_limit; zero current from fail_at_s on.

    The one implementation of the controller node's command (lockstep and offline alike).
    """

    def __init__(self, cfg: RotorConfig, gains, Ts: float, current_limit: float | None, fail_at_s: float | None):
        self.law = control_law_runtime(cfg, gains, Ts, current_limit)
        off = cfg.controller.bias_current_offset
        self.offset = np.array(off, dtype=float) if off else None
        self.limit = current_limit
        self.fail_step = None if fail_at_s is None or fail_at_s < 0 else round(fail_at_s / Ts)
        self.zero = np.zeros(4)

    def failed(self, k: int) -> bool:
        return self.fail_step is not None and k >= self.fail_step

    def step(self, k: int, y: np.ndarray) -> np.ndarray:
        """Current (A) answering sample k."""
        if self.failed(k):
            return self.zero
        u = self.law.step(y)
        if self.offset is not None:
            u = u + self.offset
            if self.limit is not None:
                u = np.clip(u, -self.limit, self.limit)
        return u


def control_law_runtime(cfg: RotorConfig, gains, Ts: float, current_limit: float | None) -> DiscretePID | ControlLaw:
    """The digital controller of cfg at period Ts (:func:`amb_dynamics.control_runtime.new_control_law`)."""
    return new_control_law(
        cfg, DiscretePIDCoefficients.from_gains(gains, Ts), current_limit, cfg.controller.delay_samples
    )


def start_gain(cfg: RotorConfig, gains, Ts: float) -> np.ndarray:
    """Current per displacement of the controller's first step (the PID: -kp; :class:`ControlLaw.start_gain`)."""
    law = control_law_runtime(cfg, gains, Ts, None)
    return law.start_gain if isinstance(law, ControlLaw) else -gains.kp * np.eye(4)


def levitated_bearing(model: StructuralModel, cfg: RotorConfig, Ts: float) -> tuple[np.ndarray, np.ndarray] | None:
    """(ki, ks) per AMB axis of a nonlinear bearing law linearised at the levitated operating point (gravity and
    the bias-current offsets load it: :mod:`amb_dynamics.operating_point`); None for a linear law, whose
    constants hold everywhere.  The loop the plant node runs about that point (``SampledLoop(bearing=...)``)."""
    if cfg.bearings.force_law != "nonlinear":
        return None
    return tangent_gains(cfg, operating_point(model, cfg, start_gain(cfg, model.gains, Ts)))


def levitated_state(plant: RigPlant, cfg: RotorConfig) -> np.ndarray:
    """Plant state at rest on the controller under gravity (base level, no spin effects): zero without gravity.

    The operating point of :func:`amb_dynamics.operating_point.operating_point` (the controller's start gain
    with the bias-current offset); the amplifier state = i, the filter state = y.  The run then starts levitated
    rather than dropping the overhung disk onto its shaft's elastic sag at t = 0.
    """
    model, lin = plant.model, plant.lin
    x = np.zeros(plant.N)
    if not plant.g:
        return x
    op = operating_point(model, cfg, start_gain(cfg, model.gains, plant.Ts))
    x[: model.n] = op.q
    if lin.layout.amp is not None:
        x[lin.layout.amp] = op.i
    if lin.layout.sens is not None:
        x[lin.layout.measured] = op.y
    return x


@dataclass
class RigRun:
    """Offline run on the rig plant (k = 0..steps)."""

    t: np.ndarray  # (K+1,) s
    x: np.ndarray  # (K+1, N) plant state
    y: np.ndarray  # (K+1, 4) measured displacement (m)
    displacement: np.ndarray  # (K+1, 4) true AMB displacement (m)
    i: np.ndarray  # (K, 4) commanded current (A)
    spin: np.ndarray  # (K+1,) spin speed (rad/s)
    contacts: list  # touchdown events [t_start, node, max penetration, peak force, t_end]
    labels: tuple


def simulate_rig(
    model: StructuralModel,
    cfg: RotorConfig,
    motion: BaseMotion,
    steps: int,
    x0: np.ndarray | None = None,
    Ts: float | None = None,
    fail_at_s: float | None = None,
    current_limit: float | None = None,
) -> RigRun:
    """The lockstep loop offline with every configured effect (``RigPlant`` and ``RigController``).

    Starts levitated (``levitated_state``, as the plant node does) plus ``x0`` ([q; q'] or the full plant state).
    """
    Ts = Ts if Ts is not None else 1.0 / cfg.controller.rate_hz
    limit = cfg.controller.current_limit if current_limit is None else current_limit
    plant = RigPlant(model, cfg, Ts, current_limit=limit, motion=motion)
    ctrl = RigController(cfg, model.gains, Ts, limit, fail_at_s)
    N = plant.N
    t = np.arange(steps + 1) * Ts
    Om, dOm = motion.angular_velocity(t)
    Om, dOm = np.ascontiguousarray(Om.T), np.ascontiguousarray(dOm.T)
    x = np.zeros((steps + 1, N))
    x[0] = levitated_state(plant, cfg)
    if x0 is not None:
        x[0, : len(x0)] += x0
    y = np.empty((steps + 1, 4))
    disp = np.empty((steps + 1, 4))
    cur = np.empty((steps, 4))
    spin = np.empty(steps + 1)
    for k in range(steps):
        y[k] = plant.measure(x[k])
        disp[k] = plant.displacement(x[k])
        spin[k] = plant.spin_speed()
        cur[k] = ctrl.step(k, y[k])
        x[k + 1] = plant.step(x[k], cur[k], Om[k], dOm[k])
    y[steps] = plant.measure(x[steps])
    disp[steps] = plant.displacement(x[steps])
    spin[steps] = plant.spin_speed()
    return RigRun(t, x, y, disp, cur, spin, plant.contact.events, plant.labels)
