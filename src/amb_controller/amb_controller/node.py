"""amb_controller node: the digital PID per AMB axis (``amb_dynamics.amb.DiscretePID``) at rate_hz.

Topics (layouts in docs/topics.md)
----------------------------------
subscribes /amb/displacement   sensor_msgs/JointState: name = channels, position = displacement (m)
publishes  /amb/current        sensor_msgs/JointState: same names, effort = current (A); stamp = the stamp of
                               the displacement sample it answers
publishes  /diagnostics        samples answered, compute time, period jitter p50/p99/max and missed deadlines
                               (realtime), saturation, lost/rejected samples, sensor state

Lockstep: every displacement sample is answered once, in order (a gap in the stamps is counted as lost samples;
a sample for t = 0 after others means the plant restarted: the PID is reset).  Realtime: a wall-clock ticker at
rate_hz computes the current from the latest sample (sample-and-hold, as an ADC would); the period error of each
tick and the deadlines missed (a tick more than half a period late, or skipped) are reported.  Safe behaviour:
when no new sample has arrived for sensor_timeout_s, the controller outputs zero current (de-levitate onto the
touchdown bearings rather than act on stale data), resets its PID and reports ERROR until samples return.
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool

import amb_ros.messages as m
from amb_dynamics.amb import DiscretePIDCoefficients
from amb_dynamics.errors import InputError
from amb_dynamics.rig_loop import RigController
from amb_dynamics.structure import AMBGains, channel_names
from amb_ros.diag_keys import Controller
from amb_ros.diagnostics import ERROR, OK, WARN, Timings
from amb_ros.live_params import LiveParams, param_at_spec
from amb_ros.loop import Waiter
from amb_ros.node_base import RigNode, run_token, run_token_spec
from amb_ros.params import ParamSpec
from amb_ros.qos import data_qos, latched_qos
from amb_ros.runtime import exit_process, run_node

from .excitation import KINDS, Excitation
from .injection_hook import InjectionHook, injection_specs
from .realtime import on_realtime_sample, run_sample_triggered, run_timer_triggered


def specs() -> list[ParamSpec]:
    c = "controller."
    return [
        run_token_spec(),
        ParamSpec("proportional_gain", None, "kp", "A/m", 0.0, 1e12, config_key=c + "proportional_gain",
                  runtime=True),
        ParamSpec("derivative_gain", None, "kd", "A s/m", 0.0, 1e12, config_key=c + "derivative_gain",
                  runtime=True),
        ParamSpec("integral_gain", None, "kI", "A/(m s)", 0.0, 1e15, config_key=c + "integral_gain",
                  runtime=True),
        ParamSpec("derivative_filter_hz", None, "derivative filter corner; 0 = backward difference", "Hz", 0.0, 1e9,
                  config_key=c + "derivative_filter_hz", none_value=0.0),
        ParamSpec("current_limit", None, "output saturation; the integrator is clamped to it", "A", 0.0, 1e12,
                  config_key=c + "current_limit"),
        ParamSpec("delay_samples", None, "one-sample computation delay (0 or 1)", "samples", 0, 1,
                  config_key=c + "delay_samples"),
        ParamSpec("trigger", "sample", "realtime: compute on each sample's arrival (sample, as an ADC interrupt does) "
                  "or on the controller's own wall-clock ticks (timer: up to one sample of extra delay)",
                  choices=("sample", "timer")),
        ParamSpec("min_subscribers", 1, "lockstep: readers of /amb/current matched before the first answer (the "
                  "plant, a recorder): a reader still being discovered would miss the first currents", "", 0, 100),
        ParamSpec("sensor_timeout_s", 0.1, "no new sample for this long: zero current and ERROR (realtime)", "s",
                  1e-4, 3600.0),
        ParamSpec("fail_at_s", -1.0, "rehearse a controller failure: zero current from this time on (a drop onto "
                  "the touchdown bearings); < 0 = never", "s", -1.0, 1e9),
        ParamSpec("excitation_kind", "none", "current injected for identification", choices=KINDS, runtime=True),
        ParamSpec("excitation_amplitude", 0.0, "sine amplitude or noise standard deviation", "A", 0.0, 1e6,
                  runtime=True),
        ParamSpec("excitation_frequency_hz", 10.0, "sine frequency", "Hz", 0.0, 1e6, runtime=True),
        ParamSpec("excitation_channels", [0, 1, 2, 3], "channel indices that receive the excitation"),
        ParamSpec("excitation_seed", 0, "seed of the noise excitation", "", 0, 2**31 - 1),
        ParamSpec("safe_gains_on_unstable", False, "switch to the safe gain set when the stability monitor's latched "
                  "/stability/unstable becomes True (stays switched; off by default)", runtime=True),
        ParamSpec("safe_proportional_gain", 0.0, "kp of the safe gain set; 0 = the nominal kp", "A/m", 0.0, 1e12,
                  runtime=True),
        ParamSpec("safe_derivative_gain", 0.0, "kd of the safe gain set; 0 = twice the nominal kd (more damping)",
                  "A s/m", 0.0, 1e12, runtime=True),
        param_at_spec(),
        *injection_specs(),
    ]  # fmt: skip


# lockstep: the plant publishes sample k+1 only after the answer to k, so a sample further ahead than this is
# not a loss but a foreign stamp (counted and rejected); the first sample must lie in the first few seconds
SAMPLE_WINDOW = 64
GAIN_PARAMS = ("proportional_gain", "derivative_gain", "integral_gain", "safe_proportional_gain",
               "safe_derivative_gain")  # fmt: skip
FIRST_SAMPLE_WINDOW = 50_000
READER_WAIT_S = 5.0  # lockstep: the longest wait for the readers of /amb/current before the first answer


class ControllerNode(RigNode):
    def __init__(self, stop):
        super().__init__("amb_controller", stop, specs())
        p, cfg = self.p, self.cfg
        self.channels = channel_names(cfg.bearings.nodes)
        chans = list(p["excitation_channels"])
        if any(c < 0 or c >= len(self.channels) for c in chans):
            raise InputError(
                f"parameter 'excitation_channels' = {chans}: indices must be in 0..{len(self.channels) - 1}"
            )
        self.gain_set, self.safe_switch_t, self.unstable_sub = "nominal", None, None
        fail = p["fail_at_s"] if p["fail_at_s"] >= 0 else None
        # the core's controller (PID + bias offset, zero current from fail_at_s): the offline rig loop runs the same
        # realtime: the plant applies a command from the sample after the one it answers (controller.delay_samples,
        # as a DSP updates its DAC at the next tick), so the law answers at once; lockstep: the law delays
        law_cfg = cfg if self.mode == "lockstep" else replace(cfg, controller=replace(cfg.controller, delay_samples=0))
        self.rig_ctrl = RigController(law_cfg, AMBGains.from_config(cfg), self.Ts, p["current_limit"], fail)
        self.pid = self.rig_ctrl.law  # the PID, with its filters (or the user's state space: no PID gains)
        if self.pid.c is not None:
            self.pid.c = self.coefficients("nominal")  # the gains as given (parameters may override the config)
        self.excitation = Excitation(p["excitation_kind"], p["excitation_amplitude"], p["excitation_frequency_hz"],
                                     chans, len(self.channels), p["excitation_seed"])  # fmt: skip
        qos = data_qos(self.mode, p["qos_depth"])
        self.pub = self.create_publisher(JointState, m.CURRENT, qos)
        self.token = run_token(self)  # commands carry it; samples without it are not this run's
        self.codec = m.joint_state_codec(self.channels, ("effort",), self.token or "")
        self.decoder = m.joint_state_decoder(self.channels, ("position",), self.token)
        self.sub = self.create_subscription(JointState, m.DISPLACEMENT, self.on_sample, qos, raw=True)
        self.matches.watch(self.sub)  # a second publisher of samples is an intruder (amb_ros/matches.py)
        if p["safe_gains_on_unstable"]:
            self.listen_unstable()
        self.injection = InjectionHook(self)  # sensor-signal disturbance (ISO 14839-3), off by default
        self.waiter = Waiter(self, [self.sub])
        self.live = LiveParams(self, [s for s in specs() if s.runtime], self.retune, self.check_gains)
        for _, name, value in self.live.schedule:
            if reason := self.check_gains(dict(self.p, **{name: value})):
                raise InputError(f"parameter 'param_at': {reason}")
        self.answered = self.saturated = self.lost = self.restarts = self.repeated = 0
        self.out_of_window = 0  # lockstep samples stamped far ahead of the stream (rejected)
        self.sensor_losses = self.safe_ticks = self.nonfinite = 0
        self.max_current = 0.0
        self.last_k = -1
        self.latest: tuple[int, np.ndarray] | None = None  # realtime: (stamp ns, y)
        self.fresh = False
        self.last_sample_wall = None
        self.sensor_state = "waiting"
        self.compute = Timings()
        self.period_error = Timings()
        self.latency = Timings()
        self.missed = self.skipped = self.ticks = 0
        self.last_update_ns: int | None = None
        self.last_stamp: int | None = None
        self.t_wall0 = time.monotonic()

    def coefficients(self, gain_set: str) -> DiscretePIDCoefficients:
        """PID coefficients of the nominal or the safe gain set, from the current parameter values."""
        p = self.p
        gains = replace(AMBGains.from_config(self.cfg), kp=p["proportional_gain"], kd=p["derivative_gain"],
                        kI=p["integral_gain"])  # fmt: skip
        if gain_set == "safe":
            gains = replace(gains, kp=p["safe_proportional_gain"] or gains.kp,
                            kd=p["safe_derivative_gain"] or 2 * gains.kd)  # fmt: skip
        return DiscretePIDCoefficients.from_gains(gains, self.Ts)

    def check_gains(self, proposed: dict) -> str:
        """A user state-space controller has no PID gains to retune (reason, or '' when the change is fine)."""
        if self.pid.c is not None:
            return ""
        gains = [k for k in GAIN_PARAMS if proposed[k] != self.p[k]]
        if gains:
            return f"'{gains[0]}': the controller is controller.state_space, which has no PID gains"
        return ""

    def listen_unstable(self) -> None:
        # served by Waiter.serve() (every ~0.1 s wall): the switch is a safety action, not part of the lockstep
        if self.unstable_sub is None:
            self.unstable_sub = self.create_subscription(Bool, m.UNSTABLE, self.on_unstable, latched_qos())

    def retune(self, changed: dict) -> None:
        """Runtime parameter changes, applied before the sample they take effect at (amb_ros.live_params)."""
        ex, p = self.excitation, self.p
        ex.kind, ex.amplitude, ex.frequency_hz = (
            p["excitation_kind"],
            p["excitation_amplitude"],
            p["excitation_frequency_hz"],
        )
        if p["safe_gains_on_unstable"]:
            self.listen_unstable()
        if self.pid.c is not None:
            self.pid.c = self.coefficients(self.gain_set)  # the PID keeps its integrator and filter state

    def on_unstable(self, msg: Bool) -> None:
        """The monitor's verdict: switch once to the safe gains (the PID keeps its integrator and filter state)."""
        if msg.data and self.gain_set == "nominal" and self.p["safe_gains_on_unstable"] and self.pid.c is not None:
            self.pid.c = self.coefficients("safe")
            self.gain_set = "safe"
            self.safe_switch_t = self.last_k * self.Ts if self.last_k >= 0 else 0.0
            self.get_logger().warning(
                f"/stability/unstable: switched to the safe gains at t = {self.safe_switch_t:.6g} s"
            )

    def wait_for_readers(self) -> None:
        """Lockstep, before the first current: the plant waits for this answer, so waiting (bounded) costs no
        sample, while a reader matched after it would never get it (volatile)."""
        deadline = time.monotonic() + READER_WAIT_S
        while self.pub.get_subscription_count() < self.p["min_subscribers"] and not self.stop.is_set:
            if time.monotonic() > deadline:
                n, want = self.pub.get_subscription_count(), self.p["min_subscribers"]
                self.get_logger().warning(f"{m.CURRENT}: {n} reader(s) after {READER_WAIT_S:g} s, {want} expected")
                return
            time.sleep(0.002)

    # -- receive ------------------------------------------------------------------------------------
    def on_sample(self, raw: bytes) -> None:
        got = self.counters.decode(m.DISPLACEMENT, self.decoder, raw)
        if got is None:
            return
        t_ns, y = got
        self.last_sample_wall = time.monotonic()
        self.sensor_state = "ok"  # (again) receiving samples
        if self.mode == "realtime":
            self.latest, self.fresh = (t_ns, y.copy()), True
            if self.p["trigger"] == "sample":
                on_realtime_sample(self, t_ns, y)
            return
        if t_ns % self.Ts_ns:
            self.counters.reject(m.DISPLACEMENT, f"stamp {t_ns} ns is not on the {self.Ts_ns} ns sample grid")
            return
        k = t_ns // self.Ts_ns
        if k == 0 and self.last_k >= 0:  # the plant restarted
            self.restarts += 1
            self.pid.reset()
        elif k <= self.last_k:
            self.counters.reject(m.DISPLACEMENT, f"sample for step {k} after step {self.last_k} (duplicate)")
            return
        elif k > self.last_k + (SAMPLE_WINDOW if self.last_k >= 0 else FIRST_SAMPLE_WINDOW):
            # not this run's stream (a future stamp, a flood): taken as the newest it would wedge the loop
            self.out_of_window += 1
            self.counters.reject(m.DISPLACEMENT, f"sample for step {k} far ahead of step {self.last_k} (foreign?)")
            return
        elif k > self.last_k + 1:
            self.lost += k - self.last_k - 1
        self.last_k = k
        self.sensor_state = "ok"
        self.answer(t_ns, y, k * self.Ts)

    def answer(self, t_ns: int, y: np.ndarray, t: float) -> None:
        if self.answered == 0 and self.mode == "lockstep":
            self.wait_for_readers()
        t0 = time.perf_counter()
        if self.live.pending or self.live.schedule:
            self.live.at_sample(t_ns)
        y = self.injection.apply(t_ns, y, t)
        with np.errstate(over="ignore", invalid="ignore"):
            u = self.rig_ctrl.step(round(t / self.Ts), y)
        if self.excitation.active:
            u = np.clip(u + self.excitation(t), -self.p["current_limit"], self.p["current_limit"])
        if not np.isfinite(u).all():  # only with a limitless controller on a diverged plant: never publish it
            self.nonfinite += 1
            u = np.zeros_like(u)
        self.pub.publish(self.codec.encode(t_ns, u))
        self.compute.add(time.perf_counter() - t0)
        self.answered += 1
        self.saturated += bool(self.pid.saturated.any())
        self.max_current = max(self.max_current, float(np.max(np.abs(u))))

    def drain(self) -> None:
        while (raw := Waiter.take(self.sub)) is not None:
            self.on_sample(raw)

    # -- loops ----------------------------------------------------------------------------------------
    def run(self) -> int:
        if self.mode == "lockstep":
            while not self.stop.is_set:
                self.waiter.wait(1.0)
                self.drain()
                self.housekeeping()
        elif self.p["trigger"] == "sample":
            run_sample_triggered(self)
        else:
            run_timer_triggered(self)
        self.deliver_pending(self.pub, self.injection.pub)
        self.waiter.close()
        self.diag.publish_final(*self.status(), self.values())
        return 0

    def housekeeping(self) -> None:
        self.waiter.serve()
        if self.mode == "lockstep" and self.last_sample_wall is not None:
            if time.monotonic() - self.last_sample_wall > self.p["sensor_timeout_s"] and self.sensor_state == "ok":
                self.sensor_state = "paused"  # lockstep: the plant paused or finished; time does not run on
        if self.diag.due():
            self.diag.publish(*self.status(), self.values())

    def status(self) -> tuple[bytes, str]:
        if self.sensor_state == "lost":
            return ERROR, (f"no sensor samples for more than {self.p['sensor_timeout_s']:g} s: "
                           "zero current output, PID reset")  # fmt: skip
        if self.nonfinite:
            return ERROR, f"PID output not finite in {self.nonfinite} samples (zero current sent instead)"
        notes = []
        if self.sensor_losses:
            notes.append(f"sensor samples stopped {self.sensor_losses} time(s) ({self.safe_ticks} ticks at zero)")
        if self.lost:
            notes.append(f"{self.lost} samples lost")
        if self.missed:
            notes.append(f"{self.missed} missed deadlines")
        if self.saturated:
            notes.append(f"saturated in {self.saturated} samples")
        if self.counters.total_rejected:
            notes.append(f"{self.counters.total_rejected} rejected messages ({self.counters.last_rejection})")
        text = f"{self.sensor_state}: {self.answered} samples answered" + ("; " + "; ".join(notes) if notes else "")
        return (WARN if notes else OK), text

    def values(self) -> dict[str, str]:
        self.counters.published[m.CURRENT] = self.answered + self.safe_ticks  # before it is read: never stale
        out = self.common_values()
        out.update(
            {
                "sensor state": self.sensor_state,
                Controller.samples_answered.text: str(self.answered),
                Controller.samples_lost.text: str(self.lost),
                Controller.samples_out_of_window.text: str(self.out_of_window),
                "restarts": str(self.restarts),
                Controller.saturated_samples.text: str(self.saturated),
                Controller.max_current.text: f"{self.max_current:.6g}",
                "current limit (A)": f"{self.p['current_limit']:.6g}",
                "excitation": self.excitation.kind if self.excitation.active else "none",
                "gain set": self.gain_set,
                "safe gains from t (s)": "-" if self.safe_switch_t is None else f"{self.safe_switch_t:.6g}",
                Controller.sensor_losses.text: str(self.sensor_losses),
                "zero-current ticks": str(self.safe_ticks),
                "wall time (s)": f"{time.monotonic() - self.t_wall0:.3f}",
            }
        )
        out.update(self.live.values())
        out.update(self.injection.values())
        out.update(self.compute.summary("compute"))
        if self.mode == "realtime":
            out.update({"trigger": self.p["trigger"], Controller.ticks.text: str(self.ticks),
                        Controller.missed_deadlines.text: str(self.missed),
                        Controller.skipped_ticks.text: str(self.skipped),
                        "repeated samples": str(self.repeated)})  # fmt: skip
            out.update(self.period_error.summary("period error"))
            out.update(self.latency.summary("sample-to-command latency"))
        return out


def main(args: list[str] | None = None) -> None:
    exit_process(run_node("amb_controller", ControllerNode, args))
