"""Entry-point scaffolding shared by the nodes: DDS environment, signals, one-line errors, exit codes.

``run_node(name, factory)`` is the whole ``main()`` of a node: it enforces localhost DDS before rclpy starts,
turns SIGINT/SIGTERM into a stop flag that the node's loop polls (so the node publishes its final diagnostics and
shuts down cleanly instead of dying mid-write), prints user errors (:class:`AmbError`, a refused DDS environment,
bad ROS arguments) as one line on stderr, and returns the exit code, which the node's ``main()`` hands to
:func:`exit_process`.
"""

from __future__ import annotations

import contextlib
import faulthandler
import gc
import os
import signal
import sys
import threading
from typing import NoReturn

from amb_dynamics.errors import AmbError

from .env import DdsEnvError, ensure_localhost_dds
from .fastdds import init_rclpy

EXIT_OK = 0
EXIT_USAGE = 2  # bad parameter, config or environment
EXIT_FAILED = 3  # the run could not go on (peer gone, state diverged)
TEARDOWN_TIMEOUT_S = 5.0  # < amb-rig's SIGINT wait (8 s)


class StopFlag:
    """Set by SIGINT/SIGTERM; loops poll ``stop.is_set`` between bounded waits."""

    def __init__(self):
        self.signal: int | None = None

    @property
    def is_set(self) -> bool:
        return self.signal is not None

    def __call__(self, signum, _frame) -> None:
        self.signal = signum


class RunFailed(Exception):
    """The node stopped because the run cannot go on; the message says why (one line), exit code 3."""


def low_latency_dds(env: dict | None = None) -> None:
    """Fast DDS publishes synchronously from the caller's thread unless told otherwise here.

    Asynchronous publication adds a thread hand-off to every message; measured here it costs ~30 % of the
    lockstep round-trip rate (benchmarks/bench_lockstep.py).  An explicit setting in the environment wins.
    """
    env = os.environ if env is None else env
    env.setdefault("RMW_FASTRTPS_PUBLICATION_MODE", "SYNCHRONOUS")


def run_node(name: str, factory, args: list[str] | None = None) -> int:
    """Create the node with ``factory(stop)`` and call its ``run()``; return the process exit code."""
    try:
        ensure_localhost_dds()
    except DdsEnvError as exc:
        print(f"{name}: {exc}", file=sys.stderr)
        return EXIT_USAGE
    low_latency_dds()
    # a crash inside the C++ libraries (a heap check's abort in Fast DDS's teardown was seen in a full test run)
    # leaves the Python stack of every thread in the node's log instead of one line
    faulthandler.enable()
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    stop = StopFlag()
    signal.signal(signal.SIGINT, stop)
    signal.signal(signal.SIGTERM, stop)
    try:
        init_rclpy(args=args if args is not None else sys.argv, signal_handler_options=SignalHandlerOptions.NO)
    except Exception as exc:  # rclpy's RCLInvalidROSArgsError and friends: a usage error, not a bug
        print(f"{name}: cannot initialise ROS ({str(exc).splitlines()[0]})", file=sys.stderr)
        return EXIT_USAGE
    node, code = None, EXIT_FAILED
    try:
        node = factory(stop)
        # everything allocated so far (imports, model, node) lives for the whole run: moved out of the
        # collector's reach, a full collection no longer walks it (tens of ms: a HIL loop's worst period)
        gc.freeze()
        if hasattr(node, "enter_loop_scheduling"):  # the loop's nodes: SCHED_FIFO now that they are built
            node.enter_loop_scheduling()
        code = node.run()
    except AmbError as exc:
        print(f"{name}: {exc}", file=sys.stderr)
        code = EXIT_USAGE
    except RunFailed as exc:
        print(f"{name}: {exc}", file=sys.stderr)
        code = EXIT_FAILED
    finally:
        teardown(name, node, code, rclpy)
    return code


def teardown(name: str, node, code: int, rclpy) -> None:
    """Destroy the node and shut DDS down.  A node that has finished (final diagnostics acknowledged) must not
    hang in Fast DDS's teardown, which happened here once in a few hundred runs (the process stayed until
    SIGKILL): after TEARDOWN_TIMEOUT_S it exits with its code."""
    watchdog = threading.Timer(TEARDOWN_TIMEOUT_S, _exit_now, args=(name, code))
    watchdog.daemon = True
    watchdog.start()
    if node is not None:
        node.destroy_node()
    rclpy.try_shutdown()
    watchdog.cancel()


def _exit_now(name: str, code: int) -> None:
    print(f"{name}: DDS shutdown did not finish within {TEARDOWN_TIMEOUT_S:g} s; exiting", file=sys.stderr,
          flush=True)  # fmt: skip
    os._exit(code)


def exit_process(code: int) -> NoReturn:
    """End a node's process with ``code`` after :func:`run_node`: flush the output and leave at once.

    The node's DDS work is over by now: :func:`teardown` destroyed the node (``RigNode.destroy_node`` first
    releases what holds its subscriptions) and shut rclpy down, which deletes the Fast DDS participant and tells
    the peers that its endpoints are gone (tests/test_runtime_teardown.py checks it from another process).  What
    the exit handlers would still do is free memory and destroy the C++ libraries' static objects, and that is
    where the processes failed: a destructor hung with a core busy for minutes (in a plant whose amb-rig had been
    SIGKILLed, holding the domain's run lock), and glibc's heap check aborted a plant after its final report in a
    full test run (no Python stack: faulthandler is off by then), which failed a run that had finished.
    ``os._exit`` skips them."""
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    os._exit(code)
