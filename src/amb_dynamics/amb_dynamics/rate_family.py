"""Chebyshev interpolants of a step exponential along a single-axis base motion.

Along a base motion about one axis e (Omega = w e, dOmega = v e), every step matrix of the loop or of the plant is an
entire function of the rate w and its derivative v; for pitch and yaw (about an axis across the shaft) it depends on
w^2 only.  Both facts are detected numerically.  The matrix is interpolated (Chebyshev points of the first kind,
barycentric weights) in u = w^2, in w, or in (w, v), from ``U_NODES`` exact exponentials; the interpolation error
is measured at fixed probe points against the exact matrix, and the nodes are doubled until it is below ``tol``
relative (to the largest entry, or column by column when the columns carry different units).  One interpolated
matrix costs a weighted sum of the node matrices instead of a matrix exponential.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .chart import _bary_weights, _cheb_nodes

U_NODES = 6
STEP_TOL = 1e-13  # max entry error of an interpolated step matrix, relative (see RateFamily)
MAX_NODES = 64


class RateFamily:
    """Interpolant of F(Omega, dOmega) for Omega = w e, dOmega = v e, |w| <= wmax, |v| <= vmax.

    Parameters
    ----------
    F : the exact matrix at (Omega, dOmega), both (3,) arrays
    axis_vec : e, a unit vector
    wmax, vmax : the box of rates the interpolant covers (rad/s, rad/s^2)
    tol : the relative error bound the node count is raised to meet
    per_column : measure the error of each column relative to that column's largest entry (a matrix whose
        columns map inputs of different units); otherwise relative to the largest entry of F
    """

    def __init__(
        self,
        F: Callable[[np.ndarray, np.ndarray], np.ndarray],
        axis_vec: np.ndarray,
        wmax: float,
        vmax: float,
        tol: float = STEP_TOL,
        per_column: bool = False,
    ):
        self.F, self.e = F, np.asarray(axis_vec, float)
        wmax, vmax = max(wmax, 1e-12), max(vmax, 1e-12)
        f_wv = self._F(wmax, vmax)
        self.uses_v = not np.array_equal(f_wv, self._F(wmax, 0.0))
        self.even = (not self.uses_v) and np.array_equal(self._F(-wmax, 0.0), self._F(wmax, 0.0))
        self.wmax, self.vmax = wmax, vmax
        self.scale = float(np.abs(f_wv).max()) or 1.0
        if per_column:
            col = np.abs(f_wv).max(axis=0)
            self.scale = np.where(col > 0.0, col, self.scale)
        n = U_NODES
        while True:
            self._build(n)
            err = self._probe_error()
            if err <= tol or n >= MAX_NODES:
                self.error = err  # relative, as measured at the probes
                break
            n *= 2

    def _F(self, w: float, v: float) -> np.ndarray:
        return self.F(w * self.e, v * self.e)

    def _build(self, n: int) -> None:
        self.n = n
        if self.even:
            self.nodes = [_cheb_nodes(0.0, self.wmax**2, n)]
            self.Fn = np.array([self._F(np.sqrt(max(u, 0.0)), 0.0) for u in self.nodes[0]])
        elif not self.uses_v:
            self.nodes = [_cheb_nodes(-self.wmax, self.wmax, n)]
            self.Fn = np.array([self._F(w, 0.0) for w in self.nodes[0]])
        else:
            self.nodes = [_cheb_nodes(-self.wmax, self.wmax, n), _cheb_nodes(-self.vmax, self.vmax, n)]
            self.Fn = np.array([self._F(w, v) for w in self.nodes[0] for v in self.nodes[1]])
        self.Fflat = self.Fn.reshape(self.Fn.shape[0], -1)
        j = np.arange(n)
        self._bw = (-1.0) ** j * np.sin(np.pi * (2 * j + 1) / (2 * n))  # barycentric weights, first-kind points

    def covers(self, w: float, v: float) -> bool:
        """True if (w, v) lies in the box the interpolant was built and checked on."""
        return abs(w) <= self.wmax and (not self.uses_v or abs(v) <= self.vmax)

    def weights(self, w: np.ndarray, v: np.ndarray) -> np.ndarray:
        """(len(w), n_nodes) interpolation weights at the rates (w, v)."""
        if self.even:
            return _bary_weights(self.nodes[0], w * w)
        if not self.uses_v:
            return _bary_weights(self.nodes[0], w)
        Ww, Wv = _bary_weights(self.nodes[0], w), _bary_weights(self.nodes[1], v)
        return (Ww[:, :, None] * Wv[:, None, :]).reshape(len(w), -1)

    def maps(self, w: np.ndarray, v: np.ndarray) -> np.ndarray:
        """The interpolated matrices at the rates w, v (arrays), shape (len(w), *F.shape)."""
        return (self.weights(w, v) @ self.Fflat).reshape(len(w), *self.Fn.shape[1:])

    def at(self, w: float, v: float) -> np.ndarray:
        """The interpolated matrix at one rate pair (the per-step path: scalar weights, one product)."""
        if self.even:
            W = _point_weights(self.nodes[0], self._bw, w * w)
        elif not self.uses_v:
            W = _point_weights(self.nodes[0], self._bw, w)
        else:
            W = np.outer(_point_weights(self.nodes[0], self._bw, w), _point_weights(self.nodes[1], self._bw, v)).ravel()
        return (W @ self.Fflat).reshape(self.Fn.shape[1:])

    def _probe_error(self) -> float:
        rng = np.random.default_rng(12345)  # fixed probes: the result does not depend on where it ran
        w = self.wmax * rng.uniform(-1, 1, 3)
        v = self.vmax * rng.uniform(-1, 1, 3) if self.uses_v else np.zeros(3)
        approx = self.maps(w, v)
        return max(float((np.abs(approx[i] - self._F(w[i], v[i])) / self.scale).max()) for i in range(3))


def _point_weights(nodes: np.ndarray, bw: np.ndarray, x: float) -> np.ndarray:
    """Barycentric interpolation weights at one point x (a node itself: that node's unit vector)."""
    d = x - nodes
    hit = d == 0.0
    if hit.any():
        return hit.astype(float)
    W = bw / d
    return W / W.sum()


def single_axis_bounds(harmonics) -> tuple[int, float, float] | None:
    """(axis index in base coordinates, wmax, vmax) of a motion whose harmonics all turn about one axis; else None.

    The base rates of a motion about one axis are Omega = w e and dOmega = v e with |w| <= sum A omega and
    |v| <= sum A omega^2 (roll about x, pitch about z, yaw about y: see ``BaseMotion.angular_velocity``)."""
    axes = {h.axis for h in harmonics}
    if len(axes) != 1:
        return None
    idx = {"roll": 0, "yaw": 1, "pitch": 2}[axes.pop()]
    wmax = sum(abs(h.amplitude) * h.frequency for h in harmonics)
    vmax = sum(abs(h.amplitude) * h.frequency**2 for h in harmonics)
    return idx, wmax, vmax
