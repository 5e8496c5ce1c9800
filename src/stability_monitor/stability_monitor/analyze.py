"""Offline re-analysis of a recorded run: the live monitor's pipeline over a bag, and the model's value.

The bag's /base/imu and /amb_plant/state (or /amb/displacement) are decoded with the node's decoders and fed
to :class:`~stability_monitor.pipeline.MonitorPipeline` in log-time order, so the estimates are those the node
computes live.  The model value is the sampled-data Floquet multiplier (``floquet.sampled_floquet``) of the
rotor config (``--config`` / ``--set``, as given to ``amb-rig``) under the base motion read back from the
recorded angular velocity (single-axis motions: axis, amplitude, frequency and phase fitted).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

import amb_ros.messages as m
from amb_bag.errors import BagError
from amb_bag.reader import Bag
from amb_dynamics.errors import InputError
from amb_dynamics.estimator.stream import Estimate
from amb_dynamics.motion import AXES, BaseMotion, Harmonic

from .messages import STATE_BLOCK_TYPE, JointStateInput, StateBlockInput
from .pipeline import MonitorPipeline, MonitorSettings

AXIS_OF_COMPONENT = {0: "roll", 1: "yaw", 2: "pitch"}  # Omega components x, y, z
SINGLE_AXIS_TOL = 1e-9


@dataclass
class Analysis:
    """Everything ``amb-monitor analyze`` reports."""

    bag: str
    topic: str
    pipeline: MonitorPipeline
    estimates: list[Estimate]
    imu_t: np.ndarray
    imu_w: np.ndarray
    sample_spacing: float | None
    rejected: dict[str, int] = field(default_factory=dict)
    model: dict | None = None
    notes: list[str] = field(default_factory=list)

    def to_dict(self, top: int = 6) -> dict:
        pl, last = self.pipeline, (self.estimates[-1] if self.estimates else None)
        pe = pl.period_estimate
        return {
            "bag": self.bag,
            "input_topic": self.topic,
            "samples": pl.samples,
            "rejected": self.rejected,
            "period_s": pe.period if pe else None,
            "base_period_s": pe.base_period if pe else None,
            "forcing": pl.forcing or None,
            "synchronous": pl.s.synchronous,
            "notes": self.notes,
            "refits": len(self.estimates),
            "estimates": [e.to_dict(top) for e in self.estimates],
            "verdict": last.verdict if last else pl.state,
            "unstable": bool(last.unstable) if last else False,
            "flag_time_s": pl.flag_time,
            "final": last.to_dict(top) if last else None,
            "model": self.model,
        }


def analyze_bag(path: Path, settings: MonitorSettings, auto_synchronous: bool = False) -> Analysis:
    """Run the monitor's pipeline over the bag at ``path`` (``auto_synchronous``: the synchronous model is
    dropped, with a note, when the bag has no tachometer topic)."""
    bag = Bag(path)  # amb_bag's reader: one line for a missing, empty, foreign, unfinished or damaged bag
    topics = {name: t.type for name, t in bag.topics.items()}
    notes = []
    if settings.synchronous and m.SPIN_SPEED not in topics:
        if not auto_synchronous:
            raise BagError(f"{path} has no {m.SPIN_SPEED} topic for the synchronous model: give --synchronous 0")
        settings = replace(settings, synchronous=0)
        notes.append(f"no {m.SPIN_SPEED} in the bag: the synchronous response (unbalance, runout) is not modelled")
    topic = m.DISPLACEMENT if settings.sensor_only else m.STATE
    if topic not in topics:
        hint = "" if settings.sensor_only else " (use --sensor-only for a bag with /amb/displacement only)"
        raise BagError(f"{path} has no {topic} topic{hint}")
    wanted = [topic]
    if settings.period == 0:
        if m.IMU not in topics:
            raise BagError(f"{path} has no {m.IMU} topic to find the base period: give --period")
        wanted.append(m.IMU)
    if settings.synchronous:
        wanted.append(m.SPIN_SPEED)
        spin_in = JointStateInput(("position", "velocity"))
    if settings.sensor_only:
        data_in = JointStateInput(("position",))
    elif topics[topic] == STATE_BLOCK_TYPE:
        data_in = StateBlockInput()
    else:  # a bag recorded when /amb_plant/state carried one JointState per sample
        data_in = JointStateInput(("position", "velocity"))
    imu_decoder = m.imu_decoder()
    pipeline = MonitorPipeline(settings)
    estimates: list[Estimate] = []
    rejected = {t: 0 for t in wanted}
    imu_t, imu_w, spacing, last_t = [], [], [], None
    for name, _type, _log_ns, _pub_ns, raw in bag.messages(wanted):
        try:
            if name == m.IMU:
                t_ns, v = imu_decoder(raw)
                imu_t.append(t_ns * 1e-9)
                imu_w.append(v[4:7].copy())
                estimates.extend(pipeline.on_imu(t_ns * 1e-9, v[4:7]))
                continue
            if name == m.SPIN_SPEED:
                t_ns, v = spin_in(raw)
                if v.size != 2:
                    raise m.Rejected(f"{v.size // 2} tachometer channels, expected 1")
                estimates.extend(pipeline.on_spin(t_ns * 1e-9, float(v[0]), float(v[1])))
                continue
            stamps, rows = data_in.samples(raw)
        except m.Rejected:
            rejected[name] += 1
            continue
        if pipeline.scale_groups is None:
            pipeline.scale_groups = data_in.scale_groups()
        for t_ns, v in zip(stamps.tolist(), rows, strict=True):
            t = t_ns * 1e-9
            if last_t is not None and t > last_t and len(spacing) < 64:
                spacing.append(t - last_t)
            try:
                estimates.extend(pipeline.on_sample(t, v))
            except InputError as exc:
                raise BagError(f"{path}: {topic}: {exc}") from None
            last_t = t
    if pipeline.samples == 0:
        raise BagError(f"{path} holds no usable {topic} message")
    return Analysis(
        str(path),
        topic,
        pipeline,
        estimates,
        np.asarray(imu_t),
        np.asarray(imu_w).reshape(-1, 3),
        float(np.median(spacing)) if spacing else None,
        rejected,
        notes=notes,
    )


def recorded_motion(t: np.ndarray, W: np.ndarray, base_period: float) -> BaseMotion:
    """Single-axis harmonic base motion that reproduces the recorded angular velocity (rad/s)."""
    peak = np.abs(W).max(axis=0)
    axis = int(np.argmax(peak))
    if any(peak[j] > SINGLE_AXIS_TOL * peak[axis] for j in range(3) if j != axis):
        raise InputError("the recorded base motion turns about more than one axis: no model value")
    from scipy.optimize import minimize_scalar

    def harmonic_fit(w: float):
        # Omega = A w cos(w t + phase): least squares for (a, b) in a cos(w t) + b sin(w t)
        basis = np.column_stack([np.cos(w * t), np.sin(w * t)])
        ab, *_ = np.linalg.lstsq(basis, W[:, axis], rcond=None)
        return float(np.sqrt(np.mean((basis @ ab - W[:, axis]) ** 2))), ab

    # the period from up-crossings is good to ~1e-7; over a long record its phase error exceeds the tolerance,
    # so the frequency is refined by least squares within +-1e-4 of it
    w0 = 2.0 * np.pi / base_period
    best = minimize_scalar(lambda w: harmonic_fit(w)[0], bounds=(w0 * (1 - 1e-4), w0 * (1 + 1e-4)),
                           method="bounded", options={"xatol": 1e-13 * w0})  # fmt: skip
    w = float(best.x) if harmonic_fit(best.x)[0] < harmonic_fit(w0)[0] else w0
    rms, (a, b) = harmonic_fit(w)
    amp_w = float(np.hypot(a, b))
    if rms > 1e-6 * amp_w:
        raise InputError("the recorded base motion is not a single harmonic: no model value")
    kind = AXIS_OF_COMPONENT[axis]
    assert kind in AXES
    return BaseMotion((Harmonic(kind, amp_w / w, w, float(np.arctan2(-b, a))),), kind)


def model_value(analysis: Analysis, cfg) -> dict:
    """Sampled-data model multipliers for the recorded base motion and the given rotor config."""
    from amb_dynamics.digital_floquet import estimate_point

    from .model_check import model_loop

    pe = analysis.pipeline.period_estimate
    if pe is None or analysis.imu_t.size < 16:
        raise InputError("no base period or base rates in the analysis: no model value")
    motion = recorded_motion(analysis.imu_t, analysis.imu_w, pe.base_period)
    loop = model_loop(cfg)  # as the rig runs it: about its operating point (a nonlinear law's tangent there)
    Ts = loop.Ts  # the nodes' whole-ns sample period
    notes = []
    if analysis.sample_spacing is not None:
        ratio = analysis.sample_spacing / Ts
        if abs(ratio - round(ratio)) > 1e-6:
            notes.append(f"recorded sample spacing {analysis.sample_spacing:.9g} s is not a multiple of Ts = {Ts:g} s")
    h = motion.harmonics[0]
    # the period of A(t) for the refined frequency (the estimate's kind: base period or half of it)
    period = pe.period * (2.0 * np.pi / pe.base_period) / h.frequency
    res = estimate_point(loop, motion, period)  # exact for T/Ts = p/r, else interpolated with a bound
    return {
        "rho": res["max_abs_multiplier"],
        "error_bound": res["error_bound"],
        "multipliers": res["multipliers"][:6],
        "motion": {"kind": h.axis, "amplitude_rad": h.amplitude, "frequency_rad_s": h.frequency, "phase_rad": h.phase},
        "method": res["method"],
        "notes": notes + list(res.get("notes", [])),
    }


def try_model_value(analysis: Analysis, cfg) -> dict:
    """``model_value`` or {'error': reason} when the recorded motion has no model value (not a failure)."""
    try:
        return model_value(analysis, cfg)
    except InputError as exc:
        return {"error": str(exc)}
