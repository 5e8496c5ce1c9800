"""Online (windowed) Floquet estimation from a stream of samples: what the monitor node runs.

Samples s_k (full plant state [q; q'], or the 4 AMB displacements in sensor-only mode) arrive one by one.
``StreamingEstimator`` samples them at P fixed phases of every period T of A(t) (exactly at the samples when
T/Ts and the phase offsets are whole numbers of samples, by linear interpolation otherwise), stacks the P
phase vectors of one period into a column (an intra-period delay embedding: with P phases the 4 AMB channels
observe every lightly damped mode, which is what makes the sensor-only mode work), and every
P / ``updates_per_period`` phases refits the one-period map over the last ``window`` periods with
:func:`amb_dynamics.estimator.fit.fit_period_map` (LS DMD on the signal subspace; with ``method='opt'`` the chosen
fit is then refined once by variable projection).  A column may start at any phase, so updates come several
times per period.  Rows are scaled by their channel's RMS; the measurement noise per channel is given or estimated
from fourth differences of consecutive samples (robust MAD; a smooth signal at 5 kHz has almost none).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from .fit import InstabilityFlag, MapFit, VerdictPolicy, fit_period_map
from .mapfit import forcing_regressors, synchronous_regressors
from .refine import refine_fit

SLOT_TOL = 1e-3  # a sample within this fraction of Ts of a phase time is taken as it is
NOISE_BUFFER = 2048  # fourth differences kept per channel for the noise estimate
D4_VARIANCE = 70.0  # Var(n_k - 4n_{k-1} + 6n_{k-2} - 4n_{k-3} + n_{k-4}) / Var(n) for white noise
MAD_TO_STD = 1.4826
DRIFT_PAIRS = 4  # per harmonic: the drift terms u_j and u_j^2 times cos and sin (mapfit.synchronous_regressors)


@dataclass(frozen=True)
class EstimatorConfig:
    """Settings of the online estimator.

    period : float
        T (s), the period of A(t) that the multipliers refer to (pitch/yaw: pi/omega).
    sample_time : float
        Ts (s), spacing of the incoming samples.
    forcing : str or int
        Model of the base-motion forcing over periods: 'alternating' (pitch, yaw: f(t+T) = -f(t)),
        'constant', 'none' (roll: f = 0) or a repeat count (see :func:`.mapfit.forcing_regressors`).
    phases : int
        P, phases sampled per period (rows of a column = P x channels).
    window : int
        Snapshot pairs (periods) in the moving window.
    updates_per_period : int
        Refits per period (each starting the columns at another phase).
    method : str
        'opt' (LS DMD refined by variable projection, :mod:`amb_dynamics.estimator.refine`), 'ls' or 'tls'.
    max_rank : int
        Largest number of modes modelled.
    noise_std : float, sequence or None
        Measurement-noise std per channel (signal units); None = estimate from the data.
    scale_groups : sequence of int or None
        Group id per channel; channels of a group share one row scale (their RMS over the window), so that
        e.g. all modal coordinates keep their physical proportions.  None: every channel its own scale.
    adaptive_start : bool
        When the window's fit is unresolved, try windows that start later (fast modes seen only in the oldest
        periods then drop out) and take the first resolved one.
    sync_harmonics : int
        Spin harmonics whose synchronous response (unbalance, runout) is removed like the base forcing
        (:func:`.mapfit.synchronous_regressors`): each sample then comes with its spin angle (``push(t, s,
        angle)``); 0 = none.  Each harmonic costs two snapshot pairs, six while the speed changes (the window
        then grows by those four).
    sync_drift_tol : float
        Relative change of the spin speed over the window above which the synchronous sequences get their
        drift terms (first and second order; a run-up or run-down).
    """

    period: float
    sample_time: float
    forcing: str | int = "constant"
    phases: int = 32
    window: int = 16
    updates_per_period: int = 8
    method: str = "opt"
    max_rank: int = 12
    noise_std: float | tuple[float, ...] | None = None
    scale_groups: tuple[int, ...] | None = None
    adaptive_start: bool = True
    policy: VerdictPolicy = field(default_factory=VerdictPolicy)
    sync_harmonics: int = 0
    sync_drift_tol: float = 1e-3

    def __post_init__(self):
        if not (np.isfinite(self.period) and np.isfinite(self.sample_time)) or self.sample_time <= 0:
            raise InputError("estimator: period and sample_time must be finite and positive")
        if self.period < 2 * self.sample_time:
            raise InputError(f"estimator: period {self.period:g} s is shorter than two samples")
        if self.sync_harmonics < 0 or not (self.sync_drift_tol >= 0):
            raise InputError("estimator: sync_harmonics and sync_drift_tol must be >= 0")
        if self.phases < 1 or self.window < 3 or self.updates_per_period < 1:
            raise InputError("estimator: phases and updates_per_period must be >= 1 and window >= 3")
        forcing_regressors(self.forcing, 1)  # validates the forcing model
        if self.phases > self.period / self.sample_time + 1e-9:
            raise InputError(f"estimator: {self.phases} phases need more samples per period than there are")

    @property
    def samples_per_period(self) -> float:
        return self.period / self.sample_time


@dataclass(frozen=True)
class Estimate:
    """One refit: time of the newest sample (s), periods of data, the fit, verdict and latched flag."""

    time: float
    periods: int
    fit: MapFit
    verdict: str
    unstable: bool
    confidence: float

    @property
    def rho(self) -> float:
        return self.fit.rho

    def to_dict(self, top: int | None = 6) -> dict:
        return {
            "time_s": self.time,
            "periods": self.periods,
            "verdict": self.verdict,
            "unstable": self.unstable,
            "confidence": self.confidence,
            **self.fit.to_dict(top),
        }


class StreamingEstimator:
    """Windowed one-period-map identification over a sample stream of ``channels`` values per sample."""

    def __init__(self, config: EstimatorConfig, channels: int):
        if channels < 1:
            raise InputError("estimator needs at least one channel")
        if config.scale_groups is not None and len(config.scale_groups) != channels:
            raise InputError(f"estimator: scale_groups has {len(config.scale_groups)} entries for {channels} channels")
        self.cfg, self.channels = config, channels
        N = config.samples_per_period
        # whole-sample phase offsets when T/Ts is a whole number: the snapshots are samples, not interpolants
        self._integer = abs(N - round(N)) <= 1e-6 * N
        P = config.phases
        self._offsets = (
            np.round(np.arange(P) * round(N) / P) * config.sample_time
            if self._integer
            else np.arange(P) * config.period / P
        )
        self._stride = max(1, P // config.updates_per_period)
        # while the spin speed changes, the window grows by the pairs its drift terms cost (4 per harmonic)
        self._drift_extra = DRIFT_PAIRS * config.sync_harmonics
        cap = (config.window + self._drift_extra + 2) * P
        self._slots = np.zeros((cap, channels))
        self._angles = np.zeros(cap)  # spin angle (rad) at each slot (synchronous regressors)
        self._noise = (
            None if config.noise_std is None else np.broadcast_to(np.asarray(config.noise_std, float), (channels,))
        )
        if self._noise is not None and (not np.isfinite(self._noise).all() or (self._noise < 0).any()):
            raise InputError("estimator: noise_std must be finite and >= 0")
        self.flag = InstabilityFlag(config.policy)
        self.reset()

    def reset(self) -> None:
        """Forget all samples (e.g. after a change of period); the latched flag is kept."""
        self._t0: float | None = None
        self._g = 0  # next slot index
        self._hist: deque = deque(maxlen=5)
        self._d4 = np.zeros((NOISE_BUFFER, self.channels))
        self._n_d4 = 0
        self._d2_sq = np.zeros(self.channels)
        self._n_d2 = 0
        self.latest: Estimate | None = None

    # ---- sampling ---------------------------------------------------------------------------------------
    def _slot_time(self, g: int) -> float:
        P = self.cfg.phases
        return self._t0 + (g // P) * self.cfg.period + self._offsets[g % P]

    def push(self, t: float, s: np.ndarray, angle: float | None = None) -> Estimate | None:
        """Add sample s (channels,) taken at time t (s), with the spin angle (rad) at t when the synchronous
        response is modelled (``sync_harmonics``); returns an Estimate when a refit happened."""
        s = np.asarray(s, dtype=float)
        if s.shape != (self.channels,):
            raise InputError(f"estimator: sample has shape {s.shape}, expected ({self.channels},)")
        if not np.isfinite(s).all() or not np.isfinite(t):
            raise InputError("estimator: sample or time is not finite")
        if self.cfg.sync_harmonics and (angle is None or not np.isfinite(angle)):
            raise InputError("estimator: the synchronous model needs the spin angle of every sample")
        angle = 0.0 if angle is None else float(angle)
        Ts = self.cfg.sample_time
        if self._t0 is None:
            self._t0 = float(t)
        elif t <= self._hist[-1][0]:
            raise InputError(f"estimator: time {t:.9f} s does not increase")
        self._noise_sample(t, s)
        out = None
        while True:
            ts = self._slot_time(self._g)
            if ts > t + SLOT_TOL * Ts:
                break
            if abs(ts - t) <= SLOT_TOL * Ts or not self._hist:
                value, phi = s, angle
            else:
                t1, s1, a1 = self._hist[-1]
                w = (ts - t1) / (t - t1)
                value, phi = s1 + (s - s1) * w, a1 + (angle - a1) * w
            self._slots[self._g % self._slots.shape[0]] = value
            self._angles[self._g % self._slots.shape[0]] = phi
            self._g += 1
            if self._g % self._stride == 0:
                out = self._refit(float(t)) or out
        self._hist.append((float(t), s.copy(), angle))
        return out

    def _noise_sample(self, t: float, s: np.ndarray) -> None:
        h = self._hist
        if not self._integer and len(h) >= 2:  # second differences: size of the interpolation error
            self._d2_sq += np.square(s - 2.0 * h[-1][1] + h[-2][1])
            self._n_d2 += 1
        if self._noise is not None or len(h) < 4:
            return
        t4, t3, t2, t1 = h[-4][0], h[-3][0], h[-2][0], h[-1][0]
        dts = (t3 - t4, t2 - t3, t1 - t2, t - t1)
        if max(dts) - min(dts) > SLOT_TOL * self.cfg.sample_time:
            return  # not equally spaced (a gap): no fourth difference
        self._d4[self._n_d4 % NOISE_BUFFER] = s - 4.0 * h[-1][1] + 6.0 * h[-2][1] - 4.0 * h[-3][1] + h[-4][1]
        self._n_d4 += 1

    def noise_estimate(self) -> np.ndarray | None:
        """Noise std per channel in the snapshots: measurement noise (configured, or from the fourth
        differences; None if too few) plus, between samples, the linear-interpolation error |s''| Ts^2 / 8."""
        noise = self._noise
        if noise is None:
            k = min(self._n_d4, NOISE_BUFFER)
            if k < 16:
                return None
            noise = MAD_TO_STD * np.median(np.abs(self._d4[:k]), axis=0) / np.sqrt(D4_VARIANCE)
        if not self._integer and self._n_d2:
            noise = np.sqrt(np.square(noise) + self._d2_sq / self._n_d2 / 64.0)
        return noise

    # ---- fitting -----------------------------------------------------------------------------------------
    def _drifting(self, cols: int) -> bool:
        """Does the spin speed per period change by more than ``sync_drift_tol`` over the last ``cols`` columns?"""
        cfg = self.cfg
        if not cfg.sync_harmonics or cols < 3:
            return False
        P, cap = cfg.phases, self._slots.shape[0]
        speed = np.diff(self._angles[(self._g - cols * P + np.arange(cols) * P) % cap])
        return bool(np.ptp(speed) > cfg.sync_drift_tol * max(np.abs(speed).max(), 1e-300))

    def window_forcing(self, cols: int) -> str | int | np.ndarray:
        """The forcing model of a window of ``cols`` columns: the base forcing, and with ``sync_harmonics`` its
        sequences stacked with the synchronous ones from the spin angles at the columns' first slots."""
        cfg = self.cfg
        if not cfg.sync_harmonics:
            return cfg.forcing
        P, cap = cfg.phases, self._slots.shape[0]
        phi = self._angles[(self._g - cols * P + np.arange(cols) * P) % cap]
        sync = synchronous_regressors(phi, cfg.sync_harmonics, self._drifting(cols))
        return np.vstack([forcing_regressors(cfg.forcing, cols), sync])

    def window_matrix(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(Z, row_scale): the columns of the current window in time order, rows scaled; None if < 2 columns.
        While the spin speed changes the window is longer by the pairs the drift terms cost."""
        P, cap = self.cfg.phases, self._slots.shape[0]
        cols = min(self.cfg.window + 1, self._g // P)
        if self._drift_extra and self._drifting(cols):
            cols = min(self.cfg.window + 1 + self._drift_extra, self._g // P)
        if cols < 2:
            return None
        idx = np.arange(self._g - cols * P, self._g) % cap
        data = self._slots[idx]  # (cols*P, channels), time order
        ms = np.mean(np.square(data), axis=0)
        groups = self.cfg.scale_groups
        if groups is not None:
            g = np.asarray(groups)
            ms = np.array([ms[g == gi].mean() for gi in g])
        scale = np.sqrt(ms)
        scale = np.where(scale > 0, scale, 1.0)
        Z = (data / scale).reshape(cols, P * self.channels).T
        return Z, scale

    def _refit(self, t: float) -> Estimate | None:
        wm = self.window_matrix()
        if wm is None:
            return None
        Z, scale = wm
        noise = self.noise_estimate()
        row_noise = None if noise is None else np.tile(noise / scale, self.cfg.phases)
        if noise is not None and not noise.any():
            row_noise = None  # noise-free whole-sample snapshots: round-off floor only
        cfg = self.cfg
        forcing = self.window_forcing(Z.shape[1])
        base = "ls" if cfg.method == "opt" else cfg.method  # the refinement runs once, on the chosen window
        fit = fit_period_map(Z, forcing, row_noise, base, cfg.max_rank)
        # Modes that decay fast are seen only in the oldest columns; if they leave the model unresolved, a window
        # that starts later (without them) may resolve what remains: the slow modes that decide stability.
        drop, used = 1, 0
        while cfg.adaptive_start and fit.excited and not fit.resolved and Z.shape[1] - drop >= 4:
            later = fit_period_map(Z[:, drop:], _later(forcing, drop), row_noise, base, cfg.max_rank)
            if later.resolved:
                fit, used = later, drop
                break
            drop += 1
        if cfg.method == "opt":
            fit = refine_fit(Z[:, used:], fit, _later(forcing, used))
        verdict = self.flag.update(fit)
        est = Estimate(t, Z.shape[1] - 1, fit, verdict, self.flag.unstable, self.flag.confidence(fit))
        self.latest = est
        return est


def _later(forcing: str | int | np.ndarray, drop: int) -> str | int | np.ndarray:
    """The forcing model of a window whose first ``drop`` columns are left out."""
    return forcing[:, drop:] if isinstance(forcing, np.ndarray) else forcing


def estimate_series(
    t: np.ndarray, S: np.ndarray, config: EstimatorConfig, angles: np.ndarray | None = None
) -> list[Estimate]:
    """Run the streaming estimator over recorded samples t (K,), S (K, channels) (and spin angles (K,) for the
    synchronous model); all refits in order."""
    t = np.asarray(t, dtype=float)
    S = np.asarray(S, dtype=float)
    if S.ndim != 2 or S.shape[0] != t.shape[0]:
        raise InputError(f"samples must have shape (len(t), channels); got {S.shape} for {t.shape[0]} times")
    if angles is not None and np.shape(angles) != t.shape:
        raise InputError(f"spin angles must have shape {t.shape}, got {np.shape(angles)}")
    est = StreamingEstimator(config, S.shape[1])
    out = []
    for k in range(t.shape[0]):
        e = est.push(t[k], S[k], None if angles is None else angles[k])
        if e is not None:
            out.append(e)
    return out
