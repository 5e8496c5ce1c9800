"""The lockstep plant takes one command per step: a second one is rejected and counted, never "last one wins".

Before: ``self.commands[k] = current`` let an intruder's 12 A command for the current step replace the
controller's (amb_plant/node.py), although docs/topics.md said duplicates are rejected.  The verdict then
fails the run: which command was applied cannot be told.  Commands are serialized by rclpy here.
"""

from __future__ import annotations

import argparse

import numpy as np
import pytest

pytestmark = pytest.mark.ros


def command(plant, k: int, amps: float, token: str = "") -> bytes:
    """A serialized /amb/current message for step k (every channel ``amps``), with ``token`` in frame_id."""
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import JointState

    msg = JointState()
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(k * plant.Ts_ns, 10**9)
    msg.header.frame_id = token
    msg.name = list(plant.channels)
    msg.effort = [amps] * len(plant.channels)
    return serialize_message(msg)


def lockstep_verdict(plant_values: dict):
    """amb-rig's verdict of a lockstep run whose plant reported ``plant_values``."""
    from amb_bringup.verdict import add_arguments, judge_verdict

    p = argparse.ArgumentParser()
    add_arguments(p)
    args = p.parse_args([])
    args.mode, args.no_plant = "lockstep", False
    return judge_verdict({"errors": [], "nodes": {"plant": {"values": plant_values}}, "rate_hz": 5000.0}, args)


def test_second_command_for_a_step_is_rejected_and_fails_the_run():
    import rclpy

    from amb_bringup.verdict import EXIT_FAILED
    from amb_plant.node import PlantNode
    from amb_ros.runtime import StopFlag

    rclpy.init(args=[])
    try:
        plant = PlantNode(StopFlag())
        assert plant.mode == "lockstep" and plant.k_now == 0
        plant.on_command(command(plant, 0, 1.0))  # the controller's
        plant.on_command(command(plant, 0, 12.0))  # an intruder's, same step
        plant.on_command(command(plant, 0, 12.0))
        assert np.array_equal(plant.commands[0], np.full(len(plant.channels), 1.0))  # the first one is kept
        values = plant.values()
        assert values["duplicate commands"] == "2"
        plant.destroy_node()
    finally:
        rclpy.try_shutdown()
    v = lockstep_verdict(values)
    assert v.exit_code == EXIT_FAILED and "2 duplicate commands for one step" in v.line


def test_commands_without_the_run_token_are_foreign_even_at_step_0():
    """An intruder's well-formed command that arrives first (step 0, before the controller's) is not applied: it
    lacks the run token in header.frame_id; it is counted as foreign and named in the verdict's warnings."""
    import rclpy

    from amb_bringup.verdict import EXIT_OK
    from amb_plant.node import PlantNode
    from amb_ros.runtime import StopFlag

    rclpy.init(args=["--ros-args", "-p", "run_token:=r0a1b2c3"])
    try:
        plant = PlantNode(StopFlag())
        assert plant.token == "r0a1b2c3"
        plant.on_command(command(plant, 0, 12.0))  # an intruder's stale command, first
        plant.on_command(command(plant, 0, 12.0, "r0a1b2c4"))  # another run's
        plant.on_command(command(plant, 0, 1.0, "r0a1b2c3"))  # the controller's
        assert np.array_equal(plant.commands[0], np.full(len(plant.channels), 1.0))
        values = plant.values()
        assert values["foreign /amb/current"] == "2" and values["duplicate commands"] == "0"
        plant.destroy_node()
    finally:
        rclpy.try_shutdown()
    v = lockstep_verdict(values)
    assert v.exit_code == EXIT_OK  # nothing foreign was applied
    assert any("rejected 2 commands with another run token" in w for w in v.warnings), v.warnings
