"""The live monitor's model value and its "model mismatch" check.

The model value is the sampled-data multiplier of the config's own loop (amplifier, sensor, controller rate and
delay; ``SampledLoop``, forcing off; a nonlinear bearing law linearised at the levitated operating point,
``rig_loop.levitated_bearing``) on the config's base motion, per period of A(t): the value an engineer would
look up in a chart before the run (``digital_floquet.estimate_point``: exact for T/Ts = p/r, else interpolated in
T/Ts with a stated bound).  It is computed once, in a background thread started after the monitor has taken its
scheduling (below the loop's: it only uses CPU the loop leaves), so the monitor starts estimating at once.

The running estimate disagrees with the model when

    |rho - rho_model| > max(MISMATCH_Z std(rho), MISMATCH_FLOOR, MISMATCH_DAMPING |1 - rho_model|) + bound

(per the estimate's period): the rig is not the config (other gains, a stiffer bearing, another rate) or the
config's motion is not the base's.  The last term allows 0.4 of the model's distance from 1, i.e. of its decay
(or growth) per period: a loop whose damping is off by more than that is not the one the config describes.  The
model is linear; on a tilting base the real rig rides a forced orbit of gravity where its bearing law is not, and
grows up to a third slower than the model says (tests/test_operating_point.py): the allowance keeps that rig,
which is the config, from being called a mismatch.
Only an excited, converged estimate (a full window of periods) is compared.
"""

from __future__ import annotations

import threading

from amb_dynamics.config import RotorConfig

MISMATCH_Z = 5.0  # standard errors of the estimate
MISMATCH_FLOOR = 1e-4  # absolute, per period
MISMATCH_DAMPING = 0.4  # of |1 - rho_model|


class ModelValue:
    """max|mu| of the config's digital loop on the config's base motion, computed in the background."""

    def __init__(self, cfg: RotorConfig):
        self.cfg = cfg
        self.rho: float | None = None  # per period of A(t)
        self.bound = 0.0
        self.period: float | None = None  # of A(t), s
        self.error = ""  # why there is no model value
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        self._thread = threading.Thread(target=self._compute, name="model-value", daemon=True)
        self._thread.start()

    def wait(self, timeout: float | None = None) -> None:
        if self._thread is not None:
            self._thread.join(timeout)

    def _compute(self) -> None:
        try:
            self.rho, self.bound, self.period = model_multiplier(self.cfg)
        except Exception as exc:  # any reason is reported in the diagnostics, never fatal to the monitor
            self.error = str(exc) or type(exc).__name__

    def per(self, period: float) -> float | None:
        """The model value per ``period`` (the monitor's period: that of A(t) or a whole multiple of it)."""
        if self.rho is None or self.period is None:
            return None
        n = max(1, round(period / self.period))
        return self.rho**n

    def mismatch(self, rho: float, rho_std: float, period: float) -> str | None:
        """A one-line reason when the estimate rho +- rho_std (per ``period``) disagrees with the model."""
        model = self.per(period)
        if model is None:
            return None
        n = max(1, round(period / self.period))
        allowed = max(MISMATCH_Z * rho_std, MISMATCH_FLOOR, MISMATCH_DAMPING * abs(1.0 - model)) + n * self.bound
        if abs(rho - model) <= allowed:
            return None
        return (f"model mismatch: rho = {rho:.4f} +- {rho_std:.2g}, the config's loop on its base motion gives "
                f"{model:.4f} (difference {rho - model:+.4f}, allowed {allowed:.2g})")  # fmt: skip

    def values(self) -> dict[str, str]:
        if self.rho is not None:
            return {"model rho per A(t) period": f"{self.rho:.6f}", "model bound": f"{self.bound:.2g}",
                    "model period (s)": f"{self.period:.9g}"}  # fmt: skip
        return {"model rho": self.error or "computing"}


def model_loop(cfg: RotorConfig):
    """The config's digital loop as the rig runs it: the nodes' whole-ns sample period, forcing off, a nonlinear
    bearing law linearised at the levitated operating point."""
    from amb_dynamics.rig_loop import levitated_bearing
    from amb_dynamics.sampled import SampledLoop
    from amb_dynamics.structure import build_structure

    Ts = max(1, round(1e9 / cfg.controller.rate_hz)) / 1e9
    model = build_structure(cfg)
    return SampledLoop(model, cfg, Ts=Ts, forcing=False, bearing=levitated_bearing(model, cfg, Ts))


def model_multiplier(cfg: RotorConfig) -> tuple[float, float, float]:
    """(max|mu|, its error bound, the period of A(t)) of the config's digital loop on its single-axis motion."""
    import math

    from amb_dynamics.digital_chart import parametric_period
    from amb_dynamics.digital_floquet import estimate_point
    from amb_dynamics.motion import BaseMotion

    motion = BaseMotion.from_config(cfg.base_motion)
    if len(motion.harmonics) != 1:
        raise ValueError("no model value: the config's base motion is not one harmonic about one axis")
    h = motion.harmonics[0]
    loop = model_loop(cfg)
    period = parametric_period(loop, h.axis, h.frequency)
    res = estimate_point(loop, motion, period)
    rho, bound = float(res["max_abs_multiplier"]), float(res["error_bound"])
    if not (math.isfinite(rho) and math.isfinite(bound)):
        raise ValueError("no model value: the model's multiplier is not finite")
    return rho, bound, period
