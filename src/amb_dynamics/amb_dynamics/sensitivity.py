"""Model sensitivity functions of the AMB loops (ISO 14839-3): S(jw) = (I + P C)^-1, one diagonal entry per axis.

A disturbance E is added to the sensor signal of AMB axis j; the controller sees y_m = y + E and every loop stays
closed.  With the plant P (coil current -> sensor displacement, all axes) and the controller written as u = K y_m
(K = -C carries the feedback sign), the disturbed sensor signal is y_m = (I - P K)^-1 E, so

    S(jw) = (I - P(jw) K(jw))^-1 = (I + P C)^-1,     S_jj = y_m,j / E_j  with every other loop closed.

Everything here takes a plant and a controller as state spaces (:class:`StateSpace`), so other plant dynamics
(amplifier, sensor, filters) or other controllers plug in by building a bigger state space.

**S of the sampled loop.**  The rig's controller samples y(t_k), adds nothing in between, and holds its current
over [t_k, t_k+1) (zero-order hold), optionally one sample late.  Sampled at t_k this loop is an exact
discrete-time LTI system: the plant becomes x_k+1 = E x_k + Gamma u_k, y_k = C x_k (ZOH discretisation, exact),
the discrete PID is a state space in k, and an injected sequence E_k added to the sampled sensor value reaches the
disturbed value y_m,k through S(z) = (I - P(z) K(z))^-1.  "S of the sampled loop" is S(z) on the unit circle,
z = exp(jw Ts), for 0 < w < pi/Ts: the ratio of the disturbed to the injected sample sequence that an injection
inside the controller measures (what ISO 14839-3 asks for on a digital controller).  It says nothing about the
intersample motion, and it is periodic in w with period 2 pi/Ts (frequencies above Nyquist alias).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import minimize_scalar

from .config import RotorConfig
from .control_law import continuous_controller, discrete_controller, discrete_pid_state_space, pid_state_space  # noqa: F401  (re-exported)
from .errors import InputError
from .sampled import PlantStepper
from .state_space import StateSpace
from .state_space import close_loop as sensitivity_state_space
from .structure import StructuralModel
from .system import coefficients_from_rates

LOCAL_POINTS = 41  # dense local grid around each peak candidate
LOCAL_HALF_WIDTHS = 8.0  # local grid spans +- this many half-power half-widths of a lightly damped pole
REFINE = 3  # candidates (largest first) refined by Brent per axis


def _speed_cfg(cfg: RotorConfig, speed_rpm: float | None) -> RotorConfig:
    return cfg if speed_rpm is None else replace(cfg, spin_speed_rpm=float(speed_rpm))


def plant_state_space(model: StructuralModel, cfg: RotorConfig, speed_rpm: float | None = None) -> StateSpace:
    """Open-loop plant, coil currents (A) -> AMB displacements (m), base at rest, spinning at ``speed_rpm``.

    The same generator as the plant node's ZOH step (:class:`amb_dynamics.sampled.PlantStepper`): negative
    stiffness ks included, no controller.  States [q; q'] and, when the config has them, the amplifier and
    sensor-filter states; the output is what the controller reads (the sensor filter's output).  A nonlinear
    bearing law is linearised at the levitated operating point (:mod:`amb_dynamics.operating_point`).
    """
    stepper = _stepper(model, _speed_cfg(cfg, speed_rpm), 1.0)
    zero = np.zeros(3)
    A = _generator(stepper, zero)
    C = _measured_output(stepper, model, A.shape[0])
    return StateSpace(A, stepper.Bp.copy(), C, np.zeros((C.shape[0], stepper.Bp.shape[1])))


def _stepper(model: StructuralModel, cfg: RotorConfig, Ts: float) -> PlantStepper:
    """The plant node's generator, its bearing law linearised at the levitated operating point (gravity, bias
    offsets: :mod:`amb_dynamics.operating_point`) where that differs from the centre (a nonlinear law)."""
    stepper = PlantStepper(model, cfg, Ts, forcing=False)
    from .rig_loop import levitated_bearing

    bearing = levitated_bearing(model, cfg, 1.0 / cfg.controller.rate_hz)
    if bearing is not None:
        stepper.set_bearing_gains(*bearing)
    return stepper


def _measured_output(stepper: PlantStepper, model: StructuralModel, n_states: int) -> np.ndarray:
    """What the controller reads: the sensor filter's output when the plant has one (Cm), else Ba^T q."""
    if stepper.Cm is not None:
        return np.array(stepper.Cm, dtype=float)
    C = np.zeros((model.Ba.shape[1], n_states))
    C[:, : model.n] = model.Ba.T
    return C


def _generator(stepper: PlantStepper, Omega: np.ndarray) -> np.ndarray:
    c = coefficients_from_rates(Omega, np.zeros(3), stepper.spin)
    return stepper.Ap0 + np.tensordot(c[stepper.Ap_idx], stepper.Ap_stack, axes=1)


def sampled_plant_state_space(
    model: StructuralModel, cfg: RotorConfig, Ts: float, speed_rpm: float | None = None
) -> StateSpace:
    """ZOH discretisation of :func:`plant_state_space` at sample period Ts (s): exactly the plant node's step."""
    stepper = _stepper(model, _speed_cfg(cfg, speed_rpm), Ts)
    E, Gam, _ = stepper.matrices(np.zeros(3), np.zeros(3))
    C = _measured_output(stepper, model, E.shape[0])
    return StateSpace(E.copy(), Gam.copy(), C, np.zeros((C.shape[0], Gam.shape[1])), dt=Ts)


@dataclass(frozen=True)
class ModalResponse:
    """H(v) = D + sum_i left[:, i] right[i, :] / (v - poles[i]) of a diagonalisable state space (v = s or z).

    One eigen-decomposition, then O(states) work per frequency: thousands of frequencies in milliseconds.
    """

    poles: np.ndarray
    left: np.ndarray
    right: np.ndarray
    D: np.ndarray
    ss: StateSpace

    @classmethod
    def of(cls, ss: StateSpace) -> ModalResponse:
        lam, V = np.linalg.eig(ss.A)
        if np.linalg.cond(V) > 1e10:  # (nearly) defective: keep the direct solves
            return cls(lam, np.zeros((ss.C.shape[0], 0)), np.zeros((0, ss.B.shape[1])), ss.D, ss)
        return cls(lam, ss.C @ V, np.linalg.solve(V, ss.B), ss.D, ss)

    def __call__(self, w: np.ndarray) -> np.ndarray:
        """Response at angular frequencies w (rad/s), shape (len(w), n_outputs, n_inputs)."""
        w = np.atleast_1d(np.asarray(w, dtype=float))
        if self.left.shape[1] == 0 and self.ss.n_states:
            return self.ss.freqresp(w)
        v = self.ss.variable(w)
        g = 1.0 / (v[:, None] - self.poles[None, :])
        return self.D + np.einsum("ki,ai,ib->kab", g, self.left, self.right)


def sensitivity_matrix(plant: StateSpace, controller: StateSpace, w: np.ndarray) -> np.ndarray:
    """S = (I - P K)^-1 at angular frequencies w (rad/s), shape (len(w), m, m), from the closed loop's modes."""
    return ModalResponse.of(sensitivity_state_space(plant, controller))(w)


def closed_loop_poles(plant: StateSpace, controller: StateSpace) -> np.ndarray:
    """Eigenvalues of the closed loop (continuous: 1/s; discrete: z), the poles of S."""
    return np.linalg.eigvals(sensitivity_state_space(plant, controller).A)


def pole_candidates(poles: np.ndarray, dt: float | None) -> tuple[np.ndarray, np.ndarray]:
    """(frequency rad/s, half-power half-width rad/s) of each oscillatory pole with positive frequency."""
    if dt is None:
        sel = poles.imag > 0
        return poles.imag[sel], np.abs(poles.real[sel])
    sel = (poles.imag > 0) & (np.abs(poles) > 0)
    z = poles[sel]
    return np.angle(z) / dt, np.abs(np.log(np.abs(z))) / dt


@dataclass(frozen=True)
class Peak:
    """Largest |S_jj| in a band: value and angular frequency (rad/s)."""

    abs: float
    w: float

    @property
    def db(self) -> float:
        return float(20.0 * np.log10(self.abs))

    @property
    def hz(self) -> float:
        return float(self.w / (2 * np.pi))


def find_peaks(
    plant: StateSpace, controller: StateSpace, w_grid: np.ndarray, S_grid: np.ndarray, band: tuple[float, float]
) -> list[Peak]:
    """Peak of |S_jj| per axis over the band (rad/s), independent of the grid's luck.

    Candidates: the grid maximum and local maxima, and every closed-loop pole in the band (a lightly damped
    mode's peak is narrower than any grid: half-width |Re lambda|).  Each candidate is searched on a dense local
    grid, then refined by bounded Brent (golden-section + parabolic) between its neighbours.
    """
    lo, hi = band
    m = S_grid.shape[1]
    resp = ModalResponse.of(sensitivity_state_space(plant, controller))
    mag = np.abs(S_grid[:, np.arange(m), np.arange(m)])  # (k, m)
    wp, hw = pole_candidates(resp.poles, plant.dt)
    keep = (wp >= lo) & (wp <= hi)
    windows = [
        np.linspace(max(lo, w0 - LOCAL_HALF_WIDTHS * h), min(hi, w0 + LOCAL_HALF_WIDTHS * h), LOCAL_POINTS)
        for w0, h in zip(wp[keep], np.maximum(hw[keep], 1e-9 * wp[keep]), strict=True)
    ]
    w_local = np.concatenate(windows) if windows else np.zeros(0)
    mag_local = np.abs(np.diagonal(resp(w_local), axis1=1, axis2=2)) if w_local.size else np.zeros((0, m))
    peaks = []
    for j in range(m):
        starts = _grid_brackets(w_grid, mag[:, j])
        for k in range(len(windows)):
            seg = slice(k * LOCAL_POINTS, (k + 1) * LOCAL_POINTS)
            starts += _grid_brackets(w_local[seg], mag_local[seg, j])[:1]
        best = Peak(float(mag[:, j].max()), float(w_grid[mag[:, j].argmax()]))
        for a, b, w0, v0 in sorted(starts, key=lambda c: -c[3])[:REFINE]:
            if v0 > best.abs:
                best = Peak(v0, w0)
            if b > a:
                res = minimize_scalar(
                    lambda x, j=j: -abs(resp(np.array([x]))[0, j, j]),
                    bounds=(a, b),
                    method="bounded",
                    options={"xatol": 1e-10 * max(b, 1.0)},
                )
                if -res.fun > best.abs:
                    best = Peak(float(-res.fun), float(res.x))
        peaks.append(best)
    return peaks


def _grid_brackets(w: np.ndarray, v: np.ndarray, top: int = 4) -> list[tuple[float, float, float, float]]:
    """(left, right, w, value) around the ``top`` largest local maxima of v on grid w."""
    if w.size == 0:
        return []
    inner = np.flatnonzero((v[1:-1] >= v[:-2]) & (v[1:-1] >= v[2:])) + 1
    idx = np.unique(np.concatenate([inner, [int(v.argmax())]]))
    idx = idx[np.argsort(v[idx])[::-1][:top]]
    out = []
    for i in idx:
        a, b = w[max(i - 1, 0)], w[min(i + 1, w.size - 1)]
        out.append((float(a), float(b), float(w[i]), float(v[i])))
    return out


def loop_state_spaces(
    model: StructuralModel, cfg: RotorConfig, speed_rpm: float, controller: str = "continuous"
) -> tuple[StateSpace, StateSpace]:
    """(plant, controller) of the config: ``continuous`` (its controller in continuous time) or ``sampled`` (the
    rig's digital loop at controller.rate_hz with controller.delay_samples); :mod:`amb_dynamics.control_law`."""
    n_axes = model.Ba.shape[1]
    if controller == "continuous":
        return plant_state_space(model, cfg, speed_rpm), continuous_controller(cfg, model.gains, n_axes)
    if controller == "sampled":
        Ts = 1.0 / cfg.controller.rate_hz
        return (
            sampled_plant_state_space(model, cfg, Ts, speed_rpm),
            discrete_controller(cfg, model.gains, Ts, cfg.controller.delay_samples, n_axes),
        )
    raise InputError(f"controller must be continuous or sampled (got {controller!r})")
