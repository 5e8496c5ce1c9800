"""Linear state spaces of plants and controllers: frequency response, series connection, Tustin, loop closing.

``StateSpace`` is continuous (``dt`` None) or discrete; a continuous one may carry an ideal derivative
feed-through ``D1`` (an ideal PD's kd s).  :func:`close_loop` closes a plant and a controller with the disturbance
added to the sensor signal, the structure behind the sensitivity function and the analysed closed loop alike.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from .errors import InputError

CHUNK = 256  # frequencies per batched solve (memory: CHUNK * n^2 complex)


@dataclass(frozen=True)
class StateSpace:
    """x' = A x + B u (``dt`` None) or x_k+1 = A x_k + B u_k (sample period ``dt`` s); y = C x + D u + D1 u'.

    ``D1`` (continuous only) is an ideal derivative feed-through (an improper term, e.g. an ideal PD's kd).
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    dt: float | None = None
    D1: np.ndarray | None = None

    @property
    def n_states(self) -> int:
        return self.A.shape[0]

    def variable(self, w: np.ndarray) -> np.ndarray:
        """s = jw (continuous) or z = exp(jw dt) (discrete) for angular frequencies w (rad/s)."""
        w = np.asarray(w, dtype=float)
        return 1j * w if self.dt is None else np.exp(1j * w * self.dt)

    def freqresp(self, w: np.ndarray) -> np.ndarray:
        """Frequency response at angular frequencies w (rad/s), shape (len(w), n_outputs, n_inputs)."""
        w = np.atleast_1d(np.asarray(w, dtype=float))
        s = self.variable(w)
        ny, nu = self.D.shape
        H = np.empty((w.size, ny, nu), dtype=complex)
        H[:] = self.D
        n = self.n_states
        if n:
            eye = np.eye(n)
            for a in range(0, w.size, CHUNK):
                sl = slice(a, a + CHUNK)
                lhs = s[sl, None, None] * eye - self.A
                X = np.linalg.solve(lhs, np.broadcast_to(self.B, (lhs.shape[0], n, nu)))
                H[sl] += self.C @ X
        if self.D1 is not None:
            H += s[:, None, None] * self.D1
        return H


def _check_pair(plant: StateSpace, controller: StateSpace) -> None:
    if (plant.dt is None) != (controller.dt is None) or (plant.dt is not None and plant.dt != controller.dt):
        raise InputError("plant and controller must both be continuous or share one sample period")
    if np.abs(plant.D).max(initial=0.0) != 0.0 or plant.D1 is not None:
        raise InputError("the plant must be strictly proper (no current-to-displacement feed-through)")


def close_loop(plant: StateSpace, controller: StateSpace) -> StateSpace:
    """The closed loop from the injected E (added to the sensor signals) to the disturbed signals y_m = y + E.

    X = [x_plant; x_controller]; an ideal derivative D1 is absorbed by the change of state X - B1 E (B1 = [Bp D1; 0]),
    valid because a mechanical plant has Cp Bp = 0 (displacement does not jump with current).
    """
    _check_pair(plant, controller)
    Ap, Bp, Cp = plant.A, plant.B, plant.C
    Ac, Bc, Cc, Dc = controller.A, controller.B, controller.C, controller.D
    feed = Dc @ Cp
    n, nc, m = Ap.shape[0], controller.n_states, Cp.shape[0]
    B1 = np.zeros((n + nc, m))
    if controller.D1 is not None:
        if np.abs(Cp @ Bp).max() > 1e-12 * max(1.0, np.abs(Bp).max()):
            raise InputError("an ideal derivative needs a plant whose displacement does not jump with current")
        feed = feed + controller.D1 @ Cp @ Ap
        B1[:n] = Bp @ controller.D1
    A = np.zeros((n + nc, n + nc))
    A[:n, :n] = Ap + Bp @ feed
    A[:n, n:] = Bp @ Cc
    A[n:, :n] = Bc @ Cp
    A[n:, n:] = Ac
    B0 = np.vstack([Bp @ Dc, Bc])
    C = np.hstack([Cp, np.zeros((m, nc))])
    return StateSpace(A, B0 + A @ B1, C, np.eye(m), plant.dt)


def series(first: StateSpace, second: StateSpace) -> StateSpace:
    """``second`` after ``first`` (u -> first -> second -> y).  ``second`` must be proper (no D1).

    An ideal derivative D1 of ``first`` passes through: the state of ``second`` is shifted by B2 D1 u, so the
    result has D1 = D2 D1 (exact for any input, the derivative of u being what D1 already needs).
    """
    if second.D1 is not None:
        raise InputError("only the first of two systems in series may have an ideal derivative")
    if (first.dt is None) != (second.dt is None) or (first.dt is not None and first.dt != second.dt):
        raise InputError("systems in series must both be continuous or share one sample period")
    A1, B1, C1, D1 = first.A, first.B, first.C, first.D
    A2, B2, C2, D2 = second.A, second.B, second.C, second.D
    n1, n2 = A1.shape[0], A2.shape[0]
    A = np.zeros((n1 + n2, n1 + n2))
    A[:n1, :n1] = A1
    A[n1:, :n1] = B2 @ C1
    A[n1:, n1:] = A2
    B = np.vstack([B1, B2 @ D1])
    C = np.hstack([D2 @ C1, C2])
    D = D2 @ D1
    Dd = None
    if first.D1 is not None:  # x2~ = x2 - B2 D1' u:  x2~' = A2 x2~ + B2 (C1 x1 + D1 u) + A2 B2 D1' u
        B[n1:] += A2 @ B2 @ first.D1
        D = D + C2 @ B2 @ first.D1
        Dd = D2 @ first.D1
    return StateSpace(A, B, C, D, first.dt, Dd)


def tustin(ss: StateSpace, Ts: float, prewarp_w: float | None = None) -> StateSpace:
    """Bilinear (Tustin) discretisation at period Ts, frequency-prewarped at ``prewarp_w`` (rad/s) if given.

    Prewarping maps s = (w0 / tan(w0 Ts / 2)) (z - 1)/(z + 1), so the discrete filter has exactly the
    continuous one's response at w0 (a notch stays centred where it was designed).
    """
    if ss.dt is not None or ss.D1 is not None:
        raise InputError("Tustin needs a proper continuous state space")
    dt = Ts if prewarp_w is None else 2.0 * np.tan(prewarp_w * Ts / 2.0) / prewarp_w
    if ss.n_states == 0:
        return StateSpace(ss.A, ss.B, ss.C, ss.D, Ts)
    from scipy.signal import cont2discrete  # here: scipy.signal takes ~1.4 s to import (see control_law)

    A, B, C, D, _ = cont2discrete((ss.A, ss.B, ss.C, ss.D), dt, method="bilinear")
    return StateSpace(A, B, C, D, Ts)


def tustin_inverse(ss: StateSpace) -> StateSpace:
    """The continuous system whose Tustin discretisation at ss.dt is ``ss`` (MATLAB's d2c 'tustin').

    Inverts scipy's bilinear map: A = (2/T)(Ad - I)(Ad + I)^-1, B = (I - A T/2) Bd / T, C = Cd (I - A T/2),
    D = Dd - C (I - A T/2)^-1 B T/2.  Needs no pole at z = -1.
    """
    T, n = ss.dt, ss.n_states
    if T is None:
        raise InputError("tustin_inverse needs a discrete state space")
    eye = np.eye(n)
    if n and abs(np.linalg.det(ss.A + eye)) < 1e-12:
        raise InputError("a discrete controller with a pole at z = -1 has no continuous (Tustin) equivalent")
    A = (2.0 / T) * sla.solve((ss.A + eye).T, (ss.A - eye).T).T
    ima = eye - A * T / 2.0
    B = ima @ ss.B / T
    C = ss.C @ ima
    D = ss.D - C @ sla.solve(ima, B) * T / 2.0
    return StateSpace(A, B, C, D, None)


def unit_delay(m: int, dt: float) -> StateSpace:
    """One-sample delay of m signals: u_k = y_k-1."""
    return StateSpace(np.zeros((m, m)), np.eye(m), np.eye(m), np.zeros((m, m)), dt)


def per_axis(siso: StateSpace, axes: tuple[int, ...], n_axes: int) -> StateSpace:
    """A SISO system on the listed axes (all if empty) and a unit pass-through on the others."""
    on = range(n_axes) if not axes else sorted(axes)
    k = siso.n_states
    A = sla.block_diag(*([siso.A] * len(on))) if k else np.zeros((0, 0))
    B = np.zeros((k * len(on), n_axes))
    C = np.zeros((n_axes, k * len(on)))
    D = np.eye(n_axes)
    for j, ax in enumerate(on):
        B[j * k : (j + 1) * k, ax] = siso.B[:, 0]
        C[ax, j * k : (j + 1) * k] = siso.C[0]
        D[ax, ax] = siso.D[0, 0]
    D1 = None
    if siso.D1 is not None:
        D1 = np.zeros((n_axes, n_axes))
        D1[list(on), list(on)] = siso.D1[0, 0]
    return StateSpace(A, B, C, D, siso.dt, D1)
