"""ROS-free heart of the stability monitor: base period from the base rates, buffering, the estimator.

The node (live topics) and ``amb-monitor analyze`` (a recorded bag) feed the same ``MonitorPipeline`` with the
same samples in the same order, so they produce the same estimates.  Samples that arrive before the period is
known are buffered and replayed into the estimator once it is: the start of a run, where the transient is
largest, is the most informative part.  Everything decided here depends on the data only (sample counts and
stamps), never on wall time, so a replay gives the same output as the live run.
"""

from __future__ import annotations

from collections import deque
from dataclasses import MISSING, dataclass, fields, replace

import numpy as np

from amb_dynamics.errors import InputError
from amb_dynamics.estimator.fit import VerdictPolicy
from amb_dynamics.estimator.period import PeriodEstimate, estimate_base_period
from amb_dynamics.estimator.stream import Estimate, EstimatorConfig, StreamingEstimator

FORCING_CHOICES = ("auto", "none", "constant", "alternating", "two_periods")
IMU_TRY_EVERY = 64  # base-rate samples between attempts to find the period (64 ms at the 1 kHz lockstep /base/imu)
SAMPLE_TIME_FROM = 8  # sample spacings that fix the sample time (median)
TACH_KEEP = 4096  # tachometer samples kept (the pending samples are always within the newest few)


def synchronous_harmonics(requested: int, cfg) -> int:
    """Spin harmonics to model: ``requested`` (>= 0), or for -1 (auto) 1 when the rotor config ``cfg`` has an
    unbalance or a sensor runout (both once per revolution), else 0."""
    if requested >= 0:
        return int(requested)
    from amb_dynamics.config_rig import disk_unbalance

    unbalanced = any(disk_unbalance(d, cfg.shaft.density, cfg.max_speed_rpm)[0] != 0.0 for d in cfg.disks)
    return int(unbalanced or cfg.sensor.runout != 0.0)


def auto_forcing(motion_forcing: str, base_forcing: bool, gravity: bool) -> str:
    """The forcing model of 'auto': the base motion's (``motion_forcing``, from the base rates) when the loop
    carries its inertial load, plus gravity's (constant, and alternating under pitch and yaw) when it has one."""
    kinds = {motion_forcing} - {"none"} if base_forcing else set()
    if gravity:
        kinds |= {"constant"} | ({"alternating"} if motion_forcing == "alternating" else set())
    if len(kinds) > 1:
        return "two_periods"
    return kinds.pop() if kinds else "none"


# the estimator's and the verdict's own defaults: typed once, in amb_dynamics.estimator
_EST = {f.name: f.default for f in fields(EstimatorConfig) if f.default is not MISSING}
_POLICY = VerdictPolicy()


@dataclass(frozen=True)
class MonitorSettings:
    """Monitor options (the node's parameters and the CLI's flags map onto these one to one).

    period : float
        Period of A(t) (s); 0 = estimate it from the base rates (/base/imu).
    forcing : str
        'auto': 'none' if ``base_forcing`` is off, else from the base rates (with a fixed period:
        'two_periods', any forcing that repeats every two periods, which covers constant and alternating);
        or 'none', 'constant', 'alternating', 'two_periods'.
    base_forcing : bool
        Whether the loop carries the inertial load of the base motion (the rotor config's ``base_forcing``; a
        real rig always does).
    gravity : bool
        Whether gravity loads the rotor (the config's ``gravity.enabled``): in the base frame it turns with the
        base, a forcing that repeats every period of A(t) and, for pitch and yaw, also alternates; with 'auto'
        it adds the constant sequence (and the alternating one: 'two_periods') to the base forcing model.
    noise_std : float
        Measurement-noise std of every channel (signal units); < 0 = estimate it from the data.
    window : int
        Periods in the moving window of a moving base (default 32: sensor-only estimates within 0.005 of the
        model after 32 periods, where 16 scattered by 0.01 and read 0.007 low; detection uses the growing window
        before it is full, so it is not delayed).
    static_window : int
        Periods (of ``static_period``) in the window of a static base (default 16 = 1.6 s: short enough that a
        run-up's speed barely moves inside it).
    static_wait : float
        Seconds of base rates without rotation after which the base is taken as static and ``static_period``
        is used (the loop is then time-invariant and any period gives its multipliers).
    synchronous : int
        Spin harmonics whose synchronous response (unbalance, runout) is removed, with the spin angle from the
        tachometer (``on_spin``, unwrapped with the mean speed between its samples); 0 = none.  Each sample
        waits for the tachometer sample at or after its stamp and takes the angle interpolated between the two
        around it (cubic Hermite in angle and speed).
    velocities : bool
        With a full-state input ([q; q'], scale groups 0 and 1), fit the velocities too.  Off (the default): the
        positions q only.  The P phases of a period already observe the velocities (a delay embedding), and the
        velocities of the fast, noise-driven modes are what the innovation plateau is made of: on the real-rig
        config the positions alone identify the growing mode about twice as early (docs/monitor.md).
    """

    sensor_only: bool = False
    period: float = 0.0
    forcing: str = "auto"
    base_forcing: bool = True
    gravity: bool = False
    phases: int = _EST["phases"]
    window: int = 32
    static_window: int = 16
    updates_per_period: int = _EST["updates_per_period"]
    method: str = _EST["method"]
    max_rank: int = _EST["max_rank"]
    noise_std: float = -1.0
    margin: float = _POLICY.margin
    hysteresis: float = _POLICY.hysteresis
    z: float = _POLICY.z
    confirm: int = _POLICY.confirm
    static_wait: float = 1.0
    static_period: float = 0.1
    max_buffer: int = 400_000
    synchronous: int = 0
    velocities: bool = False

    def __post_init__(self):
        if self.forcing not in FORCING_CHOICES:
            raise InputError(f"forcing '{self.forcing}' is not one of {', '.join(FORCING_CHOICES)}")
        if not (np.isfinite(self.period) and self.period >= 0):
            raise InputError(f"period must be >= 0 s (0 = estimate from the base rates), got {self.period}")
        VerdictPolicy(self.margin, self.hysteresis, self.z, self.confirm)  # validates
        if not 0 <= self.synchronous <= 8:
            raise InputError(f"synchronous harmonics must be 0..8, got {self.synchronous}")


class MonitorPipeline:
    """Period detection + estimator over one run; ``on_sample`` returns the estimates it produced."""

    def __init__(self, settings: MonitorSettings, scale_groups: tuple[int, ...] | None = None):
        self.s = settings
        self.scale_groups = scale_groups
        self._keep: np.ndarray | None = None  # the channels fitted (positions of a full state), fixed at sample 1
        self.restarts = 0
        self.reset()

    def reset(self) -> None:
        """Forget the run (a plant restart: stamps start again at 0)."""
        self.period_estimate: PeriodEstimate | None = None
        self.estimator: StreamingEstimator | None = None
        self.sample_time: float | None = None
        self.state = "waiting for the base period" if self.s.period == 0 else "waiting for samples"
        self.note = ""
        self.samples = self.imu_samples = self.refits = 0
        self.flag_time: float | None = None
        self.latest: Estimate | None = None
        self.recent: deque[tuple[float, float]] = deque()  # (time, rho): excited full-window refits, last window
        self._buffer: list[tuple[float, np.ndarray, float | None]] = []
        self._imu_t: list[float] = []
        self._imu_w: list[np.ndarray] = []
        self._last_t: float | None = None
        self._tach: deque = deque(maxlen=TACH_KEEP)  # (t, angle, speed), increasing t
        self._pending: deque = deque()  # samples waiting for the tachometer to reach their stamp
        self.tach_samples = 0

    # ---- inputs ------------------------------------------------------------------------------------------
    def on_imu(self, t: float, omega: np.ndarray) -> list[Estimate]:
        """One base angular-velocity sample (rad/s, base axes) at time t (s); returns the refits it caused
        (when it completes the period, the buffered samples go through the estimator)."""
        if self.period_estimate is not None or self.s.period > 0:
            return []
        if self._imu_t and t <= self._imu_t[-1]:
            if t != 0.0:
                return []
            self._imu_t, self._imu_w = [], []  # base motion restarted with the run
        self._imu_t.append(float(t))
        self._imu_w.append(np.asarray(omega, dtype=float).copy())
        self.imu_samples += 1
        if len(self._imu_t) % IMU_TRY_EVERY == 0 and self.sample_time is not None:
            return self._try_period(len(self._imu_t))
        return []

    def on_spin(self, t: float, angle: float, speed: float) -> list[Estimate]:
        """One tachometer sample: spin angle (rad) and speed (rad/s) at time t (s); returns the refits of the
        samples it releases (``synchronous``)."""
        if not (np.isfinite(t) and np.isfinite(angle) and np.isfinite(speed)):
            raise InputError("tachometer sample is not finite")
        if self._tach and t <= self._tach[-1][0]:
            if t != 0.0:
                return []  # a repeat or an old sample
            self._tach.clear()  # the plant restarted
        if self._tach:  # a tachometer may wrap its angle (the plant's is in [0, 2 pi)): unwrap it
            t0, a0, w0 = self._tach[-1]
            predicted = a0 + 0.5 * (w0 + speed) * (t - t0)
            angle += 2.0 * np.pi * round((predicted - angle) / (2.0 * np.pi))
        self._tach.append((float(t), float(angle), float(speed)))
        self.tach_samples += 1
        out: list[Estimate] = []
        while self._pending and self._pending[0][0] <= t:
            ts, values = self._pending.popleft()
            out.extend(self._accept(ts, values, self._angle_at(ts)))
        return out

    def _angle_at(self, t: float) -> float:
        """Spin angle at t from the tachometer samples around it (at or before the first one: extrapolated)."""
        tach = self._tach
        k = len(tach) - 1
        while k > 0 and tach[k - 1][0] >= t:
            k -= 1
        t1, a1, w1 = tach[k]
        if k == 0 or t >= t1:
            return a1 + w1 * (t - t1)
        t0, a0, w0 = tach[k - 1]
        h = t1 - t0
        u = (t - t0) / h
        # cubic Hermite: exact for a constant angular acceleration
        return (
            (2 * u**3 - 3 * u**2 + 1) * a0
            + (u**3 - 2 * u**2 + u) * h * w0
            + (-2 * u**3 + 3 * u**2) * a1
            + (u**3 - u**2) * h * w1
        )

    @property
    def waiting_for_tach(self) -> int:
        """Samples held until the tachometer reaches their stamp."""
        return len(self._pending)

    def on_sample(self, t: float, values: np.ndarray) -> list[Estimate]:
        """One snapshot (state [q; q'] or AMB displacements) at time t (s); returns the refits it caused."""
        if self._last_t is not None and t <= self._last_t:
            if t != 0.0:
                raise InputError(f"sample time {t:.9f} s is not after {self._last_t:.9f} s")
            self.restarts += 1
            self.reset()
        self._last_t = float(t)
        values = np.asarray(values, dtype=float)
        if self.samples == 0 and self.restarts == 0:
            self._keep = self._fitted_channels(values.size)
        values = values[self._keep] if self._keep is not None else values.copy()
        self.samples += 1
        if not self.s.synchronous:
            return self._accept(float(t), values, None)
        if self._tach and self._tach[-1][0] >= t and not self._pending:
            return self._accept(float(t), values, self._angle_at(t))
        if len(self._pending) >= self.s.max_buffer:
            raise InputError(f"no tachometer sample (/amb/spin_speed) for {self.s.max_buffer} samples: "
                             "set synchronous to 0 or publish the spin angle")  # fmt: skip
        self._pending.append((float(t), values))
        return []

    def _fitted_channels(self, size: int) -> np.ndarray | None:
        """Indices of the positions of a full-state input ([q; q'] with scale groups 0 and 1) unless
        ``velocities``; None: every channel."""
        groups = None if self.scale_groups is None else np.asarray(self.scale_groups)
        if self.s.velocities or self.s.sensor_only or groups is None or groups.size != size or not (groups == 1).any():
            return None
        return np.flatnonzero(groups == 0)

    def _accept(self, t: float, values: np.ndarray, angle: float | None) -> list[Estimate]:
        """A sample with its spin angle (None without the synchronous model): into the estimator or the buffer."""
        if self.estimator is not None:
            return self._push(t, values, angle)
        if len(self._buffer) >= self.s.max_buffer:
            raise InputError(f"no base period after {self.s.max_buffer} samples: set the period parameter")
        self._buffer.append((t, values, angle))
        if self.sample_time is None and len(self._buffer) > SAMPLE_TIME_FROM:
            dt = np.diff([b[0] for b in self._buffer])
            self.sample_time = float(np.median(dt))
            if self.s.period > 0:
                return self._start(PeriodEstimate(self.s.period, self.s.period, "two_periods"), self.s.window)
            # the attempts skipped while the sample time was unknown (base rates drained ahead of the samples):
            # the period always comes from the same prefix of the base rates, whatever the arrival batching
            for count in range(IMU_TRY_EVERY, len(self._imu_t) + 1, IMU_TRY_EVERY):
                out = self._try_period(count)
                if self.estimator is not None:
                    return out
        return []

    # ---- period and start ------------------------------------------------------------------------------
    def _try_period(self, count: int) -> list[Estimate]:
        """Find the period from the first ``count`` base-rate samples (a multiple of IMU_TRY_EVERY)."""
        t = np.asarray(self._imu_t[:count])
        try:
            pe = estimate_base_period(t, np.asarray(self._imu_w[:count]), self.sample_time)
        except InputError as exc:
            self.note = str(exc)
            if "does not rotate" in self.note and t[-1] - t[0] >= self.s.static_wait:
                # any window is a period of a static base: at least one sample per phase (slow loops, e.g. 1 kHz)
                period = max(self.s.static_period, self.s.phases * self.sample_time)
                self.note = f"static base: multipliers per {period:g} s"
                return self._start(PeriodEstimate(period, period, "constant"), self.s.static_window)
            return []
        self.note = ""
        return self._start(pe, self.s.window)

    def _start(self, pe: PeriodEstimate, window: int) -> list[Estimate]:
        forcing = self.s.forcing
        if forcing == "auto":
            forcing = auto_forcing(pe.forcing, self.s.base_forcing, self.s.gravity)
        self.period_estimate = pe
        self._imu_t, self._imu_w = [], []
        cfg = EstimatorConfig(
            period=pe.period,
            sample_time=self.sample_time,
            forcing=2 if forcing == "two_periods" else forcing,
            sync_harmonics=self.s.synchronous,
            phases=self.s.phases,
            window=window,
            updates_per_period=self.s.updates_per_period,
            method=self.s.method,
            max_rank=self.s.max_rank,
            noise_std=None if self.s.noise_std < 0 else self.s.noise_std,
            scale_groups=self.scale_groups if self._keep is None else (0,) * self._keep.size,
            policy=VerdictPolicy(self.s.margin, self.s.hysteresis, self.s.z, self.s.confirm),
        )
        channels = self._buffer[0][1].size
        self.estimator = StreamingEstimator(cfg, channels)
        self.state = "running"
        out = []
        for t, v, a in self._buffer:
            out.extend(self._push(t, v, a))
        self._buffer = []
        return out

    def _push(self, t: float, values: np.ndarray, angle: float | None) -> list[Estimate]:
        est = self.estimator.push(t, values, angle)
        if est is None:
            return []
        self.refits += 1
        self.latest = est
        if est.fit.excited and est.periods >= self.estimator.cfg.window:
            self.recent.append((est.time, est.rho))
            span = self.estimator.cfg.window * self.estimator.cfg.period
            while self.recent[0][0] < est.time - span:
                self.recent.popleft()
        if est.unstable and self.flag_time is None:
            self.flag_time = est.time
        return [est]

    def set_margins(self, margin: float, hysteresis: float) -> None:
        """Change the flag's margin and hysteresis while running; the latched flag and its counts are kept."""
        self.s = replace(self.s, margin=margin, hysteresis=hysteresis)
        if self.estimator is not None:
            self.estimator.flag.policy = replace(self.estimator.flag.policy, margin=margin, hysteresis=hysteresis)

    def rho_scatter(self) -> float:
        """Standard deviation of rho over the excited full-window refits of the last window (0 if fewer than 2).

        The fit's own standard error assumes independent noise on every snapshot entry; a rig's process noise
        moves all channels together, and on the real-rig default that error (~3e-5) is far under the scatter of
        rho between runs (~1e-3).  The refits' scatter shows it; the model check takes the larger of the two."""
        if len(self.recent) < 2:
            return 0.0
        return float(np.std([r for _, r in self.recent], ddof=1))

    @property
    def forcing(self) -> str:
        return "" if self.estimator is None else str(self.estimator.cfg.forcing)
