"""The controller's realtime (HIL) loops; see amb_controller.node for the behaviour they implement.

``sample`` trigger (default): each displacement sample is answered on arrival, as a DSP's ADC-complete interrupt
runs the control law; the update period (its jitter = |period - Ts|) is paced by the sensor's sample clock.  A
sample answered more than one period after its stamp, or a gap in the sample stream, is a missed deadline.
``timer`` trigger: the controller's own wall-clock ticks use the latest sample (sample-and-hold); the random
phase between the two clocks adds up to one sample of delay (the seed rotor's loop is not stable with it).
Both: a watchdog puts out zero current at rate_hz while no sample has arrived for sensor_timeout_s.
"""

from __future__ import annotations

import time

import numpy as np

from amb_ros.loop import Ticker


def on_realtime_sample(node, t_ns: int, y: np.ndarray) -> None:
    now = time.monotonic_ns()
    if node.last_update_ns is not None:
        period = now - node.last_update_ns
        node.period_error.add(abs(period - node.Ts_ns) * 1e-9)
    node.last_update_ns = now
    node.ticks += 1
    if node.last_stamp is not None and t_ns - node.last_stamp > 1.5 * node.Ts_ns:
        gap = round((t_ns - node.last_stamp) / node.Ts_ns) - 1
        node.skipped += gap
        node.missed += gap
    node.last_stamp = t_ns
    node.answer(t_ns, y, node.ticks * node.Ts)
    latency = node.get_clock().now().nanoseconds - t_ns  # both stamps from this machine's system clock
    node.latency.add(latency * 1e-9)
    if latency > node.Ts_ns:
        node.missed += 1
    node.fresh = False


def _watchdog(node, zero: np.ndarray) -> bool:
    """True (and zero current sent) while samples have stopped for longer than sensor_timeout_s."""
    if node.last_sample_wall is None or time.monotonic() - node.last_sample_wall <= node.p["sensor_timeout_s"]:
        return False
    if node.sensor_state != "lost":
        node.sensor_losses += 1
        node.pid.reset()
        node.last_update_ns = None
    node.sensor_state = "lost"
    node.safe_ticks += 1
    node.pub.publish(node.codec.encode(node.get_clock().now().nanoseconds, zero))
    return True


def run_sample_triggered(node) -> None:
    zero = np.zeros(len(node.channels))
    next_check = time.monotonic()
    while not node.stop.is_set:
        node.waiter.wait(node.Ts)
        node.drain()
        now = time.monotonic()
        if now >= next_check:  # the watchdog runs at rate_hz
            next_check = now + node.Ts
            _watchdog(node, zero)
        node.housekeeping()


def run_timer_triggered(node) -> None:
    ticker = Ticker(node.Ts_ns)
    half = node.Ts_ns // 2
    zero = np.zeros(len(node.channels))
    while not node.stop.is_set:
        skipped = ticker.skipped
        k, lateness, period = ticker.wait_next(node.waiter, node.drain, node.stop)
        if node.stop.is_set:
            return
        node.ticks += 1
        node.missed += (lateness > half) + (ticker.skipped - skipped)
        node.skipped = ticker.skipped
        if period is not None:
            node.period_error.add(abs(period - node.Ts_ns) * 1e-9)
        if node.latest is not None and not _watchdog(node, zero):
            node.repeated += not node.fresh
            node.fresh = False
            node.answer(node.latest[0], node.latest[1], k * node.Ts)
        if k % 16 == 0:
            node.housekeeping()
