"""The stability monitor over DDS, beside a lockstep ``amb-rig`` run (separate processes, localhost only).

The monitor runs with its defaults (base period found from /base/imu, noise level estimated, forcing model
'none' as the seed config has no base forcing) and is started before the rig.  The plant starts from the paper's
1 mm disk displacement; the current limit and the plant's displacement stop are lifted so that the loop stays the
linear one whose multipliers are the truth.

The rig runs with --no-monitor (this test starts its own) and with the plant's and base_motion's reader gates
raised by one, so that they wait for this monitor before step 0 and it sees every sample.

- unstable: pitch 0.6 rad, T = pi/omega = 718 Ts (rho = 1.0617), sensor-only input (/amb/displacement):
  /stability/unstable must become True within DETECT_PERIODS periods of simulated time (offline, the same
  deterministic run flags at 6.6 periods), and the final estimate must equal the sampled-data model rho;
- stable: pitch 0.3 rad, T = 641 Ts (rho = 0.99879), full-state input (/amb_plant/state): the flag stays False
  for the whole run.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest

from helpers import model_rho
from procs import spawn

pytestmark = pytest.mark.ros

DETECT_PERIODS = 8  # documented detection latency (periods T of A(t))
TS = 2e-4  # the seed config's 5 kHz loop
# the paper's 1 mm disk displacement; no current limit and no displacement stop: the linear loop of the model
START = ["--param", "plant:initial_displacement=1e-3", "--set", "controller.current_limit=1e9",
         "--param", "plant:max_displacement_ratio=1e9"]  # fmt: skip

PAPER = str(Path(__file__).resolve().parents[1] / "config" / "seed_paper.yaml")  # the paper's idealised rotor


@pytest.fixture
def listener():
    """An in-process rclpy node recording /stability/unstable and the monitor's /diagnostics."""
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
    from std_msgs.msg import Bool

    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    node = rclpy.create_node("monitor_test_listener", context=ctx)
    latched = QoSProfile(depth=1, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)  # fmt: skip
    rec = {"flags": [], "diag": []}
    node.create_subscription(Bool, "/stability/unstable", lambda m: rec["flags"].append(m.data), latched)

    def on_diag(msg):
        for s in msg.status:
            if s.name == "stability_monitor":
                rec["diag"].append({kv.key: kv.value for kv in s.values} | {"_level": s.level, "_msg": s.message})

    node.create_subscription(DiagnosticArray, "/diagnostics", on_diag, QoSProfile(depth=100))
    executor = rclpy.executors.SingleThreadedExecutor(context=ctx)
    executor.add_node(node)

    def spin_until(pred, timeout):
        end = time.monotonic() + timeout
        while time.monotonic() < end and not pred():
            executor.spin_once(timeout_sec=0.05)
        return pred()

    rec["spin_until"] = spin_until
    rec["node"] = node
    try:
        yield rec
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.shutdown(context=ctx)


def run_case(listener, venv_bin, tmp_path, amplitude, N, periods, sensor_only):
    T = N * TS
    omega = np.pi / T
    monitor_cmd = [str(venv_bin / "amb-monitor"), "--ros-args", "-p", "diagnostics_period_s:=0.2",
                   "-p", f"config_file:={PAPER}"]  # fmt: skip
    rig_cmd = [
        str(venv_bin / "amb-rig"),
        "run",
        "--duration",
        repr(periods * T),
        "--motion",
        "pitch",
        "--amplitude",
        repr(amplitude),
        "--frequency",
        repr(omega),
        "--log-dir",
        str(tmp_path / "rig"),
        "--no-monitor",
        *START,
    ]  # fmt: skip  (this test runs its own monitor, started first)
    # the plant and base_motion wait until this monitor reads their topics: it sees every sample from the first
    rig_cmd += ["--param", "base_motion:min_imu_subscribers=1", "--config", PAPER]
    if sensor_only:
        monitor_cmd += ["-p", "input:=displacement"]
        rig_cmd += ["--param", "plant:min_subscribers=2"]
    else:
        rig_cmd += ["--param", "plant:min_state_subscribers=1"]
    with spawn(monitor_cmd, tmp_path / "monitor.log") as mon:
        assert listener["spin_until"](lambda: listener["diag"] and listener["flags"], 30), mon.text()
        with spawn(rig_cmd, tmp_path / "rig.log") as rig:
            rc = rig.wait(timeout=240)
            assert rc == 0, rig.text()[-2000:]
        end = periods * T

        def caught_up():  # the monitor has refitted on the last samples of the run
            d = listener["diag"][-1]
            return float(d.get("estimate time (s)", -1.0)) >= end - T / 4

        assert listener["spin_until"](caught_up, 60), (listener["diag"][-1], mon.text()[-2000:])
        rc = mon.stop()
        assert rc == 0, mon.text()[-2000:]
    listener["spin_until"](lambda: listener["diag"][-1].get("final") == "true", 5)
    return listener["diag"][-1], T


def test_unstable_run_raises_the_flag(listener, venv_bin, tmp_path):
    diag, T = run_case(listener, venv_bin, tmp_path, 0.6, 718, 13, sensor_only=True)
    assert listener["flags"][0] is False and True in listener["flags"], listener["flags"]
    assert diag["samples lost"] == "0" and diag["samples"] == str(13 * 718 + 1), diag  # it kept up
    assert float(diag["flag raised at (s)"]) <= DETECT_PERIODS * T, diag
    assert float(diag["period (s)"]) == pytest.approx(T, rel=1e-12), diag  # from /base/imu, snapped to 718 Ts
    assert float(diag["rho"]) == pytest.approx(model_rho(0.6, T), abs=1e-6), diag  # the sampled-data model value
    assert diag["verdict"] == "unstable", diag


def test_stable_run_never_raises_the_flag(listener, venv_bin, tmp_path):
    diag, T = run_case(listener, venv_bin, tmp_path, 0.3, 641, 12, sensor_only=False)
    assert listener["flags"] and not any(listener["flags"])
    assert diag["samples lost"] == "0" and diag["samples"] == str(12 * 641 + 1), diag
    assert diag["verdict"] in ("stable", "marginal") and diag["unstable"] == "false"
    assert float(diag["rho"]) == pytest.approx(model_rho(0.3, T), abs=0.01)


@pytest.mark.parametrize(
    ("param", "message"),
    [
        ("input:=pressure", "'input' = 'pressure' is not one of"),
        ("period_s:=-1.0", "'period_s' = -1.0 is out of range"),
        ("phases:=0", "'phases' = 0 is out of range"),
        ("forcing:=sometimes", "'forcing' = 'sometimes' is not one of"),
        ("typo_param:=1", "unknown parameter 'typo_param'"),
    ],
)
def test_bad_parameters_exit_with_one_line(param, message, venv_bin, tmp_path):
    with spawn([str(venv_bin / "amb-monitor"), "--ros-args", "-p", param], tmp_path / "monitor.log") as mon:
        rc = mon.wait(timeout=60)
        text = mon.text().strip()
    assert rc == 2 and message in text
    assert "Traceback" not in text and len(text.splitlines()) == 1


def test_non_finite_samples_are_rejected(listener, venv_bin, tmp_path):
    """A NaN state never reaches the estimator: counted as rejected, reported in the diagnostics."""
    from builtin_interfaces.msg import Duration
    from rclpy.node import Node
    from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

    from amb_ros.qos import lockstep_qos

    node: Node = listener["node"]
    pub = node.create_publisher(JointTrajectory, "/amb_plant/state", lockstep_qos())
    with spawn([str(venv_bin / "amb-monitor"), "--ros-args", "-p", "diagnostics_period_s:=0.2"],
               tmp_path / "monitor.log") as mon:  # fmt: skip
        assert listener["spin_until"](lambda: listener["diag"] and pub.get_subscription_count() > 0, 30), mon.text()
        for k in range(5):  # blocks of two samples, the second with a NaN
            msg = JointTrajectory(joint_names=["mode1", "mode2"])
            msg.points = [JointTrajectoryPoint(positions=[0.0, 0.0], velocities=[0.0, 0.0]),
                          JointTrajectoryPoint(positions=[0.0, float("nan")], velocities=[0.0, 0.0],
                                               time_from_start=Duration(nanosec=200_000))]  # fmt: skip
            msg.header.stamp.nanosec = k * 400_000
            pub.publish(msg)

        def rejected():
            return listener["diag"][-1].get("rejected /amb_plant/state") == "5"

        assert listener["spin_until"](rejected, 30), listener["diag"][-1]
        assert "samples" not in listener["diag"][-1] or listener["diag"][-1]["samples"] == "0"
        assert "non-finite" in listener["diag"][-1]["last rejection"]
