"""Loops without an executor: a reusable wait set over the node's subscriptions, and a wall-clock ticker.

An rclpy executor rebuilds its wait set and walks every entity on each ``spin_once``; the lockstep loop waits
thousands of times per second, so it keeps one wait set over its few subscriptions and takes serialized
messages directly (``take``).  Parameter services and other callbacks are still served: call
``serve()`` now and then (it runs one ``spin_once(0)``).  Every wait is bounded so that a stop flag set by a
signal handler is seen within ``POLL_S``.
"""

from __future__ import annotations

import os
import time

from rclpy.executors import SingleThreadedExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy

POLL_S = 0.05  # longest single wait: bounds the reaction time to SIGINT/SIGTERM
SERVE_PERIOD_S = 0.1


class Waiter:
    """Wait on a fixed set of subscriptions (created with ``raw=True``) and take their serialized messages."""

    def __init__(self, node, subscriptions):
        self.node, self.subs = node, list(subscriptions)
        self._ws = _rclpy.WaitSet(max(1, len(self.subs)), 0, 0, 0, 0, 0, node.context.handle)
        self._executor = SingleThreadedExecutor(context=node.context)
        self._executor.add_node(node)
        self._next_serve = 0.0

    def wait(self, timeout_s: float, subs=None) -> None:
        """Block until a subscription (of ``subs``, default all) may have data, or ``min(timeout_s, POLL_S)``
        has passed.  Waiting on fewer subscriptions spares wake-ups for messages that are not needed yet."""
        timeout_s = max(0.0, min(timeout_s, POLL_S))
        subs = self.subs if subs is None else subs
        if not subs:  # rcl refuses an empty wait set
            time.sleep(timeout_s)
            return
        self._ws.clear_entities()
        for sub in subs:
            self._ws.add_subscription(sub.handle)
        self._ws.wait(int(timeout_s * 1e9))

    @staticmethod
    def take(sub) -> bytes | None:
        """The next serialized message of ``sub``, or None."""
        out = sub.handle.take_message(sub.msg_type, True)
        return None if out is None else out[0]

    def serve(self, force: bool = False) -> None:
        """Serve parameter services and timers, at most every SERVE_PERIOD_S (callbacks see the same handlers)."""
        now = time.monotonic()
        if force or now >= self._next_serve:
            self._next_serve = now + SERVE_PERIOD_S
            self._executor.spin_once(timeout_sec=0.0)
            matches = getattr(self.node, "matches", None)
            if matches is not None:  # publishers matched by the input subscriptions (amb_ros/matches.py)
                matches.poll()

    def close(self) -> None:
        """Release the node: the executor's hold, and the wait set's references to the subscriptions it last
        waited on (until destroyed they keep the subscriptions, the node and its DDS participant alive)."""
        if self._ws is None:
            return
        self._executor.remove_node(self.node)
        self._executor.shutdown(timeout_sec=0.1)
        self._ws.clear_entities()
        self._ws.destroy_when_not_in_use()
        self._ws = None


class Ticker:
    """Absolute-deadline ticks at ``period_ns`` on the monotonic clock.

    ``wait_next(on_wait)`` returns when the next deadline has come: it sleeps in the wait set (``on_wait`` is
    called after every wake-up to drain messages) until ``spin_ns`` before the deadline, because the wait set's
    timed wait wakes up 50-100 us late; then in a plain sleep (``clock_nanosleep``: under SCHED_FIFO about 20 us
    late at the median, 20-60 us at p99 here) until ``poll_ns`` before it, and polls only that last stretch.
    Polling the whole 200 us would keep a SCHED_FIFO node busy for 40 % of a 2 kHz period on top of its work,
    near the kernel's real-time throttling limit (95 % of each CPU-second), beyond which every real-time thread
    on the CPU stalls for the rest of the second.  If the loop fell more than a whole period behind, the missed
    ticks are skipped (counted) and the schedule stays aligned to the original start.
    """

    def __init__(self, period_ns: int, spin_ns: int = 200_000, poll_ns: int = 50_000):
        self.period_ns, self.spin_ns, self.poll_ns = period_ns, spin_ns, min(poll_ns, spin_ns)
        self.t0 = time.monotonic_ns()
        self.k = 0
        self.skipped = 0
        self.last_start: int | None = None

    def deadline(self) -> int:
        return self.t0 + self.k * self.period_ns

    def wait_next(self, waiter: Waiter, on_wait, stop) -> tuple[int, int, int | None]:
        """Wait for tick k; return (k, lateness ns, period ns since the previous tick or None)."""
        deadline = self.deadline()
        while not stop.is_set:
            now = time.monotonic_ns()
            remaining = deadline - now
            if remaining <= 0:
                break
            if remaining > self.spin_ns:
                waiter.wait((remaining - self.spin_ns) * 1e-9)
            elif remaining > self.poll_ns:
                time.sleep((remaining - self.poll_ns) * 1e-9)
            else:
                os.sched_yield()  # polling: under SCHED_FIFO, let this process's DDS threads run on this core
            on_wait()
        now = time.monotonic_ns()
        lateness = now - deadline
        if lateness > self.period_ns:  # fell behind by whole periods: skip them, keep the grid
            behind = lateness // self.period_ns
            self.skipped += behind
            self.k += behind
            lateness -= behind * self.period_ns
        period = None if self.last_start is None else now - self.last_start
        self.last_start = now
        k = self.k
        self.k += 1
        return k, lateness, period
