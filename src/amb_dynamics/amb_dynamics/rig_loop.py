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
    stepper = RigStepper(model, cfg, motion, steps, x0, Ts, fail_at_s, current_limit)
    stepper.advance(steps)
    return stepper.run()


class RigStepper:
    """``simulate_rig`` a chunk at a time: ``advance(k)`` steps up to step k; ``run()`` is the run so far.

    For a caller that may stop early (a Monte Carlo run that ends once its monitors have flagged): the arrays are
    those of the whole run, filled as far as it went; the same steps give the same numbers as ``simulate_rig``.
    """

    def __init__(self, model, cfg, motion, steps, x0=None, Ts=None, fail_at_s=None, current_limit=None):
        Ts = Ts if Ts is not None else 1.0 / cfg.controller.rate_hz
        limit = cfg.controller.current_limit if current_limit is None else current_limit
        self.plant = plant = RigPlant(model, cfg, Ts, current_limit=limit, motion=motion)
        self.ctrl = RigController(cfg, model.gains, Ts, limit, fail_at_s)
        self.steps, self.k = steps, 0
        self.t = np.arange(steps + 1) * Ts
        Om, dOm = motion.angular_velocity(self.t)
        self.Om, self.dOm = np.ascontiguousarray(Om.T), np.ascontiguousarray(dOm.T)
        self.x = np.zeros((steps + 1, plant.N))
        self.x[0] = levitated_state(plant, cfg)
        if x0 is not None:
            self.x[0, : len(x0)] += x0
        self.y = np.empty((steps + 1, 4))
        self.disp = np.empty((steps + 1, 4))
        self.cur = np.empty((steps, 4))
        self.spin = np.empty(steps + 1)
        self.closed = False  # the closing sample (k = steps) is measured

    @property
    def measured(self) -> int:
        """Samples k = 0 .. measured - 1 are measured (y, displacement, spin)."""
        return self.k + 1 if self.closed else self.k

    def advance(self, k_end: int) -> None:
        """Steps self.k .. min(k_end, steps) - 1; the closing sample is measured once the last step is done."""
        plant, ctrl, x, y, disp, cur, spin = self.plant, self.ctrl, self.x, self.y, self.disp, self.cur, self.spin
        Om, dOm = self.Om, self.dOm
        k_end = min(k_end, self.steps)
        for k in range(self.k, k_end):
            y[k] = plant.measure(x[k])
            disp[k] = plant.displacement(x[k])
            spin[k] = plant.spin_speed()
            cur[k] = ctrl.step(k, y[k])
            x[k + 1] = plant.step(x[k], cur[k], Om[k], dOm[k])
        self.k = max(self.k, k_end)
        if self.k == self.steps and not self.closed:
            y[self.k] = plant.measure(x[self.k])
            disp[self.k] = plant.displacement(x[self.k])
            spin[self.k] = plant.spin_speed()
            self.closed = True

    def run(self) -> RigRun:
        """The run up to the last measured sample."""
        n = self.measured
        return RigRun(self.t[:n], self.x[:n], self.y[:n], self.disp[:n], self.cur[: min(n, self.steps)],
                      self.spin[:n], self.plant.contact.events, self.plant.labels)  # fmt: skip
