"""base_motion node: publishes the moving base's attitude, angular velocity and angular acceleration.

Topics (layouts in docs/topics.md)
----------------------------------
publishes  /base/rates (lockstep)       trajectory_msgs/JointTrajectory: every sample, rates_block (25) per message:
                                        joint_names = omega_x, omega_y, omega_z, points[i].positions = Omega,
                                        velocities = dOmega/dt (base axes) - the plant's input (amb_ros.state_block)
publishes  /base/imu                    sensor_msgs/Imu: orientation = base->inertial quaternion (x, y, z, w),
                                        angular_velocity = Omega in base axes (rad/s); stamp = t_k; lockstep: every
                                        imu_every samples (default 5: 1 kHz at 5 kHz), realtime as well (the
                                        IMU's own rate; the plant holds the rates to first order in between)
publishes  /base/angular_acceleration   geometry_msgs/Vector3Stamped: dOmega/dt in base axes (rad/s^2), as /base/imu
publishes  /diagnostics                 samples published, clock messages received/rejected, lead
subscribes /clock (lockstep)            rosgraph_msgs/Clock from the plant

Lockstep: the plant publishes /clock = t_k at step k; this node answers with the samples up to k + lead_samples
(it does not depend on the plant, so it runs ahead by a bounded credit window and is off the plant's critical
path), in whole blocks of /base/rates.  A /clock that goes backwards restarts the sequence there.
Every base sample reaches the plant in blocks rather than as an Imu + Vector3Stamped pair per step: each reader
of a per-step topic (the plant, a recorder) costs the lockstep loop a DDS delivery per message (``make bench``).
Realtime: samples on a wall-clock ticker at rate_hz / imu_every, t measured from the node's start, stamped with
wall time; the plant takes /base/imu and /base/angular_acceleration and extrapolates Omega with dOmega/dt to each
step (a rig's IMU samples slower than its loop: at every tick this node cost a third of a core at 2 kHz).

Profiles: none, roll, pitch, yaw (beta = A sin(w t)), combined (harmonics of the config's base_motion),
recorded (CSV file, see amb_dynamics.recorded).
"""

from __future__ import annotations

import time

import numpy as np
from geometry_msgs.msg import Vector3Stamped
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu
from trajectory_msgs.msg import JointTrajectory

import amb_ros.messages as m
from amb_dynamics.errors import InputError
from amb_dynamics.motion import BaseMotion
from amb_dynamics.recorded import load_recorded
from amb_ros.diagnostics import OK, WARN
from amb_ros.loop import Ticker, Waiter
from amb_ros.node_base import RigNode
from amb_ros.params import ParamSpec
from amb_ros.qos import data_qos
from amb_ros.runtime import exit_process, run_node
from amb_ros.state_block import StateBlockWriter

from .samples import SampleSource

KINDS = ("none", "roll", "pitch", "yaw", "combined", "recorded")


def specs() -> list[ParamSpec]:
    return [
        ParamSpec("kind", "", "base motion profile; empty = the config's base_motion.kind", choices=("", *KINDS)),
        ParamSpec("amplitude", None, "amplitude A of beta = A sin(w t)", "rad", 0.0, 1.5,
                  config_key="base_motion.amplitude"),
        ParamSpec("frequency", None, "angular frequency w", "rad/s", 0.0, 1.0e4, config_key="base_motion.frequency"),
        ParamSpec("recorded_file", "", "CSV with columns t, roll, pitch, yaw (kind recorded)"),
        ParamSpec("recorded_smoothing", 0.0, "smoothing-spline lambda for recorded; 0 = automatic (GCV)", lo=0.0),
        ParamSpec("rates_block", 25, "lockstep: samples per /base/rates message (every sample is published)",
                  "samples", 1, 200),
        ParamSpec("imu_every", 5, "publish /base/imu and /base/angular_acceleration every N samples (lockstep: the "
                  "plant takes /base/rates; realtime: the IMU's rate, rate_hz / N, 5 at 2 kHz = 400 Hz)", "samples",
                  1, 10000),
        ParamSpec("min_rates_subscribers", 1, "lockstep: readers of /base/rates required before the first sample "
                  "(amb-rig: plant, recorder), so that every reader gets every sample", "", 0, 100),
        ParamSpec("min_imu_subscribers", 0, "lockstep: readers of /base/imu required before the first sample "
                  "(amb-rig: recorder, monitor)", "", 0, 100),
        ParamSpec("min_acceleration_subscribers", 0, "lockstep: readers of /base/angular_acceleration required "
                  "before the first sample (amb-rig: recorder)", "", 0, 100),
        ParamSpec("lead_samples", 200, "lockstep: samples published ahead of the plant's /clock (at least rates_block"
                  " + the plant's clock_every - 2, so that the block of every step is out in time)", "samples", 0,
                  10000),
        ParamSpec("batch_wait_s", 0.002, "lockstep: pause before answering /clock, so that one wake-up answers many "
                  "steps (off the plant's critical path while lead_samples covers it)", "s", 0.0, 1.0),
    ]  # fmt: skip


class BaseMotionNode(RigNode):
    def __init__(self, stop):
        super().__init__("base_motion", stop, specs())
        p = self.p
        kind = p["kind"] or self.cfg.base_motion.kind
        if kind == "recorded":
            if not p["recorded_file"]:
                raise InputError("parameter 'recorded_file' is required for kind recorded")
            self.motion = load_recorded(p["recorded_file"], p["recorded_smoothing"] or None)
        else:  # amplitude and frequency are already folded into the config; the core validates the profile
            self.cfg = self.params.override(f"base_motion.kind={kind}")
            self.motion = BaseMotion.from_config(self.cfg.base_motion)
        if p["lead_samples"] * 2 >= p["qos_depth"]:
            raise InputError(f"lead_samples {p['lead_samples']} must be below half of qos_depth {p['qos_depth']}")
        if self.mode == "lockstep" and p["lead_samples"] < p["rates_block"]:
            raise InputError(f"lead_samples {p['lead_samples']} must be at least rates_block {p['rates_block']} (the "
                             "plant waits for the block that holds its step)")  # fmt: skip
        self.kind = kind
        self.source = SampleSource(self.motion, self.Ts)
        qos = data_qos(self.mode, p["qos_depth"])
        self.imu_pub = self.create_publisher(Imu, m.IMU, qos)
        self.acc_pub = self.create_publisher(Vector3Stamped, m.ANGULAR_ACCELERATION, qos)
        self.imu_codec, self.acc_codec = m.imu_codec(), m.vector3_codec()
        self.rates_pub = self.rates = None
        if self.mode == "lockstep":
            self.rates_pub = self.create_publisher(JointTrajectory, m.BASE_RATES, qos)
            self.rates = StateBlockWriter(m.BASE_RATE_NAMES, p["rates_block"])
        self.clock_decoder = m.clock_decoder()
        subs = []
        if self.mode == "lockstep":
            self.clock_sub = self.create_subscription(Clock, m.CLOCK, self.on_clock, qos, raw=True)
            subs.append(self.clock_sub)
        self.waiter = Waiter(self, subs)
        self.next_k = 0  # next sample to publish
        self.clock_k = -1  # latest /clock step seen
        self.restarts = 0
        self.published = 0
        self.wall_start = None

    # -- publishing --------------------------------------------------------------------------------
    def publish_sample(self, k: int, stamp_ns: int) -> None:
        q, om, dom = self.source.sample(k)
        if self.rates is not None:
            self.publish_rates(self.rates.add(stamp_ns, np.concatenate([om, dom])))
        if self.rates is None or k % self.p["imu_every"] == 0:  # realtime: called every imu_every samples
            self.imu_pub.publish(self.imu_codec.encode(stamp_ns, np.concatenate([q, om])))
            self.acc_pub.publish(self.acc_codec.encode(stamp_ns, dom))
            self.counters.published[m.IMU] += 1
            self.counters.published[m.ANGULAR_ACCELERATION] += 1
        self.published += 1

    def publish_rates(self, block: bytes | None) -> None:
        if block is not None:
            self.rates_pub.publish(block)
            self.counters.published[m.BASE_RATES] += 1

    def on_clock(self, raw: bytes) -> None:
        got = self.counters.decode(m.CLOCK, self.clock_decoder, raw)
        if got is None:
            return
        t_ns, _ = got
        if t_ns % self.Ts_ns:
            self.counters.reject(m.CLOCK, f"t = {t_ns} ns is not on the {self.Ts_ns} ns sample grid")
            return
        k = t_ns // self.Ts_ns
        if k < self.clock_k:  # the plant restarted: follow it
            self.restarts += 1
            self.next_k = k
            self.rates.reset()  # the next block starts there
        self.clock_k = k

    def readers_ready(self) -> bool:
        """Before sample 0: every expected reader is matched (a late recorder would lose the first samples)."""
        return self.next_k > 0 or (
            self.rates_pub.get_subscription_count() >= self.p["min_rates_subscribers"]
            and self.imu_pub.get_subscription_count() >= self.p["min_imu_subscribers"]
            and self.acc_pub.get_subscription_count() >= self.p["min_acceleration_subscribers"]
        )

    def answer_clock(self) -> None:
        if not self.readers_ready():
            return
        while self.next_k <= self.clock_k + self.p["lead_samples"]:
            self.publish_sample(self.next_k, self.next_k * self.Ts_ns)
            self.next_k += 1

    # -- loops -------------------------------------------------------------------------------------
    def run(self) -> int:
        self.wall_start = time.monotonic()
        if self.mode == "lockstep":
            while not self.stop.is_set:
                self.waiter.wait(1.0)
                if self.next_k > self.clock_k + self.p["lead_samples"] // 2 and self.p["batch_wait_s"] > 0:
                    time.sleep(self.p["batch_wait_s"])  # still half a window ahead: let /clock messages gather
                while (raw := Waiter.take(self.clock_sub)) is not None:
                    self.on_clock(raw)
                if self.clock_k >= 0:
                    self.answer_clock()
                self.housekeeping()
        else:  # the IMU's own rate: every imu_every samples (the plant holds the rates to first order between)
            every = self.p["imu_every"]
            ticker = Ticker(self.Ts_ns * every)
            while not self.stop.is_set:
                k, _, _ = ticker.wait_next(self.waiter, lambda: None, self.stop)
                if self.stop.is_set:
                    break
                self.publish_sample(k * every, self.get_clock().now().nanoseconds)
                self.housekeeping()
            self.skipped = ticker.skipped
        if self.rates is not None:
            self.publish_rates(self.rates.flush())  # the samples of the last, shorter block
        self.deliver_pending(self.imu_pub, self.acc_pub, self.rates_pub)
        self.waiter.close()
        level, message = self.status()
        self.diag.publish_final(level, message, self.values())
        return 0

    def housekeeping(self) -> None:
        self.waiter.serve()
        if self.diag.due():
            self.diag.publish(*self.status(), self.values())

    def status(self) -> tuple[bytes, str]:
        t = self.next_k * self.Ts
        duration = getattr(self.motion, "duration", None)
        if duration is not None and t > duration:
            return WARN, f"recording ended at t = {duration:.6g} s: base held at rest"
        if self.counters.total_rejected:
            return WARN, f"{self.counters.total_rejected} rejected messages ({self.counters.last_rejection})"
        return OK, f"{self.kind}: {self.published} samples published"

    def values(self) -> dict[str, str]:
        m_ = self.motion
        out = self.common_values()
        out.update(
            {
                "kind": self.kind,
                "harmonics": "; ".join(f"{h.axis} A={h.amplitude:g} rad w={h.frequency:g} rad/s" for h in m_.harmonics),
                "samples published": str(self.published),
                "last sample t (s)": f"{(self.next_k - 1) * self.Ts:.9g}",
                "clock step": str(self.clock_k),
                "lead (samples)": str(self.p["lead_samples"]),
                "restarts": str(self.restarts),
                "wall time (s)": f"{time.monotonic() - self.wall_start:.3f}" if self.wall_start else "0",
            }
        )
        return out


def main(args: list[str] | None = None) -> None:
    exit_process(run_node("base_motion", BaseMotionNode, args))
