"""The controller's sensor-signal injection (ISO 14839-3): parameters, the refusal check, y_m = y + E, /amb/injection.

E (:mod:`amb_dynamics.injection`) is added to the sampled displacement of one axis before the PID sees it; every
answered sample publishes ``/amb/injection`` (sensor_msgs/JointState, stamp = the sample's, name = ["injection",
"disturbed"], position = [E, y_m] in m, frame_id = the axis) while the injection is configured.  An amplitude whose
predicted steady-state current or current slew (digital-loop model, :func:`amb_dynamics.injection.predicted_load`)
exceeds the amplifier's current limit or its V/L is refused unless ``injection_force`` is true.
"""

from __future__ import annotations

import numpy as np
from sensor_msgs.msg import JointState

import amb_ros.messages as m
from amb_dynamics.errors import InputError
from amb_dynamics.injection import KINDS, Injection, InjectionSpec, overload, predicted_load
from amb_dynamics.structure import build_structure
from amb_ros.params import ParamSpec
from amb_ros.qos import data_qos

INJECTION = "/amb/injection"


def injection_specs() -> list[ParamSpec]:
    return [
        ParamSpec("injection_kind", "none", "disturbance added to one axis's sensor signal (ISO 14839-3)",
                  choices=KINDS),
        ParamSpec("injection_axis", "amb1_y", "AMB axis (channel name) that receives the injection"),
        ParamSpec("injection_amplitude", 0.0, "peak of the injected disturbance E", "m", 0.0, 1.0),
        ParamSpec("injection_band_lo_hz", 5.0, "lower band edge", "Hz", 0.0, 1e6),
        ParamSpec("injection_band_hi_hz", 50.0, "upper band edge (below Nyquist)", "Hz", 0.0, 1e6),
        ParamSpec("injection_duration_s", 20.0, "injection length (simulated time in lockstep)", "s", 0.0, 1e6),
        ParamSpec("injection_start_s", 0.0, "injection start", "s", 0.0, 1e6),
        ParamSpec("injection_resolution_hz", 0.5, "multisine line spacing (1/period); must divide rate_hz", "Hz",
                  1e-6, 1e6),
        ParamSpec("injection_steps", 20, "stepped sine: number of frequencies", "", 1, 100000),
        ParamSpec("injection_ramp_s", 0.5, "raised-cosine fade-in", "s", 0.0, 1e6),
        ParamSpec("injection_force", False, "inject even if the predicted current or slew exceeds its limit"),
    ]  # fmt: skip


class InjectionHook:
    """Set up from the node's parameters; ``apply(t_ns, y, t)`` returns y_m and publishes (E, y_m)."""

    def __init__(self, node):
        p = node.p
        self.active = p["injection_kind"] != "none"
        self.pub = None
        if not self.active:
            return
        if p["injection_axis"] not in node.channels:
            raise InputError(
                f"parameter 'injection_axis' = {p['injection_axis']!r} does not exist (axes: "
                f"{', '.join(node.channels)})"
            )
        self.axis = node.channels.index(p["injection_axis"])
        spec = InjectionSpec(
            p["injection_kind"],
            p["injection_amplitude"],
            (p["injection_band_lo_hz"], p["injection_band_hi_hz"]),
            p["injection_duration_s"],
            p["injection_start_s"],
            p["injection_resolution_hz"],
            p["injection_steps"],
            p["injection_ramp_s"],
        )
        self.fs = 1.0 / node.Ts
        self.injection = Injection(spec, self.fs)
        load = predicted_load(build_structure(node.cfg), node.cfg, self.axis, self.injection)
        self.predicted_current = load.current
        why = overload(load, node.cfg, p["current_limit"])
        if why is not None and not p["injection_force"]:
            raise InputError(
                f"injection of {spec.amplitude:g} m on {p['injection_axis']} would drive {why} (model of the digital "
                "loop): lower injection_amplitude or set injection_force:=true"
            )
        self.pub = node.create_publisher(JointState, INJECTION, data_qos(node.mode, p["qos_depth"]))
        self.names = (f"{p['injection_axis']}_injection", f"{p['injection_axis']}_disturbed")
        self.codec = m.joint_state_codec(self.names, ("position",))
        self.counters = node.counters
        self.published = 0

    def apply(self, t_ns: int, y: np.ndarray, t: float) -> np.ndarray:
        if not self.active:
            return y
        e = self.injection.value(round(t * self.fs))
        y = y.copy()
        y[self.axis] += e
        self.pub.publish(self.codec.encode(t_ns, np.array([e, y[self.axis]])))
        self.published += 1
        self.counters.published[INJECTION] += 1
        return y

    def values(self) -> dict[str, str]:
        if not self.active:
            return {"injection": "none"}
        s = self.injection.spec
        return {
            "injection": f"{s.kind} {s.amplitude:g} m on {s.band_hz[0]:g}-{s.band_hz[1]:g} Hz",
            "injection predicted current (A)": f"{self.predicted_current:.4g}",
        }
