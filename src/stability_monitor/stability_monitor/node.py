"""stability_monitor node: online Floquet multipliers of the running rig and a latched instability flag.

Topics (layouts in docs/monitor.md)
-----------------------------------
subscribes /amb_plant/state        trajectory_msgs/JointTrajectory: blocks of consecutive samples, joint_names =
                                   generalised coordinates, points[i] = (q, dq/dt) of one sample, stamp = header
                                   stamp + time_from_start (input:=state, the default; amb_ros.state_block)
subscribes /amb/displacement       sensor_msgs/JointState: name = AMB channels, position = y (m)
                                   (input:=displacement, sensor-only: what a real rig measures)
subscribes /base/imu               sensor_msgs/Imu: angular_velocity = Omega (rad/s); only to find the base
                                   period (period_s:=0, the default)
subscribes /amb/spin_speed         sensor_msgs/JointState: the tachometer, name [spin], position = spin angle
                                   (rad), velocity = speed (rad/s); only with synchronous harmonics (auto: the
                                   config has unbalance or runout)
publishes  /stability/multipliers  std_msgs/Float64MultiArray, layout dims [k, 2] ("multiplier", "re_im"):
                                   data = [re_0, im_0, re_1, im_1, ...], largest |mu| first, k <= publish_count;
                                   k = 0 when the data do not identify the map.  One message per refit.
publishes  /stability/unstable     std_msgs/Bool, RELIABLE + TRANSIENT_LOCAL depth 1 (latched): the verdict
                                   flag; False at start, republished on every change
publishes  /diagnostics            rho, its standard error and confidence, periods used, verdict, rank, period,
                                   the model value (model_check.py); level OK (stable), WARN (marginal,
                                   collecting, insufficient excitation, waiting for the period, model
                                   mismatch), ERROR (unstable)

Time is the stamp of the samples (t_k of the lockstep /clock, or of the replayed bag): the estimates depend on
the data only, never on wall time, so a replay gives the live run's output.  The monitor only reads the lockstep
topics (reliable, deep history), so it never holds up the loop; its cost per sample is in the diagnostics.
The numbers come from ``amb_dynamics.estimator`` through :mod:`stability_monitor.pipeline`.
"""

from __future__ import annotations

import time

from rclpy.qos import DurabilityPolicy, QoSProfile
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Bool, Float64MultiArray
from trajectory_msgs.msg import JointTrajectory

import amb_ros.messages as m
from amb_dynamics.errors import InputError
from amb_dynamics.estimator.fit import METHODS
from amb_ros.diag_keys import Monitor
from amb_ros.diagnostics import ERROR, OK, WARN, Timings
from amb_ros.live_params import LiveParams, param_at_spec
from amb_ros.loop import Waiter
from amb_ros.node_base import RigNode
from amb_ros.params import ParamSpec
from amb_ros.qos import consumer_qos, latched_qos, reliable_qos
from amb_ros.runtime import exit_process, run_node
from amb_ros.scheduling import PRIORITIES, consumer_priority

from .gaps import SampleGaps
from .messages import JointStateInput, StateBlockInput, multipliers_message
from .model_check import ModelValue
from .pipeline import FORCING_CHOICES, MonitorPipeline, MonitorSettings, synchronous_harmonics

MULTIPLIERS, UNSTABLE = m.MULTIPLIERS, m.UNSTABLE
INPUTS = ("state", "displacement")
D = MonitorSettings()  # the defaults, typed once (pipeline.py, from the estimator's)
MODEL_WAIT_S = 5.0  # at the end, for a model value still being computed (real rig ~3 s; amb-rig waits 8 s)


def multipliers_qos() -> QoSProfile:
    # every refit is a result: reliable, deep enough for a recorder, no history for late joiners
    return reliable_qos(100, DurabilityPolicy.VOLATILE)


def specs() -> list[ParamSpec]:
    return [
        ParamSpec("input", "state", "snapshots: full plant state, or the AMB displacements only", choices=INPUTS),
        ParamSpec("period_s", 0.0, "period of A(t); 0 = estimate the base period from /base/imu", "s", 0.0, 1e4),
        ParamSpec("forcing", "auto", "forcing model over periods; auto: none without the config's base_forcing, "
                  "else from /base/imu", choices=FORCING_CHOICES),
        ParamSpec("synchronous", -1, "spin harmonics of the synchronous response (unbalance, runout) removed with "
                  "the angle from /amb/spin_speed; -1 = auto: 1 when the config has unbalance or runout", "", -1, 8),
        ParamSpec("velocities", D.velocities, "input state: fit the velocities too (default: the positions only; the "
                  "phases of a period observe the velocities)"),
        ParamSpec("phases", D.phases, "phases sampled per period", "", 1, 4096),
        ParamSpec("window_periods", D.window, "periods in the moving window (moving base)", "", 3, 10000),
        ParamSpec("static_window_periods", D.static_window, "periods of static_period_s in the window (static base)",
                  "", 3, 10000),
        ParamSpec("updates_per_period", D.updates_per_period, "refits per period", "", 1, 4096),
        ParamSpec("method", D.method, "identification: LS refined by variable projection (opt), least squares (ls) or "
                  "total least squares (tls)", choices=METHODS),
        ParamSpec("max_rank", D.max_rank, "largest number of modes identified", "", 1, 1000),
        ParamSpec("noise_std", D.noise_std, "measurement noise std of every channel; negative = estimate from the data",
                  "signal units", -1.0, 1e9),
        ParamSpec("margin", D.margin, "flag when rho >= 1 + margin (and rho - z std > 1)", "", 0.0, 10.0,
                  runtime=True),
        ParamSpec("hysteresis", D.hysteresis, "clear when rho + z std < 1 + margin - hysteresis", "", 0.0, 10.0,
                  runtime=True),
        ParamSpec("confidence_z", D.z, "standard errors required on the right side of 1", "", 0.0, 100.0),
        ParamSpec("confirm", D.confirm, "consecutive refits needed to raise or clear the flag", "", 1, 1000),
        ParamSpec("publish_count", 8, "multipliers published per refit (largest first)", "", 0, 10000),
        ParamSpec("static_wait_s", D.static_wait, "no base rotation for this long: static base", "s", 0.0, 1e6),
        ParamSpec("static_period_s", D.static_period, "period used for a static base", "s", 1e-6, 1e6),
        ParamSpec("batch_s", 0.02, "sleep between drains: fewer wake-ups, less CPU taken from the loop (the "
                  "qos_depth-deep history holds the samples meanwhile, in realtime too)", "s", 0.0, 1.0),
        ParamSpec("priority", "idle", "scheduling of every thread, DDS's included: idle (SCHED_IDLE: only CPU time "
                  "the loop leaves; a refit never preempts it), low (niceness +5) or normal", choices=PRIORITIES),
        ParamSpec("model_check", True, "compare the estimate with the config's model value (its digital loop on its "
                  "base motion, computed in the background at start): WARN 'model mismatch' when they disagree"),
        param_at_spec(),
    ]  # fmt: skip


class MonitorNode(RigNode):
    def __init__(self, stop):
        super().__init__("stability_monitor", stop, specs())
        p = self.p
        self.input = p["input"]
        self.settings = MonitorSettings(
            sensor_only=self.input == "displacement",
            period=p["period_s"],
            forcing=p["forcing"],
            base_forcing=self.cfg.base_forcing,
            gravity=self.cfg.gravity.enabled,
            phases=p["phases"],
            window=p["window_periods"],
            static_window=p["static_window_periods"],
            updates_per_period=p["updates_per_period"],
            method=p["method"],
            max_rank=p["max_rank"],
            noise_std=p["noise_std"],
            margin=p["margin"],
            hysteresis=p["hysteresis"],
            z=p["confidence_z"],
            confirm=p["confirm"],
            static_wait=p["static_wait_s"],
            static_period=p["static_period_s"],
            synchronous=synchronous_harmonics(p["synchronous"], self.cfg),
            velocities=p["velocities"],
        )
        self.pipeline = MonitorPipeline(self.settings)  # scale groups set once the first sample names the channels
        if self.input == "displacement":
            self.topic, self.data_in, data_type = m.DISPLACEMENT, JointStateInput(("position",)), JointState
        else:
            self.topic, self.data_in, data_type = m.STATE, StateBlockInput(), JointTrajectory
        qos = consumer_qos(self.mode, p["qos_depth"])
        self.data_sub = self.create_subscription(data_type, self.topic, self.on_data, qos, raw=True)
        subs = [self.data_sub]
        self.imu_sub = None
        if self.settings.period == 0:
            self.imu_decoder = m.imu_decoder()
            self.imu_sub = self.create_subscription(Imu, m.IMU, self.on_imu, qos, raw=True)
            subs.append(self.imu_sub)
        self.spin_sub = None
        if self.settings.synchronous:
            self.spin_in = JointStateInput(("position", "velocity"))
            self.spin_sub = self.create_subscription(JointState, m.SPIN_SPEED, self.on_spin, qos, raw=True)
            subs.append(self.spin_sub)
        self.mult_pub = self.create_publisher(Float64MultiArray, MULTIPLIERS, multipliers_qos())
        self.flag_pub = self.create_publisher(Bool, UNSTABLE, latched_qos())
        self.waiter = Waiter(self, subs)
        self.flag = False
        self.flag_pub.publish(Bool(data=False))
        self.counters.published[UNSTABLE] = 1
        self.cost = Timings()
        self.gaps = SampleGaps(self.Ts_ns)  # samples missing from the stream (jitter-proof in realtime)
        self.error = ""
        self.live = LiveParams(self, [s for s in specs() if s.runtime], self.retune)
        self.model = ModelValue(self.cfg) if p["model_check"] else None

    def retune(self, changed: dict) -> None:
        """Runtime margin/hysteresis (amb_ros.live_params): from the sample at which the change applies."""
        self.pipeline.set_margins(self.p["margin"], self.p["hysteresis"])

    # -- receive ------------------------------------------------------------------------------------
    def on_imu(self, raw: bytes) -> None:
        got = self.counters.decode(m.IMU, self.imu_decoder, raw)
        if got is None:
            return
        t_ns, values = got
        self.publish(self.pipeline.on_imu(t_ns * 1e-9, values[4:7]))

    def on_spin(self, raw: bytes) -> None:
        got = self.counters.decode(m.SPIN_SPEED, self.spin_in, raw)
        if got is None:
            return
        t_ns, values = got
        if values.size != 2:
            self.counters.reject(m.SPIN_SPEED, f"{values.size // 2} tachometer channels, expected 1")
            return
        try:
            self.publish(self.pipeline.on_spin(t_ns * 1e-9, float(values[0]), float(values[1])))
        except InputError as exc:
            self.counters.reject(m.SPIN_SPEED, str(exc))

    def on_data(self, raw: bytes) -> None:
        got = self.counters.decode(self.topic, self.data_in.samples, raw)
        if got is None:
            return
        stamps, rows = got
        if self.pipeline.scale_groups is None:
            self.pipeline.scale_groups = self.data_in.scale_groups()
        for t_ns, values in zip(stamps.tolist(), rows, strict=True):
            t0 = time.perf_counter()
            if self.live.pending or self.live.schedule:
                self.live.at_sample(t_ns)
            try:
                estimates = self.pipeline.on_sample(t_ns * 1e-9, values)
            except InputError as exc:
                self.counters.reject(self.topic, str(exc))
                self.error = str(exc)
                return
            self.gaps.add(t_ns)
            self.publish(estimates)
            self.cost.add(time.perf_counter() - t0)

    def publish(self, estimates) -> None:
        # the flag follows each estimate, not the last of a batch (the buffered start refits many at once):
        # its sequence is then a function of the sample stream only, however the samples arrived
        for est in estimates:
            self.mult_pub.publish(multipliers_message(est.fit.multipliers if est.fit.excited else [],
                                                      self.p["publish_count"]))  # fmt: skip
            self.counters.published[MULTIPLIERS] += 1
            self.set_flag(bool(est.unstable))
        if self.pipeline.latest is None:
            self.set_flag(False)  # a restarted run has no verdict yet

    def set_flag(self, unstable: bool) -> None:
        if unstable != self.flag:
            self.flag = unstable
            self.flag_pub.publish(Bool(data=unstable))
            self.counters.published[UNSTABLE] += 1

    def drain(self) -> None:
        for sub, handler in ((self.imu_sub, self.on_imu), (self.spin_sub, self.on_spin), (self.data_sub, self.on_data)):
            if sub is None:
                continue
            while (raw := Waiter.take(sub)) is not None:
                handler(raw)

    # -- loop -----------------------------------------------------------------------------------------
    def run(self) -> int:
        self.scheduling = consumer_priority(self.p["priority"])
        if self.model is not None:  # after the scheduling: the thread inherits it
            self.model.start()
        batch = self.p["batch_s"]
        while not self.stop.is_set:
            self.waiter.wait(1.0)
            self.drain()
            if batch:
                time.sleep(batch)
            self.waiter.serve()
            if self.diag.due():
                self.diag.publish(*self.status(), self.values())
        self.drain()
        self.waiter.close()
        if self.model is not None:  # the final report always carries the model value (live and replayed alike)
            self.model.wait(MODEL_WAIT_S)
        level, message = self.status()
        self.diag.publish_final(level, message, self.values())
        pl = self.pipeline
        lost = self.gaps.lost
        print(f"stability_monitor: {pl.samples} samples ({lost} lost), {pl.refits} refits; {message}", flush=True)
        return 0

    def status(self) -> tuple[bytes, str]:
        pl = self.pipeline
        if self.error:
            return ERROR, f"input rejected: {self.error}"
        if pl.samples == 0:
            return WARN, f"waiting for {self.topic}"
        est = pl.latest
        if pl.estimator is None and pl.waiting_for_tach and not pl.tach_samples:
            return WARN, f"waiting for the tachometer ({m.SPIN_SPEED}): {pl.waiting_for_tach} samples held"
        if pl.estimator is None:
            note = f" ({pl.note})" if pl.note else ""
            return WARN, f"{pl.state}: {pl.imu_samples} base-rate and {pl.samples} data samples{note}"
        if est is None:
            return WARN, "collecting the first periods"
        if est.unstable:
            std = self.rho_uncertainty()
            return ERROR, f"UNSTABLE: rho = {est.rho:.4f} +- {std:.2g} (flag raised at t = {pl.flag_time:.4f} s)"
        if not est.fit.excited:
            return WARN, f"{est.verdict.replace('_', ' ')}: {est.fit.reason}"
        level = OK if est.verdict == "stable" else WARN
        text = f"{est.verdict}: rho = {est.rho:.4f} +- {self.rho_uncertainty():.2g} over {est.periods} periods"
        if mismatch := self.mismatch():
            return WARN, f"{text}; {mismatch}"
        return level, text

    def mismatch(self) -> str | None:
        """The model check of the latest converged estimate (a full window of periods), if it disagrees."""
        pl, est = self.pipeline, self.pipeline.latest
        if self.model is None or est is None or not est.fit.excited or pl.period_estimate is None:
            return None
        if est.periods < pl.estimator.cfg.window:  # the static base's window or the moving base's
            return None
        return self.model.mismatch(est.rho, self.rho_uncertainty(), pl.period_estimate.period)

    def rho_uncertainty(self) -> float:
        """The larger of the latest fit's standard error and the scatter of the last window's refits."""
        return max(self.pipeline.latest.fit.rho_std, self.pipeline.rho_scatter())

    def values(self) -> dict[str, str]:
        out = self.common_values()
        pl = self.pipeline
        out.update(
            {
                "input": self.input,
                Monitor.unstable.text: str(self.flag).lower(),
                Monitor.samples_lost.text: str(self.gaps.lost),
            }
        )
        if pl.samples:
            out.update({"samples": str(pl.samples), "refits": str(pl.refits), "restarts": str(pl.restarts),
                        "state": pl.state, "forcing": pl.forcing,
                        "synchronous harmonics": str(self.settings.synchronous)})  # fmt: skip
            if pl.period_estimate is not None:
                out[Monitor.period.text] = f"{pl.period_estimate.period:.9g}"
                out["base period (s)"] = f"{pl.period_estimate.base_period:.9g}"
            if pl.flag_time is not None:
                out[Monitor.flag_raised_at.text] = f"{pl.flag_time:.6g}"
            est = pl.latest
            if est is not None:
                f = est.fit
                out.update({Monitor.verdict.text: est.verdict, Monitor.periods_used.text: str(est.periods),
                            "rank": str(f.rank),
                            "signal rank": str(f.signal_rank), "snr": f"{f.snr:.3g}",
                            "confidence": f"{est.confidence:.4f}", "estimate time (s)": f"{est.time:.6g}"})  # fmt: skip
                if f.excited:
                    out[Monitor.rho.text] = f"{f.rho:.6f}"
                    out[Monitor.rho_std.text] = f"{f.rho_std:.3g}"
                if len(pl.recent) >= 2:
                    out[Monitor.rho_scatter.text] = f"{pl.rho_scatter():.3g}"
        if self.model is not None:
            out.update(self.model.values())
            if pl.period_estimate is not None and (rho := self.model.per(pl.period_estimate.period)) is not None:
                out[Monitor.model_rho.text] = f"{rho:.6f}"  # per the estimate's period
                out[Monitor.model_mismatch.text] = str(self.mismatch() is not None).lower()
        out.update(self.live.values())
        out.update(self.cost.summary("cost per sample"))
        return out


def main(args: list[str] | None = None) -> None:
    exit_process(run_node("stability_monitor", MonitorNode, args))
