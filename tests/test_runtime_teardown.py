"""A node that has finished must not hang in DDS teardown: ``amb_ros.runtime.teardown`` exits with the node's code
after TEARDOWN_TIMEOUT_S when the shutdown does not return (a Fast DDS teardown hang was seen once in a few hundred
runs; the node then lingered until amb-rig's SIGKILL, which failed the run)."""

from __future__ import annotations

import subprocess
import sys
import time

import pytest

HANGING = """
import time
import amb_ros.runtime as rt
rt.TEARDOWN_TIMEOUT_S = 0.5
class HangingRclpy:
    @staticmethod
    def try_shutdown():
        time.sleep(60)
rt.teardown("test_node", None, 3, HangingRclpy)
"""

RETURNING = """
import amb_ros.runtime as rt
rt.TEARDOWN_TIMEOUT_S = 0.5
class Rclpy:
    @staticmethod
    def try_shutdown():
        pass
rt.teardown("test_node", None, 3, Rclpy)
print("returned")
"""


def test_hanging_teardown_exits_with_the_node_code():
    t0 = time.monotonic()
    res = subprocess.run([sys.executable, "-c", HANGING], capture_output=True, text=True, timeout=30)
    assert res.returncode == 3
    assert "DDS shutdown did not finish within 0.5 s" in res.stderr and "Traceback" not in res.stderr
    assert time.monotonic() - t0 < 20  # not the 60 s the shutdown would have taken


def test_normal_teardown_returns_and_cancels_the_watchdog():
    res = subprocess.run([sys.executable, "-c", RETURNING + "import time; time.sleep(1.0)"], capture_output=True,
                         text=True, timeout=30)  # fmt: skip
    assert res.returncode == 0 and res.stdout.strip() == "returned" and res.stderr == ""


def test_the_supervisor_waits_longer_than_a_node_may_take_to_exit():
    """amb-rig's SIGINT wait covers a node's exit budget: its wait for slow readers (ACK_TIMEOUT_S) and its final
    report's wait (publish_final's default timeout), with room to spare; else a node still delivering its last
    samples to a lagging recorder is escalated to SIGTERM and the run fails."""
    import inspect

    from amb_bringup.supervisor import NODE_EXIT_BUDGET_S, SIGINT_WAIT_S
    from amb_ros.diagnostics import Diagnostics
    from amb_ros.node_base import ACK_TIMEOUT_S

    final_s = inspect.signature(Diagnostics.publish_final).parameters["timeout_s"].default
    assert NODE_EXIT_BUDGET_S == ACK_TIMEOUT_S + final_s
    assert SIGINT_WAIT_S >= NODE_EXIT_BUDGET_S + 3.0


EXITING = """
import atexit, sys, time
import amb_ros.runtime as rt
atexit.register(print, "exit handler ran")
atexit.register(time.sleep, 60)  # stands for a C++ destructor that hung (it did once, in a plant)
sys.stdout.write("buffered; ")
sys.stderr.write("last words")
rt.exit_process(3)
"""

LEAVING = """
import sys, time
import rclpy
from std_msgs.msg import String
import amb_ros.runtime as rt
from amb_ros.fastdds import init_rclpy
from amb_ros.loop import Waiter
from amb_ros.node_base import RigNode

init_rclpy()
node = RigNode("leaving", rt.StopFlag(), [])  # as a loop's node holds its input: a wait set and a match watch
sub = node.create_subscription(String, "teardown_probe", lambda msg: None, 10, raw=True)
node.waiter = Waiter(node, [sub])
node.matches.watch(sub)
deadline = time.monotonic() + 20
while node.count_publishers("/teardown_probe") < 1 and time.monotonic() < deadline:
    node.waiter.wait(0.01)
    node.waiter.serve(force=True)
rt.teardown("leaving", node, 0, rclpy)
print("torn down", flush=True)
time.sleep(float(sys.argv[1]))  # still alive: only the teardown can have told the peers
rt.exit_process(4)
"""


def test_exit_process_leaves_with_the_node_code_and_skips_the_exit_handlers():
    """What was printed is out, the code is the node's, and no exit handler runs (nor keeps the process)."""
    t0 = time.monotonic()
    res = subprocess.run([sys.executable, "-c", EXITING], capture_output=True, text=True, timeout=30)
    assert res.returncode == 3 and res.stdout == "buffered; " and res.stderr == "last words"
    assert time.monotonic() - t0 < 20  # not the 60 s of the hanging handler


@pytest.mark.ros
def test_teardown_tells_the_peers_before_the_exit():
    """Skipping the exit handlers loses nothing: right after :func:`teardown`, with the process still alive, a
    peer's publisher no longer matches the node's subscription, although the node waited on it in its wait set
    and watched its match status (both hold the subscription unless released: the participant then lived on
    until the exit handlers, and with os._exit the peers would keep it for the lease duration, 20 s)."""
    from std_msgs.msg import String

    from helpers import ros_node

    hold_s = 8.0
    with ros_node("teardown_observer") as (node, _):
        pub = node.create_publisher(String, "teardown_probe", 10)
        proc = subprocess.Popen([sys.executable, "-c", LEAVING, str(hold_s)], stdout=subprocess.PIPE, text=True)
        try:
            line = proc.stdout.readline()
            t0 = time.monotonic()
            while pub.get_subscription_count() > 0 and time.monotonic() < t0 + hold_s:
                time.sleep(0.005)
            left_after = time.monotonic() - t0
            assert line.strip() == "torn down" and proc.poll() is None  # the process was still there
            assert pub.get_subscription_count() == 0 and left_after < 2.0, left_after
            assert proc.wait(30) == 4
        finally:
            proc.kill()
            proc.wait()


def test_every_node_main_ends_through_exit_process():
    """The four node executables hand run_node's code to exit_process (not sys.exit alone, which has no time limit)."""
    import inspect

    from amb_controller import node as controller
    from amb_plant import node as plant
    from base_motion import node as base_motion
    from stability_monitor import node as monitor

    for module in (plant, controller, base_motion, monitor):
        src = inspect.getsource(module.main)
        assert "exit_process(run_node(" in src and "sys.exit" not in src, module.__name__
