"""amb_plant node: the flexible rotor on its AMBs, stepped with the core's exact sampled-data propagator.

Topics (layouts in docs/topics.md)
----------------------------------
publishes  /clock (lockstep)            rosgraph_msgs/Clock, t_k = k Ts every clock_every steps (default 5: a 1 kHz
                                        clock at 5 kHz) and at the last step: the plant is the clock master
publishes  /amb/displacement            sensor_msgs/JointState: name = channels, position = measured y (m)
publishes  /amb_plant/state             trajectory_msgs/JointTrajectory: every sample, state_block (25) per
                                        message: joint_names = generalised coordinates (modes when modal_cutoff is
                                        set, FE DOFs n<i>_v... otherwise), points[i] = (q, dq/dt) of one sample,
                                        time_from_start = its stamp - header stamp (amb_ros.state_block)
publishes  /diagnostics                 steps, rates, peak displacement vs air gap, saturation, command
                                        timeouts, counts published/received/rejected
subscribes /amb/current                 sensor_msgs/JointState: effort = coil current (A), stamp = the sample
subscribes /base/rates (lockstep)       trajectory_msgs/JointTrajectory blocks: Omega, dOmega of every step
subscribes /base/imu, /base/angular_acceleration (realtime)   the latest base rates Omega, dOmega

Lockstep: at step k publish y_k, /clock and (every state_block steps) the state (stamp t_k), wait for the base
sample k and the command stamped t_k (waiting on the command alone once the base sample is in), then
x_{k+1} = E_k x_k + Gamma_k i_k + g_k (``PlantStepper``) - exactly ``SampledLoop.simulate``.  The matrices of step
k are computed while the controller works on y_k.  No command within command_timeout_s (controller gone): ERROR
diagnostic, exit code 3.  Realtime: wall-clock ticks, latest command and base sample, sensor model and the
command policy of :mod:`amb_plant.sensor`.
"""

from __future__ import annotations

import sys
import time

import numpy as np
from geometry_msgs.msg import Vector3Stamped
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import String
from trajectory_msgs.msg import JointTrajectory

import amb_ros.messages as m
from amb_dynamics.fe import dof_index
from amb_dynamics.rig_loop import levitated_state
from amb_dynamics.rig_plant import RigPlant
from amb_dynamics.structure import build_structure
from amb_ros.diag_keys import Plant
from amb_ros.diagnostics import ERROR, OK, WARN, Timings
from amb_ros.loop import Waiter
from amb_ros.node_base import RigNode, run_token, run_token_spec
from amb_ros.params import ParamSpec
from amb_ros.qos import data_qos, latched_qos
from amb_ros.run_config import config_json
from amb_ros.runtime import RunFailed, exit_process, run_node
from amb_ros.state_block import StateBlockDecoder, StateBlockWriter

from .loops import run_lockstep, run_realtime, wait_connected
from .report import DisplacementReport, contact_json, contact_summary
from .sensor import CommandPolicy, SensorModel

SAMPLE_MEMORY = 4096  # realtime: published samples whose stamp a command may still answer
RATES_BLOCK = 25  # base_motion's default rates_block: the decoder's fast path (other block sizes are decoded too)


def specs() -> list[ParamSpec]:
    return [
        run_token_spec(),
        ParamSpec("duration_s", 0.0, "run length (simulated in lockstep, wall in realtime); 0 = until stopped", "s",
                  0.0, 1e6),
        ParamSpec("current_limit", None, "amplifier saturation", "A", 0.0, 1e12, config_key="controller.current_limit"),
        ParamSpec("noise_std", 0.0, "sensor noise standard deviation", "m", 0.0, 1.0),
        ParamSpec("quantization", 0.0, "sensor quantization step; 0 = none", "m", 0.0, 1.0),
        ParamSpec("sensor_delay_samples", 0, "sensor delay", "samples", 0, 1000),
        ParamSpec("noise_seed", 0, "seed of the sensor noise", "", 0, 2**31 - 1),
        ParamSpec("command_timeout_s", 10.0, "lockstep: wall time to wait for a command before failing (longer than"
                  " the ~3 s a stalled DDS reader can hold the loop up)", "s",
                  0.01, 3600.0),
        ParamSpec("delay_samples", None, "realtime: the loop's computation delay; a command acts from the sample "
                  "after the one it answers (lockstep: the controller delays)", "samples", 0, 1,
                  config_key="controller.delay_samples"),
        ParamSpec("start_samples", 20, "realtime: consecutive on-time commands before levitation starts (the "
                  "plant holds its start state until the loop keeps up)", "samples", 1, 1000000),
        ParamSpec("hold_samples", 10, "realtime: samples a stale command is held before zero current", "samples",
                  0, 1000000),
        ParamSpec("start_timeout_s", 30.0, "wall time to wait for controller and base motion to connect", "s",
                  0.1, 3600.0),
        ParamSpec("min_subscribers", 1, "readers of /amb/displacement required before starting", "", 1, 100),
        ParamSpec("min_state_subscribers", 0, "readers of /amb_plant/state required before starting (amb-rig: "
                  "recorder and monitor)", "", 0, 100),
        ParamSpec("initial_displacement", 0.0, "initial lateral (v) displacement of the disk node", "m", -1.0, 1.0),
        ParamSpec("max_displacement_ratio", 100.0, "stop the run when |y| exceeds this many air gaps (the linear "
                  "model means nothing there)", "", 1.0, 1e12),
        ParamSpec("clock_every", 5, "lockstep: publish /clock every N steps (5 at 5 kHz = a 1 kHz clock; base_motion"
                  " runs lead_samples ahead of it)", "steps", 1, 10000),
        ParamSpec("spin_every", 25, "publish /amb/spin_speed (the tachometer) every N steps", "steps", 1, 100000),
        ParamSpec("state_block", 25, "samples per /amb_plant/state message (every sample is published; a block "
                  "costs the loop one DDS delivery per reader instead of one per sample)", "samples", 1, 200),
    ]  # fmt: skip


class PlantNode(RigNode):
    def __init__(self, stop):
        super().__init__("amb_plant", stop, specs())
        p, cfg = self.p, self.cfg
        self.model = build_structure(cfg)
        self.limit = p["current_limit"]
        self.rig = RigPlant(self.model, cfg, self.Ts, current_limit=self.limit)  # the core's one stepping code
        self.rig.warm_up()  # the moving base's step interpolant, before the loop's first step needs it
        self.stepper = self.rig.lin
        self.channels = self.model.channels
        self.air_gap = cfg.bearings.air_gap
        # with backup bearings the rotor lands on them and the run goes on; without, it stops at the gap multiple
        self.max_y = np.inf if cfg.touchdown.nodes else p["max_displacement_ratio"] * self.air_gap
        self.sensor = SensorModel(p["noise_std"], p["quantization"], p["sensor_delay_samples"], p["noise_seed"])
        self.policy = CommandPolicy(len(self.channels), p["hold_samples"], p["delay_samples"], p["start_samples"])
        self.x = self.initial_state(p["initial_displacement"])
        self.steps = 0
        self.report = DisplacementReport(self.channels, cfg, self.Ts)
        self.peak = self.report.peak
        self.saturated = 0
        self.max_current = 0.0
        self.failure = ""
        self.finished = False
        self.round_trip = Timings()
        self.sample_round_trip = Timings()  # realtime: sample published -> its command back, this plant's clock
        self.period_error = Timings()
        self.missed = 0
        self.skipped = 0
        self.t_wall0 = self.t_wall1 = None
        self.connect_s = 0.0
        self.start_wait_s = 0.0  # lockstep: wait for step 0's base sample and command (peers still starting)
        qos = data_qos(self.mode, p["qos_depth"])
        self.disp_pub = self.create_publisher(JointState, m.DISPLACEMENT, qos)
        self.state_pub = self.create_publisher(JointTrajectory, m.STATE, qos)
        self.clock_pub = self.create_publisher(Clock, m.CLOCK, qos) if self.mode == "lockstep" else None
        self.token = run_token(self)  # samples carry it; commands without it are not this run's
        self.disp_codec = m.joint_state_codec(self.channels, ("position",), self.token or "")
        self.state_block = StateBlockWriter(self.model.dof_names, p["state_block"])
        # actuator and filter states, spin angle: /amb_plant/aux_state (same block layout), /amb/spin_speed
        self.aux_names = (*self.rig.labels[2 * self.model.n :], "spin")
        self.aux_block = StateBlockWriter(self.aux_names, p["state_block"])
        self.aux_row = np.zeros(2 * len(self.aux_names))
        self.aux_pub = self.create_publisher(JointTrajectory, m.AUX_STATE, qos)
        self.spin_pub = self.create_publisher(JointState, m.SPIN_SPEED, qos)
        self.spin_codec = m.joint_state_codec(("spin",), ("position", "velocity"))
        self.spin_every = p["spin_every"]
        self.contact_pub = self.create_publisher(String, m.TOUCHDOWN, latched_qos())
        self.contacts_sent = 0
        # the effective config, latched: a recorder (any, ros2 bag's too) keeps it with the run's data
        self.create_publisher(String, m.RUN_CONFIG, latched_qos()).publish(String(data=config_json(cfg)))
        self.clock_codec = m.clock_codec()
        self.cmd_decoder = m.joint_state_decoder(self.channels, ("effort",), self.token)
        self.cmd_sub = self.create_subscription(JointState, m.CURRENT, self.on_command, qos, raw=True)
        self.matches.watch(self.cmd_sub)  # a second publisher of commands is an intruder (amb_ros/matches.py)
        self.handlers = [(self.cmd_sub, self.on_command)]
        if self.mode == "lockstep":  # every base sample, in blocks
            self.rates_decoder = StateBlockDecoder(m.BASE_RATE_NAMES, RATES_BLOCK)
            rates_sub = self.create_subscription(JointTrajectory, m.BASE_RATES, self.on_rates, qos, raw=True)
            self.handlers.append((rates_sub, self.on_rates))
        else:  # the latest sample of the base's sensors
            self.imu_decoder, self.acc_decoder = m.imu_decoder(), m.vector3_decoder()
            imu_sub = self.create_subscription(Imu, m.IMU, self.on_imu, qos, raw=True)
            acc_sub = self.create_subscription(Vector3Stamped, m.ANGULAR_ACCELERATION, self.on_acc, qos, raw=True)
            self.handlers += [(imu_sub, self.on_imu), (acc_sub, self.on_acc)]
        self.waiter = Waiter(self, [sub for sub, _ in self.handlers])
        # received data: lockstep keeps samples by step index, realtime only the latest
        self.commands: dict[int, np.ndarray] = {}
        self.duplicates = 0  # lockstep: second commands for one step (rejected; the run cannot be trusted)
        self.closed = False  # the loop has ended: what still arrives is counted, never applied
        self.after_end = 0  # well-formed commands taken after the loop ended (counted by the final drain)
        self.rates: dict[int, np.ndarray] = {}  # lockstep: step -> [Omega, dOmega]
        self.latest_rates = (np.zeros(3), np.zeros(3))
        self.imu_at_ns: int | None = None  # realtime: when the latest Omega arrived (time.monotonic_ns)
        self.sample_at_ns = 0  # realtime: when the last sample went out, the start of the next step (same clock)
        self.k_now = 0  # lockstep: the step being computed; realtime: the current tick
        self.sample_index: dict[int, int] = {}  # realtime: stamp of a published sample -> its index
        self.samples_out = 0  # realtime: samples published (a command's age counts them, not wall-clock ticks)

    def initial_state(self, disk_v: float) -> np.ndarray:
        n = self.model.n
        x = levitated_state(self.rig, self.cfg)  # at rest on the controller under gravity (zero without)
        if disk_v:
            fe = self.model.fe
            q_fe = np.zeros(fe.n)
            disk_node = self.cfg.disks[0].node if self.cfg.disks else self.cfg.n_nodes
            q_fe[dof_index(disk_node, 0)] = disk_v  # DOF 0 = v (lateral y)
            x[:n] += self.model.from_fe(q_fe)
        return x

    # -- receive handlers (called from the loops and from executor callbacks) -------------------------
    def _grid_steps(self, topic: str, stamps: np.ndarray) -> np.ndarray | None:
        """Lockstep step indices of ``stamps`` (ns); None (the message rejected) if one is off the sample grid."""
        off = stamps % self.Ts_ns
        if np.any(off):
            bad = int(np.ravel(stamps)[np.argmax(np.ravel(off) != 0)])
            self.counters.reject(topic, f"stamp {bad} ns is not on the {self.Ts_ns} ns sample grid")
            return None
        return stamps // self.Ts_ns

    def on_command(self, raw: bytes) -> None:
        got = self.counters.decode(m.CURRENT, self.cmd_decoder, raw)
        if got is None:
            return
        t_ns, current = got
        if self.closed:
            self.after_end += 1
            return
        if self.mode == "realtime":
            answered = self.sample_index.get(t_ns)
            if answered is None:
                self.counters.reject(m.CURRENT, "command answers no sample of this plant (or one too old)")
            else:
                self.policy.command(current.copy(), answered)
                self.sample_round_trip.add((self.get_clock().now().nanoseconds - t_ns) * 1e-9)
            return
        k = self._grid_steps(m.CURRENT, t_ns)
        if k is None:
            return
        if k == self.k_now and not self.finished and k in self.commands:  # never "the last one wins"
            self.duplicates += 1
            self.counters.reject(m.CURRENT, f"duplicate command for step {k} (a second publisher?); first one kept")
        elif k == self.k_now and not self.finished:
            self.commands[k] = current.copy()
        else:
            self.counters.reject(m.CURRENT, f"command for step {k} while at step {self.k_now}")

    def on_rates(self, raw: bytes) -> None:
        """Lockstep: a block of base samples [Omega, dOmega], kept by step until the plant gets there."""
        got = self.counters.decode(m.BASE_RATES, self.rates_decoder, raw)
        if got is None:
            return
        stamps, rows = got
        steps = self._grid_steps(m.BASE_RATES, stamps)
        if steps is None:
            return
        if steps[0] < self.k_now:
            self.counters.reject(m.BASE_RATES, f"block from step {steps[0]} arrived after step {self.k_now} began")
            return
        self.rates.update(zip(steps.tolist(), rows, strict=True))

    def on_imu(self, raw: bytes) -> None:
        """Realtime: the latest Omega."""
        got = self.counters.decode(m.IMU, self.imu_decoder, raw)
        if got is not None:
            self.latest_rates = (got[1][4:7].copy(), self.latest_rates[1])
            self.imu_at_ns = time.monotonic_ns()  # this host's clock: another host's stamps may be offset

    def on_acc(self, raw: bytes) -> None:
        """Realtime: the latest dOmega/dt."""
        got = self.counters.decode(m.ANGULAR_ACCELERATION, self.acc_decoder, raw)
        if got is not None:
            self.latest_rates = (self.latest_rates[0], got[1].copy())

    def drain(self, limit: int | None = None) -> None:
        """Take and handle every queued message (at most ``limit`` per subscription: a publisher that keeps
        sending cannot hold the final drain forever)."""
        for sub, handler in self.handlers:
            n = 0
            while (limit is None or n < limit) and (raw := Waiter.take(sub)) is not None:
                handler(raw)
                n += 1

    # -- physics glue ----------------------------------------------------------------------------------
    def publish_outputs(self, k: int, stamp_ns: int) -> None:
        y = self.rig.displacement(self.x)
        self.report.add(y)
        if self.peak.max() > self.max_y:
            j = int(np.argmax(self.peak))
            raise RunFailed(
                f"rotor left the bearing: |{self.channels[j]}| = {self.peak[j]:.3g} m = "
                f"{self.peak[j] / self.air_gap:.3g} x air gap at t = {k * self.Ts:.6g} s (max_displacement_ratio)"
            )
        self.disp_pub.publish(self.disp_codec.encode(stamp_ns, self.sensor.measure(self.rig.measure(self.x))))
        if self.mode == "realtime":
            self.sample_index[stamp_ns] = self.samples_out
            self.sample_at_ns = time.monotonic_ns()
            self.samples_out += 1
            self.sample_index.pop(stamp_ns - SAMPLE_MEMORY * self.Ts_ns, None)  # bounded memory (approximately)
            if len(self.sample_index) > 2 * SAMPLE_MEMORY:
                self.sample_index = dict(list(self.sample_index.items())[-SAMPLE_MEMORY:])
        self.counters.published[m.DISPLACEMENT] += 1
        n2 = 2 * self.model.n
        self.publish_state(self.state_block.add(stamp_ns, self.x[:n2]))
        na = len(self.aux_names)
        self.aux_row[: na - 1] = self.x[n2:]
        self.aux_row[na - 1] = self.rig.phi
        self.aux_row[-1] = self.rig.spin_speed()
        self.publish_aux(self.aux_block.add(stamp_ns, self.aux_row))
        if k % self.spin_every == 0:
            self.spin_pub.publish(self.spin_codec.encode(stamp_ns, np.array([self.rig.phi, self.rig.spin_speed()])))
            self.counters.published[m.SPIN_SPEED] += 1
        if len(self.rig.contact.events) > self.contacts_sent:
            self.publish_contacts()

    def publish_state(self, block: bytes | None) -> None:
        if block is not None:
            self.state_pub.publish(block)
            self.counters.published[m.STATE] += 1

    def publish_aux(self, block: bytes | None) -> None:
        if block is not None:
            self.aux_pub.publish(block)
            self.counters.published[m.AUX_STATE] += 1

    def publish_contacts(self) -> None:
        """Each new touchdown contact, as it begins: one JSON line on /amb_plant/touchdown."""
        for ev in self.rig.contact.events[self.contacts_sent :]:
            self.contact_pub.publish(String(data=contact_json(ev)))
            self.counters.published[m.TOUCHDOWN] += 1
        self.contacts_sent = len(self.rig.contact.events)

    def advance(self, rates: np.ndarray, current: np.ndarray) -> None:
        """x_{k+1} = RigPlant.step(x_k, i_k, rates of sample k): the clamp, the effects and the ZOH (core)."""
        self.x = self.rig.step(self.x, current, rates[:3], rates[3:])
        self.saturated, self.max_current = self.rig.saturated, self.rig.max_command
        self.steps += 1
        if not np.isfinite(self.x).all():
            raise RunFailed(f"plant state is no longer finite at step {self.steps} (t = {self.steps * self.Ts:.6g} s)")

    # -- run and report ---------------------------------------------------------------------------------
    def run(self) -> int:
        code = 0
        try:
            wait_connected(self)
            if not self.stop.is_set:
                self.t_wall0 = time.monotonic()
                (run_lockstep if self.mode == "lockstep" else run_realtime)(self)
        except RunFailed as exc:
            self.failure, code = str(exc), 3
        self.t_wall1 = time.monotonic()
        self.closed = True
        # what is still queued is counted (a foreign burst, the answer to the last sample), never applied
        self.drain(limit=2 * self.p["qos_depth"])
        self.publish_state(self.state_block.flush())  # the samples of the last, shorter block
        self.publish_aux(self.aux_block.flush())
        self.publish_contacts()
        self.deliver_pending(self.disp_pub, self.state_pub, self.clock_pub, self.aux_pub, self.contact_pub)
        self.waiter.close()
        level, message = self.status()
        self.diag.publish_final(level, message, self.values())
        if code:
            print(f"amb_plant: {self.failure}", file=sys.stderr)
        else:
            v = self.values()
            print(f"amb_plant: {v['state']}: {self.steps} steps, {v['wall time (s)']} s wall, {v['steps per second']} "
                  "steps/s", flush=True)  # fmt: skip
        return code

    def status(self) -> tuple[bytes, str]:
        ratio = float(self.peak.max()) / self.air_gap
        if self.failure:
            return ERROR, self.failure
        if self.policy.state == "zeroed":  # commands have stopped (and not come back)
            return ERROR, (f"commands stopped {self.policy.losses} time(s): held {self.p['hold_samples']} samples, "
                           f"then zero current for {self.policy.zeroed} samples")  # fmt: skip
        notes = []
        if self.policy.losses:
            notes.append(f"commands stopped {self.policy.losses} time(s) and came back ({self.policy.zeroed} samples "
                         "at zero current)")  # fmt: skip
        if self.policy.held:
            notes.append(f"stale command held for {self.policy.held} samples")
        if ratio > 1.0:
            notes.append(f"peak displacement {ratio:.3g} x air gap (linear model beyond the gap)")
        if self.saturated:
            notes.append(f"current saturated in {self.saturated} steps")
        if self.counters.total_rejected:
            notes.append(f"{self.counters.total_rejected} rejected messages ({self.counters.last_rejection})")
        state = "finished" if self.finished else "running"
        text = f"{state}: {self.steps} steps" + ("; " + "; ".join(notes) if notes else "")
        return (WARN if notes else OK), text

    def values(self) -> dict[str, str]:
        wall = (self.t_wall1 or time.monotonic()) - self.t_wall0 if self.t_wall0 else 0.0
        out = self.common_values()
        out.update(
            {
                "state": "failed" if self.failure else ("finished" if self.finished else "running"),
                Plant.steps.text: str(self.steps),
                Plant.simulated_time.text: f"{self.steps * self.Ts:.9g}",
                Plant.wall_time.text: f"{wall:.4f}",
                Plant.steps_per_second.text: f"{self.steps / wall:.1f}" if wall > 0 else "0",
                "connect time (s)": f"{self.connect_s:.3f}",
                "generalised coordinates": str(self.model.n),
                Plant.air_gap.text: f"{self.air_gap:.6g}",
                "current limit (A)": f"{self.limit:.6g}",
                Plant.saturated_steps.text: str(self.saturated),
                "max command (A)": f"{self.max_current:.6g}",
                "failure": self.failure,
            }
        )
        out.update(contact_summary(self.rig.contact.events))
        out["commands after the end"] = str(self.after_end)
        out["spin speed (rpm)"] = f"{self.rig.spin_speed() * 30 / np.pi:.6g}"
        out.update(self.report.values())
        if self.mode == "lockstep":
            out[Plant.duplicate_commands.text] = str(self.duplicates)
            out["start wait (s)"] = f"{self.start_wait_s:.3f}"
            out.update(self.round_trip.summary("command wait"))
        else:
            pol = self.policy
            out.update({Plant.late_commands_held.text: str(pol.held), Plant.zero_current.text: str(pol.zeroed),
                        Plant.command_losses.text: str(pol.losses), "command state": pol.state,
                        "missed deadlines": str(self.missed), "skipped ticks": str(self.skipped),
                        "ticks before levitation": str(pol.waiting),
                        Plant.command_deadline.text: f"{(pol.delay + 1) * self.Ts * 1e6:.1f}"})  # fmt: skip
            out.update(self.period_error.summary("period error"))
            out["samples answered"] = str(self.sample_round_trip.count)
            out.update(self.sample_round_trip.summary("round trip"))
        return out


def main(args: list[str] | None = None) -> None:
    exit_process(run_node("amb_plant", PlantNode, args))
