"""The real-rig plant over one sample: the one stepping code of the plant node and the offline sampled-data run.

``RigPlant.step(x, i_cmd, Omega, dOmega)`` advances the plant state x = [q; q'; i_a; y_f(; y_f')]
(:mod:`amb_dynamics.plant_dynamics`) over one sample Ts with the commanded current held, base rates held at their
sample, the spin speed of the profile at t_k held:

* linear part: exact ZOH, ``expm(Ts Aaug)`` of [[A_p(Omega, Phi), B_i, B_f, B_F, B_u], ...] cached per (rates,
  spin) as PlantStepper caches its matrices; B_f are the base forcing inputs a1..a4, B_F held external node forces
  (gravity, force noise, nonlinear corrections), B_u the unbalance driven by a rotating oscillator
  [cos; sin](phi + Phi t), so that the unbalance response is exact at constant speed.  On the config's base
  motion about one axis the exponential is interpolated in the base rate (:class:`rate_family.RateFamily`, built
  once per spin speed and checked at build time to 1e-12 of each column) instead of computed per step;
* unbalance: U Phi^2 (cos, sin)(phi + phase) at each disk in the base frame, plus the tangential term
  U dPhi/dt (-sin, cos) during a ramp (the base rotation's share of the rotor's angle is neglected);
* gravity g_B = R^T (0, -g, 0), R the base attitude integrated from the held rates (exact rotation of each step),
  held over the step;
* seeded force noise (per step, at the disk and AMB nodes) and sensor noise: blocks of BLOCK steps drawn from a
  counter-based Philox generator keyed by (seed, block), so that any step's noise is the same for any caller;
* synchronous sensor runout r (cos, sin)(phi + phase) added to the filtered measurement, with the noise;
* amplifier: commanded current clamped at current_limit; the voltage limit as a slew-rate limit |di/dt| <= V/L
  (with a current loop: the command is moved so that the initial slope is V/L, first order in Ts);
* state-dependent forces (nonlinear bearing law minus its linearisation, touchdown contact): exponential
  trapezoidal predictor-corrector (ETD2), second order in the sub-step h; the step is split into ``substeps``
  sub-steps while a rotor node is near its backup bearing, one sub-step otherwise.

With every effect off ``step`` is PlantStepper's x_{k+1} = E x + Gamma i + g (no clamping), so that RigPlant
reproduces SampledLoop.simulate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from .config import RotorConfig
from .config_rig import disk_unbalance
from .fe import dof_index
from .gravity import attitude_step, gravity_yz
from .motion import BaseMotion
from .rate_family import RateFamily, single_axis_bounds
from .rig_forces import RigForces
from .sampled import CACHE_LIMIT, PlantStepper
from .spin import SpinProfile
from .structure import StructuralModel
from .system import coefficients_from_rates, forcing_from_rates

BLOCK = 256  # steps of noise per Philox draw
SPIN_GRID = 2.0 * math.pi / 30.0  # rad/s (2 rpm): during a ramp the step matrices are interpolated between these
FAMILY_LIMIT = 4  # step-exponential interpolants kept (spin speeds x sub-step lengths)
# per column, relative: an exact expm of the real rig's plant rows itself differs by ~3e-13 between rate values
# one rounding apart (entries up to 1e4 beside 1e-5), so a tighter bound would measure rounding, not interpolation
FAMILY_TOL = 1e-12
BOX_MARGIN = 1.05  # the interpolants cover 5 % more than the config motion's largest rates (a measured IMU)


@dataclass
class _Plan:
    """The command-free part of one step (RigPlant._plan): matrices, held forces, free response, next angles."""

    k: int
    x: np.ndarray
    rates: bytes  # Omega, dOmega
    near: bool
    m: int  # sub-steps
    h: float
    E: np.ndarray
    G: np.ndarray
    GFn: np.ndarray  # node-force columns
    GFa: np.ndarray  # their AMB-axis columns
    Gu: np.ndarray
    rot: np.ndarray  # the unbalance oscillator over one sub-step
    free: np.ndarray  # g + Gamma_F held
    cs: np.ndarray  # (cos, sin) of the spin angle
    base0: np.ndarray | None = None  # E x + free + Gu cs (one sub-step)
    f0: np.ndarray | None = None  # the bearing law's correction at x (when it does not need the command)
    angles: tuple = ()

    def fits(self, k: int, x: np.ndarray, Omega: np.ndarray, dOmega: np.ndarray) -> bool:
        return k == self.k and x is self.x and np.concatenate([Omega, dOmega]).tobytes() == self.rates


class RigPlant:
    """One-sample propagator of the real-rig plant (see module docstring).

    Parameters
    ----------
    model, cfg : the structural model and its config
    Ts : sample period (s)
    forcing : base-motion forcing (docs/physics.md#forcing); None = cfg.base_forcing
    current_limit : amplifier clamp (A); None = controller.current_limit
    motion : the base motion whose rates the step interpolants cover; None = cfg.base_motion (other rates are
        stepped exactly)
    """

    def __init__(
        self,
        model: StructuralModel,
        cfg: RotorConfig,
        Ts: float,
        forcing: bool | None = None,
        current_limit: float | None = None,
        motion: BaseMotion | None = None,
    ):
        self.lin = lin = PlantStepper(model, cfg, Ts, forcing)
        self.model, self.cfg, self.Ts, self.n, self.N = model, cfg, Ts, model.n, lin.N
        self.spin = SpinProfile.from_config(cfg)
        self.forces = RigForces(model, cfg, lin.layout)
        self.forces.set_rate(Ts)
        n, fe = model.n, model.fe
        Psi = model.basis if model.basis is not None else np.eye(fe.n)
        Minv = sla.inv(model.M)
        # held node forces: columns (y, z) of every force node, then gravity (y, z)
        nodes = self.forces.nodes
        S = np.zeros((fe.n, 2 * len(nodes) + 2))
        for j, node in enumerate(nodes):
            S[dof_index(node, 0), 2 * j], S[dof_index(node, 1), 2 * j + 1] = 1.0, 1.0
        S[0::4, -2], S[1::4, -1] = 1.0, 1.0  # rigid unit translations along Y, Z
        S[:, -2:] = fe.matrices.mass @ S[:, -2:]  # consistent load of a unit acceleration field
        self.S = Psi.T @ S
        self.BF = np.zeros((self.N, S.shape[1]))
        self.BF[n : 2 * n] = Minv @ self.S
        # unbalance per unit (cos, sin) of the spin angle: node force columns scaled later by Phi^2 and dPhi
        self.unb = [(nodes.index(d.node), *disk_unbalance(d, cfg.shaft.density, cfg.max_speed_rpm)) for d in cfg.disks]
        self.unb = [(j, U, ph) for j, U, ph in self.unb if U]
        self.g = cfg.gravity.g if cfg.gravity.enabled else 0.0
        self.slew = cfg.actuator.slew_limit
        self.limit = cfg.controller.current_limit if current_limit is None else current_limit
        sens, dist = cfg.sensor, cfg.disturbances
        self.runout = sens.runout
        self.runout_phase = math.radians(sens.runout_phase_deg)
        self.noise_y = sens.noise_rms
        amb = set(cfg.bearings.nodes)
        self.noise_f = np.repeat(
            [
                (dist.force_noise_rms_disk if node in self.forces.disk_nodes else 0.0)
                + (dist.force_noise_rms_bearing if node in amb else 0.0)
                for node in nodes
            ],
            2,
        )
        self.seed = dist.seed
        self.linear_only = not (
            self.unb or self.g or self.noise_f.any() or self.forces.active or self.slew or self.runout or self.noise_y
        )
        self._cache: dict[bytes, tuple] = {}
        self._last: tuple = (None, None)
        self._nf = 4 if np.any(lin.Bf) else 0  # base forcing inputs a1..a4 (docs/physics.md#forcing)
        motion = BaseMotion.from_config(cfg.base_motion) if motion is None else motion
        bounds = single_axis_bounds(motion.harmonics)
        self._axis = None if bounds is None else bounds[0]
        self._box = None if bounds is None else (BOX_MARGIN * bounds[1], BOX_MARGIN * bounds[2])
        self._families: dict[tuple[float, float], RateFamily] = {}
        self._noise_block = -1
        self._noise = np.zeros((BLOCK, 4 + self.noise_f.size))
        self.reset()

    # -- state of the effects -----------------------------------------------------------------------------
    def reset(self) -> None:
        """Step counter, spin angle and base attitude back to t = 0."""
        self.k = 0
        self.phi = 0.0  # spin angle relative to the base (rad)
        self.quat = (0.0, 0.0, 0.0, 1.0)  # base -> inertial (x, y, z, w)
        self._pre: _Plan | None = None  # the coming step's command-free part (prepare)
        self.contact = self.forces.new_contact_log()
        self._i_prev = np.zeros(4)
        self.saturated = 0  # steps with the command clamped or slew-limited
        self.max_command = 0.0  # largest |command| (A)

    @property
    def t(self) -> float:
        return self.k * self.Ts

    def spin_speed(self, k: int | None = None) -> float:
        """Spin phi_dot at step k (rad/s)."""
        return self.spin.speed(self.Ts * (self.k if k is None else k))

    # -- matrices -----------------------------------------------------------------------------------------
    def matrices(self, Omega: np.ndarray, dOmega: np.ndarray, spin: float, h: float | None = None):
        """(E, Gamma_i, g, Gamma_F, Gamma_u) of a (sub-)step h (default Ts) at held rates and spin.

        On a moving base about one axis the exponential comes from the step's RateFamily (interpolated, checked to
        STEP_TOL per column at build time); otherwise, and for rates outside the family's box, it is exact."""
        h = self.Ts if h is None else h
        key = np.concatenate([Omega, dOmega, (spin, h)]).tobytes()
        hit = self._cache.get(key)
        if hit is not None:
            return hit
        if self._last[0] == key:  # prepared ahead of the step while the cache is full
            return self._last[1]
        Om, dOm = np.asarray(Omega, float), np.asarray(dOmega, float)
        fam = self._family(Om, dOm, spin, h)
        if fam is not None:
            P = fam.at(float(Om[self._axis]), float(dOm[self._axis]))
        else:
            P = self._exponential(Om, dOm, spin, h)
        N, nf, m = self.N, self._nf, self.BF.shape[1]
        o = N + 4 + nf + m
        g = P[:, N + 4 : N + 4 + nf] @ forcing_from_rates(Om, dOm, spin) if nf else np.zeros(N)
        out = (P[:, :N], P[:, N : N + 4], g, P[:, N + 4 + nf : o], P[:, o : o + 2])
        if fam is None and len(self._cache) < CACHE_LIMIT:  # an interpolated step costs less than a lookup
            self._cache[key] = out
        self._last = (key, out)
        return out

    def _exponential(self, Om: np.ndarray, dOm: np.ndarray, spin: float, h: float) -> np.ndarray:
        """The plant rows of expm(h Aaug): [E, Gamma_i, Gamma_f (forcing a1..a4), Gamma_F, Gamma_u], N x columns."""
        lin, N, nf = self.lin, self.N, self._nf
        c = coefficients_from_rates(Om, dOm, spin)
        m = self.BF.shape[1]
        size = N + 4 + nf + m + 2
        aug = np.zeros((size, size))
        aug[:N, :N] = lin.Ap0 + np.tensordot(c[lin.Ap_idx], lin.Ap_stack, axes=1)
        aug[:N, N : N + 4] = lin.Bp
        aug[:N, N + 4 : N + 4 + nf] = lin.Bf[:, :nf]
        aug[:N, N + 4 + nf : N + 4 + nf + m] = self.BF
        o = N + 4 + nf + m  # unbalance oscillator (cos, sin): d/dt = Phi [[0, -1], [1, 0]]
        aug[o, o + 1], aug[o + 1, o] = -spin, spin
        aug[:N, o : o + 2] = self._unbalance_columns(spin)
        return sla.expm(h * aug)[:N]

    def _family(self, Om: np.ndarray, dOm: np.ndarray, spin: float, h: float) -> RateFamily | None:
        """The interpolant of the step exponential at (spin, h) if the rates lie on the config motion's axis, in its
        box (built on first use; FAMILY_LIMIT kept); None on a static base or off the axis (the exact path)."""
        if self._axis is None:
            return None
        w, v = float(Om[self._axis]), float(dOm[self._axis])
        if np.count_nonzero(Om) + np.count_nonzero(dOm) != (w != 0.0) + (v != 0.0) or not (w or v):
            return None
        key = (spin, h)
        fam = self._families.get(key)
        if fam is None:
            e = np.eye(3)[self._axis]
            F = lambda a, b: self._exponential(a, b, spin, h)  # noqa: E731
            fam = RateFamily(F, e, *self._box, tol=FAMILY_TOL, per_column=True)
            if len(self._families) >= FAMILY_LIMIT:
                self._families.pop(next(iter(self._families)))
            self._families[key] = fam
        return fam if fam.covers(w, v) else None

    def warm_up(self) -> None:
        """Build the config motion's step interpolant at the start speed now (~0.1 s) instead of in the first moving
        step, which a realtime plant cannot afford (a 0.13 s stall there dropped the rotor)."""
        if self._axis is not None and self._box[0] > 0.0:
            self.step_matrices(0.5 * self._box[0] * np.eye(3)[self._axis], np.zeros(3), self.spin_speed(0))

    def step_matrices(self, Omega: np.ndarray, dOmega: np.ndarray, spin: float, h: float | None = None):
        """The matrices of a step at ``spin``: exact at a constant speed; during a ramp linear interpolation between
        the cached matrices of the SPIN_GRID speeds around it (error O(SPIN_GRID^2); the speed-dependent terms
        follow the speed at every step without an exponential per step)."""
        if self.spin.rate == 0.0:
            return self.matrices(Omega, dOmega, spin, h)
        j = math.floor(spin / SPIN_GRID)
        a = spin / SPIN_GRID - j
        lo = self.matrices(Omega, dOmega, j * SPIN_GRID, h)
        if a == 0.0:
            return lo
        hi = self.matrices(Omega, dOmega, (j + 1) * SPIN_GRID, h)
        return tuple(u + a * (v - u) for u, v in zip(lo, hi, strict=True))

    def _unbalance_columns(self, spin: float) -> np.ndarray:
        """Plant input of the unbalance per unit (cos phi, sin phi), centrifugal part U Phi^2 (N x 2)."""
        cols = np.zeros((self.N, 2))
        for j, U, ph in self.unb:
            f = U * spin * spin
            # F_y = f cos(phi + ph), F_z = f sin(phi + ph) in terms of (cos phi, sin phi)
            cols[:, 0] += self.BF[:, 2 * j] * f * math.cos(ph) + self.BF[:, 2 * j + 1] * f * math.sin(ph)
            cols[:, 1] += -self.BF[:, 2 * j] * f * math.sin(ph) + self.BF[:, 2 * j + 1] * f * math.cos(ph)
        return cols

    # -- one step -----------------------------------------------------------------------------------------
    def prepare(self, Omega: np.ndarray, dOmega: np.ndarray, x: np.ndarray | None = None) -> None:
        """Everything of the coming step that does not need its command, ahead of it (the plant node, while the
        controller computes): the step's matrices; given the state x, also the held forces, the free response,
        the state-dependent forces at the step's start and the next spin angle and attitude (``_plan``)."""
        if x is None or self.linear_only:
            self.step_matrices(Omega, dOmega, self.spin_speed())
        else:
            self._pre = self._plan(x, Omega, dOmega, self.spin_speed())

    def applied_current(self, x: np.ndarray, i_cmd: np.ndarray) -> np.ndarray:
        """Command after the current clamp and the voltage (slew) limit (i_cmd itself when neither acts)."""
        i = i_cmd
        if np.abs(i_cmd).max() > self.limit:
            i = np.clip(i_cmd, -self.limit, self.limit)
        if self.slew is None:
            return i
        amp = self.lin.layout.amp
        if amp is not None:  # current loop: slope wa (i_c - i_a) limited to V/L
            ia = x[amp]
            span = self.slew / self.lin.dynamics.amplifier_rad_s
            return np.clip(i, ia - span, ia + span) if np.abs(i - ia).max() > span else i
        return i  # ideal amplifier: the rate limit acts on the held current, see step()

    def step(self, x: np.ndarray, i_cmd: np.ndarray, Omega: np.ndarray, dOmega: np.ndarray) -> np.ndarray:
        """x_{k+1} from x_k, the held command (A) and the base rates of sample k; advances k, phi, attitude."""
        spin = self.spin_speed()
        i = self.applied_current(x, i_cmd)
        self.max_command = max(self.max_command, float(np.abs(i_cmd).max()))
        if i is not i_cmd and not np.array_equal(i, i_cmd):  # clamped or slew-limited this step
            self.saturated += 1
        if self.linear_only:
            E, G, g, _, _ = self.step_matrices(Omega, dOmega, spin)
            x_next = E @ x + G @ i + g
            self.phi, self.quat = self._next_angles(Omega, dOmega, spin)
        else:
            x_next = self._step_effects(x, i, Omega, dOmega, spin)
        self.k += 1
        return x_next

    def _plan(self, x, Omega, dOmega, spin) -> _Plan:
        """The command-free part of step k from state x (the same arithmetic whether prepared ahead or not)."""
        held = np.zeros(self.BF.shape[1])
        noise = self.noise_row(self.k)
        held[:-2] += self.noise_f * noise[4:]
        if self.g:
            held[-2:] = gravity_yz(self.quat, self.g)
        accel = self.spin.accel(self.t)
        if accel and self.unb:  # tangential unbalance force during a ramp, held over the step
            for j, U, ph in self.unb:
                a = self.phi + ph
                held[2 * j] -= U * accel * math.sin(a)
                held[2 * j + 1] += U * accel * math.cos(a)
        cs = np.array([math.cos(self.phi), math.sin(self.phi)])
        near = self.forces.near(x, self.Ts)
        m = self.forces.substeps if near else 1
        h = self.Ts / m
        E, G, g, GF, Gu = self.step_matrices(Omega, dOmega, spin, h)
        rot = np.array([[math.cos(spin * h), -math.sin(spin * h)], [math.sin(spin * h), math.cos(spin * h)]])
        free = g + GF @ held
        GFn = GF[:, :-2]
        rates = np.concatenate([Omega, dOmega]).tobytes()
        plan = _Plan(self.k, x, rates, near, m, h, E, G, GFn, GFn[:, self.forces.amb_idx], Gu, rot, free, cs)
        if m == 1:
            plan.base0 = E @ x + free + Gu @ cs
            if self.forces.nonlinear and not near and not self.forces.uses_command:
                plan.f0 = self.forces.amb_correction(x, None)
        plan.angles = self._next_angles(Omega, dOmega, spin)
        return plan

    def _step_effects(self, x, i, Omega, dOmega, spin):
        if self.slew is not None and self.lin.layout.amp is None:
            i = np.clip(i, self._i_prev - self.slew * self.Ts, self._i_prev + self.slew * self.Ts)
        self._i_prev = i
        pre, self._pre = self._pre, None
        if pre is None or not pre.fits(self.k, x, Omega, dOmega):
            pre = self._plan(x, Omega, dOmega, spin)
        Gi = pre.G @ i
        cs, h, near = pre.cs, pre.h, pre.near
        for j in range(pre.m):
            base = pre.base0 + Gi if j == 0 and pre.base0 is not None else pre.E @ x + (pre.free + Gi) + pre.Gu @ cs
            if near:  # touchdown possible: every force node, contacts logged
                t = self.t + j * h
                f0 = self.forces.node_forces(x, i, spin, t, self.contact, near)
                x_pred = base + pre.GFn @ f0
                f1 = self.forces.node_forces(x_pred, i, spin, t + h, None, near)
                x = base + pre.GFn @ (0.5 * (f0 + f1))
            elif self.forces.nonlinear:  # the bearing law's correction at the four AMB axes only
                f0 = pre.f0 if pre.f0 is not None else self.forces.amb_correction(x, i)
                f1 = self.forces.amb_correction(base + pre.GFa @ f0, i)
                x = base + pre.GFa @ (0.5 * (f0 + f1))
            else:
                x = base
            cs = pre.rot @ cs
        self.phi, self.quat = pre.angles
        return x

    def _next_angles(self, Omega, dOmega, spin) -> tuple[float, tuple]:
        """Spin angle and base attitude at step k + 1 (the attitude turned by the midpoint rate, exactly)."""
        accel = self.spin.accel(self.t)
        phi = math.fmod(self.phi + spin * self.Ts + 0.5 * accel * self.Ts * self.Ts, 2 * math.pi)
        if not self.g:
            return phi, self.quat
        w = tuple(float(o) + 0.5 * self.Ts * float(d) for o, d in zip(Omega, dOmega, strict=True))
        return phi, attitude_step(self.quat, w, self.Ts)

    # -- measurement --------------------------------------------------------------------------------------
    def measure(self, x: np.ndarray) -> np.ndarray:
        """What the sensors report at this step (m): filtered displacement + runout + seeded noise."""
        y = self.lin.output(x)
        if self.runout:
            a = self.phi + self.runout_phase
            y = y + self.runout * np.array([math.cos(a), math.sin(a)] * 2)
        if self.noise_y:
            y = y + self.noise_y * self.noise_row(self.k)[:4]
        return y

    def noise_row(self, k: int) -> np.ndarray:
        """Standard normal draws of step k: [sensor (4), force per node axis]; Philox keyed by (seed, k // BLOCK)."""
        b = k // BLOCK
        if b != self._noise_block:
            gen = np.random.Generator(np.random.Philox(key=[self.seed, b]))
            self._noise = gen.standard_normal(self._noise.shape)
            self._noise_block = b
        return self._noise[k % BLOCK]

    def displacement(self, x: np.ndarray) -> np.ndarray:
        """True AMB displacements (m)."""
        return self.lin.displacement(x)

    @property
    def labels(self) -> tuple[str, ...]:
        return self.lin.labels
