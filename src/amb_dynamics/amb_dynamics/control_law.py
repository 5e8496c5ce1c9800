"""The controller as a linear system: the PID, notch and lead-lag filters in series, or the user's state space.

One description serves every analysis: :func:`continuous_controller` (modes, Floquet, charts, S of the continuous
loop) and :func:`discrete_controller` (the digital loop the rig runs: its step maps, S(z)).  Filters are designed
in continuous time and discretised by Tustin prewarped at their characteristic frequency, as a digital AMB
controller implements them; a continuous user controller is discretised by plain Tustin, a discrete one is used as
given (and mapped back by inverse Tustin for the continuous analyses).  A config without filters or state space
gives exactly the PID's matrices of before.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from .amb import DiscretePIDCoefficients, pid_update_matrices
from .config import RotorConfig
from .config_control import FilterConfig
from .errors import InputError
from .state_space import StateSpace, per_axis, series, tustin, tustin_inverse, unit_delay
from .structure import AMBGains


def is_plain_pid(cfg: RotorConfig) -> bool:
    """True when the controller is the PID alone (no filters, no user state space)."""
    return not cfg.controller.filters and cfg.controller.state_space is None


def describe(cfg: RotorConfig) -> str:
    """One line naming the controller (for summaries and reports)."""
    c = cfg.controller
    if c.state_space is not None:
        kind = "continuous" if c.state_space.sample_time is None else "discrete"
        return f"user state space ({kind}, {c.state_space.structure}, {len(c.state_space.A)} states)"
    parts = ["PID"]
    for f in c.filters:
        on = "all axes" if not f.axes else "axes " + ",".join(str(a) for a in f.axes)
        if f.kind == "notch":
            parts.append(f"notch {f.frequency_hz:g} Hz (width {f.bandwidth_hz:g} Hz, depth {f.depth:g}, {on})")
        else:
            parts.append(f"lead-lag zero {f.zero_hz:g} Hz / pole {f.pole_hz:g} Hz ({on})")
    return " + ".join(parts)


def filter_state_space(f: FilterConfig) -> tuple[StateSpace, float]:
    """(continuous SISO filter, its characteristic angular frequency for prewarping).

    notch: (s^2 + 2 d z w0 s + w0^2)/(s^2 + 2 z w0 s + w0^2), z = bandwidth/(2 f0), d = depth (gain at w0);
    lead-lag: (s/wz + 1)/(s/wp + 1), unit gain at DC, prewarped at sqrt(wz wp) (its peak phase).
    """
    if f.kind == "notch":
        w0 = 2 * np.pi * f.frequency_hz
        z = f.bandwidth_hz / (2.0 * f.frequency_hz)
        num, den = [1.0, 2.0 * f.depth * z * w0, w0 * w0], [1.0, 2.0 * z * w0, w0 * w0]
    else:
        wz, wp = 2 * np.pi * f.zero_hz, 2 * np.pi * f.pole_hz
        w0 = float(np.sqrt(wz * wp))
        num, den = [wp / wz, wp], [1.0, wp]
    from scipy.signal import tf2ss  # here: scipy.signal takes ~1.4 s to import, and every node imports this module

    A, B, C, D = tf2ss(num, den)
    return StateSpace(A, B, C, D), w0


def user_state_space(cfg: RotorConfig, n_axes: int = 4) -> StateSpace:
    """controller.state_space as given (continuous, or discrete at its sample_time), expanded to n_axes."""
    ss = cfg.controller.state_space
    A, B, C, D = ss.matrices()
    siso = StateSpace(A, B, C, D, ss.sample_time)
    return per_axis(siso, (), n_axes) if ss.structure == "per_axis" else siso


def continuous_controller(cfg: RotorConfig, gains: AMBGains, n_axes: int = 4) -> StateSpace:
    """The controller the continuous analyses use, u = K(s) y_m (K carries the feedback sign)."""
    if cfg.controller.state_space is not None:
        user = user_state_space(cfg, n_axes)
        return user if user.dt is None else tustin_inverse(user)
    K = pid_state_space(gains, n_axes)
    for f in cfg.controller.filters:
        K = series(K, per_axis(filter_state_space(f)[0], f.axes, n_axes))
    return K


def discrete_filters(cfg: RotorConfig, Ts: float, n_axes: int = 4) -> StateSpace | None:
    """All of controller.filters in series, Tustin-prewarped at Ts; None without filters."""
    K = None
    for f in cfg.controller.filters:
        siso, w0 = filter_state_space(f)
        d = per_axis(tustin(siso, Ts, prewarp_w=w0), f.axes, n_axes)
        K = d if K is None else series(K, d)
    return K


def discrete_user(cfg: RotorConfig, Ts: float, n_axes: int = 4) -> StateSpace:
    """The user's controller at the loop's sample period Ts (Tustin of a continuous one)."""
    user = user_state_space(cfg, n_axes)
    if user.dt is None:
        return tustin(user, Ts)
    if not np.isclose(user.dt, Ts, rtol=1e-9, atol=0.0):
        raise InputError(
            f"controller.state_space is discrete at sample_time {user.dt:g} s; it cannot run at Ts = {Ts:g} s"
        )
    return StateSpace(user.A, user.B, user.C, user.D, Ts)


def discrete_controller(cfg: RotorConfig, gains: AMBGains, Ts: float, delay: int = 0, n_axes: int = 4) -> StateSpace:
    """The digital controller the rig runs at period Ts: x_k+1 = A x_k + B y_k, u_k = C x_k + D y_k, with the
    optional one-sample computation delay last."""
    if is_plain_pid(cfg):
        return discrete_pid_state_space(gains, Ts, delay, n_axes)
    if cfg.controller.state_space is not None:
        K = discrete_user(cfg, Ts, n_axes)
    else:
        K = series(discrete_pid_state_space(gains, Ts, 0, n_axes), discrete_filters(cfg, Ts, n_axes))
    return series(K, unit_delay(n_axes, Ts)) if delay else K


def pid_state_space(gains: AMBGains, n_axes: int = 4) -> StateSpace:
    """Continuous PID per axis, u = K y_m with K(s) = -(kp + kI/s + kd s) (ideal) or -(kp + kI/s + kd wf s/(s+wf)).

    States: the integrals (if kI != 0), then the derivative filter states (if wf is set); the ideal derivative is
    the improper term D1 = -kd I.
    """
    Id = np.eye(n_axes)
    blocks_A, blocks_B, blocks_C = [], [], []
    D = -gains.kp * Id
    D1 = None
    if gains.kI != 0.0:
        blocks_A.append(np.zeros((n_axes, n_axes)))
        blocks_B.append(Id)
        blocks_C.append(-gains.kI * Id)
    if gains.kd != 0.0 and gains.omega_f is not None:
        wf = gains.omega_f  # kd wf s/(s+wf) = kd wf (1 - wf/(s+wf)); x' = -wf x + y
        blocks_A.append(-wf * Id)
        blocks_B.append(Id)
        blocks_C.append(gains.kd * wf * wf * Id)
        D = D - gains.kd * wf * Id
    elif gains.kd != 0.0:
        D1 = -gains.kd * Id
    A = sla.block_diag(*blocks_A) if blocks_A else np.zeros((0, 0))
    B = np.vstack(blocks_B) if blocks_B else np.zeros((0, n_axes))
    C = np.hstack(blocks_C) if blocks_C else np.zeros((n_axes, 0))
    return StateSpace(A, B, C, D, None, D1)


def discrete_pid_state_space(gains: AMBGains, Ts: float, delay_samples: int = 0, n_axes: int = 4) -> StateSpace:
    """The digital PID the controller node runs (:class:`amb_dynamics.amb.DiscretePID`) as a state space in k.

    State x_k = the controller memory m_k-1; u_k = U_y y_k + U_m x_k, or u_k-1 with a one-sample computation delay.
    """
    coeffs = DiscretePIDCoefficients.from_gains(gains, Ts)
    use_int, use_eta, use_delay = gains.kI != 0.0, gains.kd != 0.0, delay_samples > 0
    Py, Pm, Uy, Um, parts = pid_update_matrices(coeffs, n_axes, use_int, use_eta, use_delay)
    if use_delay:
        j = parts.index("u")
        C = np.zeros((n_axes, Pm.shape[0]))
        C[:, n_axes * j : n_axes * (j + 1)] = np.eye(n_axes)
        return StateSpace(Pm, Py, C, np.zeros((n_axes, n_axes)), dt=Ts)
    return StateSpace(Pm, Py, Um, Uy, dt=Ts)
