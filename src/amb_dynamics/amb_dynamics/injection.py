"""The sensor-signal disturbance E of an ISO 14839-3 sensitivity measurement (ROS-free; used by the controller node).

E is added to the sampled displacement of one axis before the controller sees it (y_m = y + E).  Kinds:

* ``multisine``: lines at every multiple of ``resolution_hz`` inside the band, equal amplitudes, Schroeder phases
  (low crest factor), period 1/resolution_hz; scaled so that max|E| over a period is ``amplitude``.  Estimated with
  rectangular Welch segments of exactly one period (no leakage at the lines).
* ``swept``: a linear sine sweep over the band, repeated every ``period_s`` (default: the whole duration).
* ``stepped``: sines at ``steps`` log-spaced frequencies in the band, each held for duration/steps.

A raised-cosine fade-in over ``ramp_s`` limits the switch-on transient.  E is 0 before ``start_s`` and after
``start_s + duration_s``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import InputError

KINDS = ("none", "multisine", "swept", "stepped")


@dataclass(frozen=True)
class InjectionSpec:
    kind: str = "none"
    amplitude: float = 0.0  # m, peak of E
    band_hz: tuple[float, float] = (5.0, 50.0)
    duration_s: float = 20.0
    start_s: float = 0.0
    resolution_hz: float = 0.5  # multisine line spacing = 1/period
    steps: int = 20  # stepped sine
    ramp_s: float = 0.5

    def validate(self, fs: float) -> None:
        if self.kind not in KINDS:
            raise InputError(f"injection kind must be one of {', '.join(KINDS)} (got {self.kind!r})")
        if self.kind == "none":
            return
        lo, hi = self.band_hz
        if not (0 < lo < hi):
            raise InputError(f"injection band {lo:g}:{hi:g} Hz is empty: need 0 < lo < hi")
        if hi >= fs / 2:
            raise InputError(f"injection band upper {hi:g} Hz must be below the Nyquist frequency {fs / 2:g} Hz")
        if not self.amplitude > 0 or not self.duration_s > 0:
            raise InputError("injection amplitude (m) and duration (s) must be > 0")
        if self.kind == "multisine":
            if self.resolution_hz <= 0 or round(fs / self.resolution_hz) != fs / self.resolution_hz:
                raise InputError(
                    f"multisine resolution {self.resolution_hz:g} Hz must divide the sample rate {fs:g} Hz"
                )
            if self.lines().size == 0:
                raise InputError(f"no multisine line of {self.resolution_hz:g} Hz spacing lies in {lo:g}:{hi:g} Hz")
        if self.kind == "stepped" and self.steps < 1:
            raise InputError("stepped sine needs at least 1 step")

    def lines(self) -> np.ndarray:
        """Multisine frequencies (Hz)."""
        lo, hi = self.band_hz
        k = np.arange(np.ceil(lo / self.resolution_hz - 1e-9), np.floor(hi / self.resolution_hz + 1e-9) + 1)
        return k * self.resolution_hz

    def step_frequencies(self) -> np.ndarray:
        return np.geomspace(*self.band_hz, self.steps) if self.steps > 1 else np.array([np.sqrt(np.prod(self.band_hz))])


class Injection:
    """E(t_k) of a spec on the sample grid of rate fs (Hz); ``value(k)`` for sample k (t_k = k/fs)."""

    def __init__(self, spec: InjectionSpec, fs: float):
        spec.validate(fs)
        self.spec, self.fs = spec, fs
        self._scale = 1.0
        if spec.kind == "multisine":
            f = spec.lines()
            n = np.arange(f.size)
            self._f, self._phase = f, -np.pi * n * (n + 1) / f.size  # Schroeder
            period = self.period_samples()
            self._scale = spec.amplitude / np.abs(self._raw(np.arange(period) / fs)).max()
            self._table = self._scale * self._raw(np.arange(period) / fs)  # one period: O(1) per sample
        self._k0 = round(spec.start_s * fs)
        self._n = round(spec.duration_s * fs)

    @property
    def active(self) -> bool:
        return self.spec.kind != "none"

    def period_samples(self) -> int | None:
        """Samples per multisine period (the Welch segment), None for the other kinds."""
        return round(self.fs / self.spec.resolution_hz) if self.spec.kind == "multisine" else None

    def _raw(self, t: np.ndarray) -> np.ndarray:
        s = self.spec
        if s.kind == "multisine":
            return np.cos(2 * np.pi * np.outer(t, self._f) + self._phase).sum(axis=1)
        if s.kind == "swept":
            lo, hi = s.band_hz
            T = s.duration_s
            return s.amplitude * np.sin(2 * np.pi * (lo * t + (hi - lo) * t * t / (2 * T)))
        if s.kind == "stepped":
            f = s.step_frequencies()
            dwell = s.duration_s / f.size
            idx = np.minimum((t // dwell).astype(int), f.size - 1)
            return s.amplitude * np.sin(2 * np.pi * f[idx] * (t - idx * dwell))
        return np.zeros_like(t)

    def values(self, k: np.ndarray) -> np.ndarray:
        """E (m) at samples k (array)."""
        s = self.spec
        t = np.asarray(k, dtype=float) / self.fs - s.start_s
        on = (t >= 0) & (t < s.duration_s)
        out = np.zeros(t.shape)
        if not self.active or not on.any():
            return out
        out[on] = self._scale * self._raw(t[on])
        if s.ramp_s > 0:
            ramp = np.clip(t[on] / s.ramp_s, 0.0, 1.0)
            out[on] *= 0.5 - 0.5 * np.cos(np.pi * ramp)
        return out

    def value(self, k: int) -> float:
        """E (m) at sample k: the controller's per-sample call (a table look-up for a multisine)."""
        s = self.spec
        i = k - self._k0
        if not self.active or i < 0 or i >= self._n:
            return 0.0
        if s.kind != "multisine":
            return float(self.values(np.array([k]))[0])
        t = i / self.fs
        ramp = 1.0 if s.ramp_s <= 0 or t >= s.ramp_s else 0.5 - 0.5 * math.cos(math.pi * t / s.ramp_s)
        return float(self._table[i % self._table.size]) * ramp


@dataclass(frozen=True)
class InjectionLoad:
    """What an injection asks of its axis's amplifier, predicted by the digital-loop model (steady state).

    current : peak commanded current (A).
    slew : peak rate the amplifier must follow (A/s): its current loop's slope w_a |i_c - i_a| at the start of a
        sample (the first-order loop the plant runs; with an ideal amplifier, the held current's jump per sample
        times the rate).  The plant limits it to V/L (``actuator.slew_limit``).
    """

    current: float
    slew: float


def predicted_load(model, cfg, axis: int, injection: Injection, speed_rpm: float | None = None) -> InjectionLoad:
    """Peak current and slew rate the injection drives on its own axis through the digital loop.

    The controller output per unit E with every loop closed is (K S)_jj; the amplifier's lag i_c - i_a at the
    sample instants follows from it through (1 - z^-1) / (1 - a z^-1), a = exp(-w_a Ts).  Multisine: the exact
    periodic steady state (sum of its lines) over one period; swept and stepped sines: max|E| x the largest
    response over the band (quasi-stationary).
    """
    from .plant_dynamics import PlantDynamics
    from .sensitivity import ModalResponse, loop_state_spaces, sensitivity_state_space

    plant, ctrl = loop_state_spaces(model, cfg, cfg.spin_speed_rpm if speed_rpm is None else speed_rpm, "sampled")
    spec = injection.spec
    f = spec.lines() if spec.kind == "multisine" else np.geomspace(*spec.band_hz, 400)
    w = 2 * np.pi * f
    S = ModalResponse.of(sensitivity_state_space(plant, ctrl))(w)
    ks = (ctrl.freqresp(w) @ S)[:, axis, axis]
    wa = PlantDynamics.from_config(cfg).amplifier_rad_s
    Ts = 1.0 / injection.fs
    a = 0.0 if wa is None else math.exp(-wa * Ts)
    z1 = np.exp(-1j * w * Ts)
    lag = ks * (1 - z1) / (1 - a * z1)  # i_c - i_a per unit E
    per_s = injection.fs if wa is None else wa
    if spec.kind == "multisine":
        t = np.arange(injection.period_samples()) / injection.fs

        def peak(h: np.ndarray) -> float:
            phase = 2 * np.pi * np.outer(t, f) + injection._phase + np.angle(h)
            return float(np.abs((injection._scale * np.abs(h) * np.cos(phase)).sum(1)).max())

        return InjectionLoad(peak(ks), per_s * peak(lag))
    return InjectionLoad(float(spec.amplitude * np.abs(ks).max()), float(per_s * spec.amplitude * np.abs(lag).max()))


def overload(load: InjectionLoad, cfg, current_limit: float | None = None) -> str | None:
    """Why the predicted load is too much for the amplifier (current limit, then slew limit), or None.

    ``current_limit``: the controller's own (a node parameter may override the config's)."""
    limit = cfg.controller.current_limit if current_limit is None else current_limit
    if load.current > limit:
        return f"about {load.current:.3g} A, above the current limit {limit:g} A"
    limit = cfg.actuator.slew_limit
    if limit is not None and load.slew > limit:
        return (f"a current slew of about {load.slew * 1e-3:.3g} A/ms, above the amplifier's V/L = "
                f"{limit * 1e-3:.3g} A/ms (the loop would leave its linear model)")  # fmt: skip
    return None
