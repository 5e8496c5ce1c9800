"""Optional action on instability: the controller switches to its safe gains on /stability/unstable (off by default)."""

import time
from pathlib import Path

import numpy as np
import pytest

from helpers import ros_node
from procs import spawn

pytestmark = pytest.mark.ros

KP, KD = 15648.2525, 11.273957  # the seed config's nominal gains
SAFE_KP = 20000.0  # the safe set of this test (kd: 0 = twice nominal)
TS_NS = 200_000  # 5 kHz
PAPER = str(Path(__file__).resolve().parents[1] / "config" / "seed_paper.yaml")


@pytest.fixture
def rig_node():
    with ros_node("safe_gain_test") as pair:
        yield pair


@pytest.mark.parametrize("enabled", [True, False])
def test_switch_to_safe_gains_on_unstable(rig_node, venv_bin, tmp_path, enabled):
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Bool

    from amb_ros import messages as m
    from amb_ros.qos import latched_qos, lockstep_qos

    node, ex = rig_node
    answers = {}
    node.create_subscription(JointState, m.CURRENT, lambda msg: answers.__setitem__(
        msg.header.stamp.nanosec, np.array(msg.effort)), lockstep_qos())  # fmt: skip
    disp = node.create_publisher(JointState, m.DISPLACEMENT, lockstep_qos())
    flag = node.create_publisher(Bool, m.UNSTABLE, latched_qos())
    y = np.array([1e-4, -2e-4, 3e-5, 5e-5])

    def sample(k):
        msg = JointState(name=["amb1_y", "amb1_z", "amb5_y", "amb5_z"], position=y.tolist())
        msg.header.stamp.nanosec = k * TS_NS
        disp.publish(msg)
        end = time.monotonic() + 20
        while k * TS_NS not in answers and time.monotonic() < end:
            ex.spin_once(timeout_sec=0.05)
        return answers[k * TS_NS]

    params = ["safe_gains_on_unstable:=" + str(enabled).lower(), f"safe_proportional_gain:={SAFE_KP}",
              f"config_file:={PAPER}"]  # the paper's loop: u = -kp y, no gravity feed-forward  # fmt: skip
    cmd = [str(venv_bin / "amb-controller"), "--ros-args", *[a for p in params for a in ("-p", p)]]
    with spawn(cmd, tmp_path / "controller.log") as ctl:
        end = time.monotonic() + 30
        while disp.get_subscription_count() < 1 and time.monotonic() < end:
            ex.spin_once(timeout_sec=0.05)
        u0 = sample(0)  # y_{-1} = y_0: no derivative term, u = -kp y
        np.testing.assert_allclose(u0, -KP * y, rtol=1e-12)
        flag.publish(Bool(data=True))
        time.sleep(1.0)  # the switch is served within ~0.1 s of wall time
        u1 = sample(1)  # same y again: derivative zero, u = -kp' y
        expected = -(SAFE_KP if enabled else KP) * y
        np.testing.assert_allclose(u1, expected, rtol=1e-12)
        assert ("switched to the safe gains" in ctl.text()) == enabled
