"""The digital loop's Floquet multiplier about its forced periodic orbit (docs/physics.md#orbit).

The monitor's model value (:func:`amb_dynamics.digital_floquet.estimate_point` with the bearing law's tangent at
the levitated point) is the loop linearised at rest on a level base.  On a tilting base gravity turns in the base
frame and the loop answers with a forced orbit; with the nonlinear bearing law the orbit changes the tangent the
rotor sees, and a large orbit changes the multiplier.  This module computes the multiplier about that orbit:

1. Period: the orbit repeats once per base period T2 = 2 pi / omega (gravity follows the attitude), A(t) twice; the
   loop is sampled at Ts' = T2 / m for integers m near T2 / Ts (as ``estimate_point`` does, then interpolated in
   the sampling ratio with its error bound).
2. The orbit: a fixed point of the period map P(z), z = [plant state; controller state], P = m steps of the rig
   plant (``RigPlant.step``: gravity, base forcing, amplifier, sensor filter, the nonlinear bearing law; the noises,
   unbalance and runout, which are not periodic in T2, off) closed by the controller's linear form
   (``discrete_controller``) plus its bias-current offsets.  Newton-chord iterations
   z <- z - (M0 - I)^-1 (P(z) - z) with M0 the monodromy of step 3 along the first iterate, to a residual of
   ``ORBIT_TOL`` times the orbit's size.
3. The linearisation: M = F_{m-1} ... F_0, F_k the ``SampledLoop`` step map at the rates of step k with the bearing
   law's tangent (dF/di, -dF/dy per axis) at the mean of the orbit's samples k and k + 1 (second order in Ts).
4. max|mu| per period T of A(t) (pi / omega for pitch, as everywhere else): max|eig M|^(T / T2).

Independent of the rig's own stepping (exact exponentials of the tangent against the rig's predictor-corrector of
the law), it is checked against the rig's growth on the orbit (tests/test_orbit_floquet.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .config import RotorConfig, apply_override, config_from_dict, to_dict
from .control_law import discrete_controller
from .digital_floquet import plan_ratio
from .errors import InputError
from .magnet import BearingLaw
from .motion import BaseMotion
from .rig_loop import levitated_state
from .rig_plant import RigPlant
from .sampled import SampledLoop
from .structure import StructuralModel

ORBIT_TOL = 1e-10  # |P(z) - z| / |z| at which the orbit counts as found
MAX_ITERATIONS = 12


@dataclass(frozen=True)
class Orbit:
    """The forced orbit at one sampling ratio and the multipliers about it."""

    steps: int  # m samples per base period T2
    z0: np.ndarray  # [plant state; controller state] at t = 0
    displacement: np.ndarray  # (m + 1, 4) AMB displacements along the orbit (m)
    current: np.ndarray  # (m + 1, 4) bearing currents along the orbit (A)
    residual: float  # |P(z0) - z0| / |z0|
    iterations: int
    max_abs_per_T2: float  # max|eig M| over the base period T2


def quiet_config(cfg: RotorConfig) -> RotorConfig:
    """cfg without what is not periodic in the base period: force and sensor noise, unbalance, runout."""
    data = to_dict(cfg)
    items = ["disturbances.force_noise_rms_bearing=0", "disturbances.force_noise_rms_disk=0", "sensor.noise_rms=0",
             "sensor.runout=0"]  # fmt: skip
    for j in range(len(cfg.disks)):
        items += [f"disks.{j}.balance_grade=null", f"disks.{j}.unbalance=0"]
    for item in items:
        apply_override(data, item)
    return config_from_dict(data)


class _Loop:
    """The nonlinear digital loop at Ts' = T2 / m and its linearisation along a trajectory."""

    def __init__(self, model: StructuralModel, cfg: RotorConfig, motion: BaseMotion, T2: float, m: int):
        self.m, self.Ts = m, T2 / m
        self.plant = RigPlant(model, cfg, self.Ts, motion=motion)
        self.K = discrete_controller(cfg, model.gains, self.Ts, cfg.controller.delay_samples)
        off = cfg.controller.bias_current_offset
        self.offset = np.array(off, dtype=float) if off else np.zeros(4)
        t = np.arange(m + 1) * self.Ts
        Om, dOm = motion.angular_velocity(t)
        self.Om, self.dOm = np.ascontiguousarray(Om.T), np.ascontiguousarray(dOm.T)
        self.lin = SampledLoop(model, cfg, Ts=self.Ts, forcing=False)
        self.law = BearingLaw.from_config(cfg.bearings) if cfg.bearings.force_law == "nonlinear" else None
        self.ki = np.full(4, cfg.bearings.current_stiffness)
        self.ks = np.full(4, cfg.bearings.displacement_stiffness)
        self.N, self.nc = self.plant.N, self.K.n_states

    def start(self, cfg: RotorConfig) -> np.ndarray:
        """The levitated state with the controller at its steady state there (Newton's first iterate)."""
        x = levitated_state(self.plant, cfg)
        y = self.plant.measure(x)
        xc = np.linalg.lstsq(np.eye(self.nc) - self.K.A, self.K.B @ y, rcond=None)[0] if self.nc else np.zeros(0)
        return np.concatenate([x, xc])

    def period(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """P(z), and the AMB displacements and bearing currents at the m + 1 samples."""
        plant, K, N = self.plant, self.K, self.N
        plant.reset()
        x, xc = z[:N].copy(), z[N:].copy()
        disp, cur = np.empty((self.m + 1, 4)), np.empty((self.m + 1, 4))
        amp = plant.lin.layout.amp
        for k in range(self.m + 1):
            y = plant.measure(x)
            u = K.C @ xc + K.D @ y + self.offset
            disp[k] = plant.displacement(x)
            cur[k] = x[amp] if amp is not None else u
            if k == self.m:
                break
            x = plant.step(x, u, self.Om[k], self.dOm[k])
            xc = K.A @ xc + K.B @ y
        return np.concatenate([x, xc]), disp, cur

    def monodromy(self, disp: np.ndarray, cur: np.ndarray) -> np.ndarray:
        """Product of the step maps linearised about the trajectory (disp, cur) over the m steps."""
        M = np.eye(self.N + self.nc)
        for k in range(self.m):
            if self.law is not None:
                y, i = 0.5 * (disp[k] + disp[k + 1]), 0.5 * (cur[k] + cur[k + 1])
                self.lin.plant.set_bearing_gains(self.law.current_gain(y, i), self.law.negative_stiffness(y, i))
            elif k == 0:
                self.lin.plant.set_bearing_gains(self.ki, self.ks)
            M = self.lin.step_map(self.Om[k], self.dOm[k]) @ M
        return M

    def orbit(self, z: np.ndarray, J: np.ndarray | None = None) -> tuple[Orbit, np.ndarray]:
        """Newton-chord on P(z) = z from z (see the module docstring), with the chord J = M - I of the first
        iterate unless one is given (another ratio's: the orbits differ by a fraction of a sample); returns the
        orbit and the chord."""
        Pz, disp, cur = self.period(z)
        if J is None:
            J = self.monodromy(disp, cur) - np.eye(z.size)
        scale = max(float(np.linalg.norm(z)), 1e-12)
        residual = float(np.linalg.norm(Pz - z)) / scale
        it = 0
        while residual > ORBIT_TOL and it < MAX_ITERATIONS:
            z = z - np.linalg.solve(J, Pz - z)
            Pz, disp, cur = self.period(z)
            residual = float(np.linalg.norm(Pz - z)) / scale
            it += 1
        rho = float(np.abs(np.linalg.eigvals(self.monodromy(disp, cur))).max())
        return Orbit(self.m, z, disp, cur, residual, it, rho), J


def orbit_floquet(model: StructuralModel, cfg: RotorConfig, motion: BaseMotion, period: float) -> dict:
    """max|mu| per ``period`` (that of A(t)) of the digital loop about its forced orbit on ``motion``, one
    harmonic of base period T2 = 2 pi / omega, a whole multiple of ``period``; at the config's rate: exact where
    T2 / Ts is an integer, else interpolated in the ratio from the three integers nearest
    (``digital_floquet.plan_ratio``), with its error bound."""
    if len(motion.harmonics) != 1:
        raise InputError("the orbit's multiplier needs a base motion of one harmonic")
    omega = motion.harmonics[0].frequency
    T2 = 2.0 * math.pi / omega
    per = T2 / period
    if not (np.isfinite(per) and per >= 1.0 - 1e-9 and abs(per - round(per)) < 1e-9):
        raise InputError(f"the base period {T2:.6g} s is not a whole multiple of the period {period:.6g} s of A(t)")
    cfg = quiet_config(cfg)
    plan = plan_ratio(T2 * cfg.controller.rate_hz, max_r=1)
    orbits: list[Orbit] = []
    z, J = None, None
    for m, _ in plan.ratios:
        loop = _Loop(model, cfg, motion, T2, m)
        orbit, J = loop.orbit(loop.start(cfg) if z is None else z, J)
        orbits.append(orbit)
        z = orbit.z0
    worst = max(o.residual for o in orbits)
    if worst > 1e3 * ORBIT_TOL:
        raise InputError(f"no periodic orbit found (residual {worst:.2g} after {MAX_ITERATIONS} iterations)")
    per_T2, bound_T2 = plan.combine([o.max_abs_per_T2 for o in orbits])
    n = round(per)
    rho = per_T2 ** (1.0 / n)
    nearest = min(orbits, key=lambda o: abs(o.steps - plan.x))
    swing = np.abs(nearest.displacement - nearest.displacement.mean(axis=0)).max(axis=0)
    return {
        "max_abs_multiplier": rho,
        "error_bound": bound_T2 * rho / (n * per_T2),  # d(x^(1/n)) = x^(1/n) dx / (n x)
        "period_s": period,
        "base_period_s": T2,
        "sampling_ratio": plan.x,
        "method": "orbit, " + plan.method,
        "steps": int(sum(o.steps for o in orbits)),
        "ratio_values": [[o.steps, o.max_abs_per_T2 ** (1.0 / n)] for o in orbits],
        "orbit_swing_m": swing.tolist(),
        "orbit_residual": worst,
        "newton_iterations": [o.iterations for o in orbits],
    }
