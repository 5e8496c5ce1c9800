"""A future-stamped sample or a flood of random stamps cannot wedge the lockstep controller (issue 20 item 2).

Before: one /amb/displacement sample stamped t = 1000 s became the controller's newest; it counted ~5 million
samples lost and rejected every real sample as a duplicate, and the plant failed 10 s later.  Samples are
serialized by rclpy and fed to the controller's receive path in-process.
"""

from __future__ import annotations

import numpy as np
import pytest

pytestmark = pytest.mark.ros


def test_future_stamp_and_random_flood_are_rejected_and_the_stream_goes_on():
    import rclpy
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import JointState

    from amb_controller.node import SAMPLE_WINDOW, ControllerNode
    from amb_ros.runtime import StopFlag

    rclpy.init(args=[])
    try:
        ctl = ControllerNode(StopFlag())
        names = ["amb1_y", "amb1_z", "amb5_y", "amb5_z"]

        def sample(t_ns: int) -> bytes:
            msg = JointState()
            msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(t_ns, 10**9)
            msg.name = names
            msg.position = [1e-5] * 4
            return serialize_message(msg)

        ts = ctl.Ts_ns
        ctl.on_sample(sample(0))
        ctl.on_sample(sample(1000 * 10**9))  # t = 1000 s
        rng = np.random.default_rng(3)
        flood = rng.integers(SAMPLE_WINDOW + 300, 10**7, size=10_000)  # steps beyond any window of this stream
        off_grid = rng.integers(1, ts, size=200)
        for k in range(1, 201):
            for j in range(50):
                ctl.on_sample(sample(int(flood[(k * 50 + j) % flood.size]) * ts))
            ctl.on_sample(sample(k * ts + int(off_grid[k - 1])))  # not on the grid
            ctl.on_sample(sample(k * ts))  # the real stream
        values = ctl.values()
        assert values["samples answered"] == "201"  # every real sample, 0..200
        assert values["samples lost"] == "0"
        assert int(values["samples out of window"]) == 1 + 200 * 50
        ctl.destroy_node()
    finally:
        rclpy.try_shutdown()


def test_samples_without_this_runs_token_are_foreign_and_never_answered():
    """The controller answers only samples that carry its run's token (header.frame_id), as the plant takes only
    commands that do: an intruder's well-formed sample for the current step, without a token or with another
    run's, is counted as foreign, and the real sample of that step is still answered once."""
    import rclpy
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import JointState

    from amb_controller.node import ControllerNode
    from amb_ros.runtime import StopFlag

    rclpy.init(args=["--ros-args", "-p", "run_token:=r0a1b2c3"])
    try:
        ctl = ControllerNode(StopFlag())
        assert ctl.token == "r0a1b2c3"

        def sample(k: int, token: str, y: float = 1e-5) -> bytes:
            msg = JointState(name=["amb1_y", "amb1_z", "amb5_y", "amb5_z"], position=[y] * 4)
            msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(k * ctl.Ts_ns, 10**9)
            msg.header.frame_id = token
            return serialize_message(msg)

        for k in range(5):
            ctl.on_sample(sample(k, "", 1e-3))  # an intruder's, first
            ctl.on_sample(sample(k, "r0a1b2c4", 1e-3))  # another run's
            ctl.on_sample(sample(k, "r0a1b2c3"))  # the plant's
        values = ctl.values()
        assert values["foreign /amb/displacement"] == "10"
        assert values["samples answered"] == "5" and values["samples lost"] == "0"
        ctl.destroy_node()
    finally:
        rclpy.try_shutdown()
