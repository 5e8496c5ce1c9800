"""amb_ros.loop.Ticker: the realtime loops' absolute-deadline ticks (wait set, then a plain sleep, then a short
poll).  No timing goal is asserted (machines here are noisy): what is asserted cannot depend on the load."""

from __future__ import annotations

import time

from amb_ros.loop import Ticker


class FakeWaiter:
    """Records the timeouts the ticker asks the wait set for, and sleeps them (a wait set with no messages)."""

    def __init__(self):
        self.timeouts: list[float] = []

    def wait(self, timeout_s: float) -> None:
        self.timeouts.append(timeout_s)
        time.sleep(timeout_s)


class Stop:
    is_set = False


def test_ticks_never_come_early_and_the_wait_set_stops_short_of_the_poll():
    period = 2_000_000  # 2 ms
    waiter, drained = FakeWaiter(), []
    ticker = Ticker(period, spin_ns=400_000, poll_ns=50_000)
    ks = []
    for _ in range(20):
        k, lateness, _ = ticker.wait_next(waiter, lambda: drained.append(1), Stop())
        assert lateness >= 0  # never before its deadline
        assert time.monotonic_ns() >= ticker.t0 + k * period
        ks.append(k)
    assert ks == sorted(ks) and len(set(ks)) == len(ks)  # one tick per deadline, skipped ones counted
    assert ticker.skipped == ks[-1] - (len(ks) - 1)
    # the wait set is asked to wake no later than spin_ns before a deadline: never the whole period
    assert waiter.timeouts and max(waiter.timeouts) <= (period - 400_000) * 1e-9 + 1e-12
    assert drained  # messages are drained after every wake-up


def test_poll_window_is_at_most_the_wait_set_margin():
    assert Ticker(500_000, spin_ns=200_000, poll_ns=300_000).poll_ns == 200_000
    assert Ticker(500_000).poll_ns == 50_000
