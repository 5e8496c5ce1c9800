"""Runtime parameters: validated on set (a bad value is rejected, the old one kept), applied at a defined sample.

* Over DDS, as ``ros2 param set`` does it (the node's set_parameters service), against a running controller fed
  samples by this test: rejected values leave the control law unchanged (u = -kp y checked against the seed
  gain), an accepted gain applies from the next sample and is stamped in /diagnostics with that sample.
* ``amb-rig run --param-at T controller:proportional_gain=V`` in lockstep, recorded: the displacement trajectory
  in the bag equals the core's offline sampled-data loop with the gain switched at the first sample t_k >= T, and
  not with it switched one sample earlier or later; the change is in the bag (/diagnostics and /parameter_events).
"""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from helpers import ros_node
from procs import spawn

pytestmark = pytest.mark.ros

KP = 15648.2525  # the seed config's nominal kp (A/m); kI = 0 in the seed config
TS_NS = 200_000  # 5 kHz
Y = np.array([1e-4, -2e-4, 3e-5, 5e-5])

PAPER = str(Path(__file__).resolve().parents[1] / "config" / "seed_paper.yaml")  # the idealised loop


def test_schedule_is_checked_before_the_run():
    from amb_controller.node import specs
    from amb_ros.live_params import parse_schedule
    from amb_ros.params import ParamError

    runtime = {s.name: s for s in specs() if s.runtime}
    current = {"proportional_gain": KP, "excitation_kind": "none"}
    got = parse_schedule(["0.3 excitation_kind=sine", "0.1001 proportional_gain=20000"], runtime, current)
    assert got == [(100_100_000, "proportional_gain", 20000.0), (300_000_000, "excitation_kind", "sine")]
    assert isinstance(got[0][2], float)  # an integer given for a float gain is that float
    for bad, why in (
        ("0.1 current_limit=3.0", "cannot change at run time"),
        ("-1 proportional_gain=1.0", "T >= 0"),
        ("0.1 proportional_gain=-5.0", "out of range [0, 1e+12]"),
        ("0.1 excitation_kind=square", "not one of"),
    ):
        with pytest.raises(ParamError, match=why.replace("[", r"\[").replace("+", r"\+")):
            parse_schedule([bad], runtime, {**current, "current_limit": 10.0})


@pytest.fixture
def client_node():
    with ros_node("live_param_test") as pair:
        yield pair


def test_param_set_rejects_bad_values_and_applies_good_ones_at_the_next_sample(client_node, venv_bin, tmp_path):
    from diagnostic_msgs.msg import DiagnosticArray
    from rcl_interfaces.srv import SetParameters
    from rclpy.parameter import Parameter
    from sensor_msgs.msg import JointState

    from amb_ros import messages as m
    from amb_ros.qos import diagnostics_qos, lockstep_qos

    node, ex = client_node
    answers, diags = {}, []
    node.create_subscription(JointState, m.CURRENT, lambda msg: answers.__setitem__(
        msg.header.stamp.nanosec, np.array(msg.effort)), lockstep_qos())  # fmt: skip
    node.create_subscription(DiagnosticArray, "/diagnostics", diags.append, diagnostics_qos())
    disp = node.create_publisher(JointState, m.DISPLACEMENT, lockstep_qos())
    client = node.create_client(SetParameters, "/amb_controller/set_parameters")

    def spin_until(cond, timeout=30.0):
        end = time.monotonic() + timeout
        while not cond() and time.monotonic() < end:
            ex.spin_once(timeout_sec=0.05)
        assert cond()

    def sample(k):
        msg = JointState(name=["amb1_y", "amb1_z", "amb5_y", "amb5_z"], position=Y.tolist())
        msg.header.stamp.nanosec = k * TS_NS
        disp.publish(msg)
        spin_until(lambda: k * TS_NS in answers)
        return answers[k * TS_NS]

    def set_param(name, value):
        req = SetParameters.Request(parameters=[Parameter(name, value=value).to_parameter_msg()])
        future = client.call_async(req)
        spin_until(future.done)
        return future.result().results[0]

    cmd = [
        str(venv_bin / "amb-controller"),
        "--ros-args",
        "-p",
        "diagnostics_period_s:=0.2",
        "-p",
        f"config_file:={PAPER}",
    ]
    with spawn(cmd, tmp_path / "controller.log") as ctl:
        spin_until(lambda: disp.get_subscription_count() >= 1 and client.service_is_ready())
        np.testing.assert_allclose(sample(0), -KP * Y, rtol=1e-12)  # y_-1 = y_0: u = -kp y
        for name, value, why in (
            ("proportional_gain", -1.0, ""),  # out of the declared range
            ("proportional_gain", float("nan"), ""),
            ("excitation_kind", "square", "not one of none, sine, noise"),
            ("current_limit", 1.0, ""),  # read-only: not a runtime parameter
            ("derivative_gain", 5, ""),  # an integer for a float parameter: wrong type
        ):
            result = set_param(name, value)
            assert not result.successful and result.reason, (name, value)
            assert why in result.reason
        # the loop kept running on the old gain
        np.testing.assert_allclose(sample(1), -KP * Y, rtol=1e-12)
        new_kp = 2.5e4
        assert set_param("proportional_gain", new_kp).successful
        np.testing.assert_allclose(sample(2), -new_kp * Y, rtol=1e-12)  # derivative term zero (same y)
        np.testing.assert_allclose(sample(3), -new_kp * Y, rtol=1e-12)

        def change_reported():
            for arr in diags:
                for st in arr.status:
                    values = {kv.key: kv.value for kv in st.values}
                    if st.name == "amb_controller" and "parameter change 1" in values:
                        return values
            return None

        spin_until(lambda: change_reported() is not None)
        values = change_reported()
        assert values["parameter change 1"].startswith(f"proportional_gain: {KP!r} -> {new_kp!r} at k = 2 ")
        assert values["parameter changes rejected"] == "1"  # only excitation_kind reached the node's own check
        assert "parameter change rejected" in ctl.text()


def offline_switched(steps: int, k_switch: int, new_kp: float, disk_v: float) -> np.ndarray:
    """Displacements y_0..y_steps of the offline sampled-data loop with kp switched before sample k_switch."""
    from amb_dynamics.amb import DiscretePIDCoefficients
    from amb_dynamics.config import load_config, paper_config_path
    from amb_dynamics.fe import dof_index
    from amb_dynamics.motion import BaseMotion
    from amb_dynamics.sampled import SampledLoop
    from amb_dynamics.structure import build_structure

    cfg = load_config(paper_config_path())  # the paper's loop: no bias offset, no added plant dynamics
    model = build_structure(cfg)
    q = np.zeros(model.fe.n)
    q[dof_index(cfg.disks[0].node, 0)] = disk_v
    x = np.concatenate([model.from_fe(q), np.zeros(model.n)])
    loop = SampledLoop(model, cfg, Ts=TS_NS / 1e9)
    Om, dOm = BaseMotion.from_config(cfg.base_motion).angular_velocity(np.arange(steps + 1) * loop.Ts)
    pid = loop.new_controller()
    y = np.empty((steps + 1, 4))
    for k in range(steps + 1):
        if k == k_switch:
            pid.c = DiscretePIDCoefficients.from_gains(replace(model.gains, kp=new_kp), loop.Ts)
        y[k] = loop.plant.output(x)
        if k < steps:
            x = loop.plant.step(x, pid.step(y[k]), Om[:, k], dOm[:, k])
    return y


def test_param_at_switches_at_the_first_sample_after_T_and_is_in_the_bag(tmp_path, venv_bin):
    from diagnostic_msgs.msg import DiagnosticArray
    from rcl_interfaces.msg import ParameterEvent
    from rclpy.serialization import deserialize_message
    from sensor_msgs.msg import JointState

    from amb_bag.reader import Bag
    from helpers import run_rig

    duration, t_at, new_kp, disk_v = 0.2, 0.1001, 2.0e4, 1e-4
    k_switch = 501  # first k with k * 0.2 ms >= 100.1 ms
    bag = tmp_path / "bag"
    code, summary, text = run_rig(tmp_path, venv_bin, [
        "--config", PAPER, "--duration", str(duration), "--initial-displacement", str(disk_v), "--no-monitor",
        "--bag", str(bag),
        "--param-at", str(t_at), f"controller:proportional_gain={new_kp}"])  # fmt: skip
    assert code == 0, summary.get("errors") or text[-2000:]
    ctl = summary["nodes"]["controller"]["values"]
    assert ctl["parameter change 1"].startswith(f"proportional_gain: {KP!r} -> {new_kp!r} at k = {k_switch} ")
    assert "param_at" in ctl["parameter change 1"]

    steps = round(duration * 1e9 / TS_NS)
    disp, changes, events = {}, [], []
    for topic, _, _, _, data in Bag(bag).messages():
        if topic == "/amb/displacement":
            msg = deserialize_message(data, JointState)
            disp[msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec] = np.array(msg.position)
        elif topic == "/diagnostics":
            for st in deserialize_message(data, DiagnosticArray).status:
                values = {kv.key: kv.value for kv in st.values}
                if st.name == "amb_controller" and "parameter change 1" in values:
                    changes.append(values["parameter change 1"])
        elif topic == "/parameter_events":
            ev = deserialize_message(data, ParameterEvent)
            events += [(ev.node, p.name, p.value.double_value) for p in ev.changed_parameters]
    assert sorted(disp) == [k * TS_NS for k in range(steps + 1)]
    y_dds = np.array([disp[k * TS_NS] for k in range(steps + 1)])
    ref = offline_switched(steps, k_switch, new_kp, disk_v)
    scale = np.abs(ref).max()
    assert np.abs(y_dds - ref).max() <= 1e-9 * scale
    for other in (k_switch - 1, k_switch + 1):  # the comparison tells the sample apart
        assert np.abs(y_dds - offline_switched(steps, other, new_kp, disk_v)).max() > 1e-6 * scale
    assert changes and changes[0] == ctl["parameter change 1"]
    assert ("/amb_controller", "proportional_gain", new_kp) in events


def test_monitor_margin_changes_the_running_flag_policy():
    """stability_monitor's runtime margin/hysteresis reach the running estimator's flag, which keeps its state."""
    from types import SimpleNamespace

    from amb_dynamics.estimator.fit import InstabilityFlag, VerdictPolicy
    from stability_monitor.pipeline import MonitorPipeline, MonitorSettings

    pl = MonitorPipeline(MonitorSettings(period=0.1))
    flag = InstabilityFlag(VerdictPolicy(margin=0.02, hysteresis=0.02, z=3.0, confirm=2))
    pl.estimator = SimpleNamespace(flag=flag)  # the running estimator's flag (only its policy is touched)
    fit = SimpleNamespace(excited=True, rho=1.03, rho_std=0.0, resolved=True, reason="")
    flag.update(fit)  # one of the two confirmations at margin 0.02 (1.03 >= 1.02)
    pl.set_margins(0.05, 0.01)
    assert (pl.s.margin, pl.s.hysteresis) == (0.05, 0.01)
    assert flag.policy == VerdictPolicy(margin=0.05, hysteresis=0.01, z=3.0, confirm=2)
    assert flag.update(fit) != "unstable" and not flag.unstable  # 1.03 < 1 + 0.05: not raised
    pl.set_margins(0.02, 0.01)
    flag.update(fit)
    assert flag.update(fit) == "unstable"  # two confirmations at the restored margin
