"""The plant's start gate and its two time modes (see amb_plant.node): the lockstep clock-master loop and the
realtime ticker."""

from __future__ import annotations

import time

import numpy as np

import amb_ros.messages as m
from amb_ros.diagnostics import WARN
from amb_ros.loop import Ticker
from amb_ros.runtime import RunFailed

RATES_HOLD_S = 0.01  # realtime: longest extrapolation of the base rates past the latest IMU sample
HOUSEKEEPING_EVERY = 64  # steps between diagnostics/service checks in lockstep (cheap, but not free)


def run_lockstep(node) -> None:
    """Step k: publish /clock t_k, y_k, state; wait for base sample k and the command for t_k; advance."""
    Ts_ns = node.Ts_ns
    steps = round(node.p["duration_s"] / node.Ts) if node.p["duration_s"] > 0 else None
    clock_codec, stepper = node.clock_codec, node.rig
    clock_every = node.p["clock_every"]
    only_command = [node.cmd_sub]
    no_values = np.zeros(0)
    k = 0
    timeout = node.p["start_timeout_s"]  # the first answer may take longer (peers finish starting up)
    while not node.stop.is_set:
        t_ns = k * Ts_ns
        node.k_now = k
        t_sent = time.perf_counter()
        node.publish_outputs(k, t_ns)  # the displacement first: it starts the controller (the critical path)
        if k % clock_every == 0 or k == steps:
            node.clock_pub.publish(clock_codec.encode(t_ns, no_values))
            node.counters.published[m.CLOCK] += 1
        if steps is not None and k >= steps:
            node.finished = True
            return
        deadline = time.monotonic() + timeout
        mats = None
        while True:
            node.drain()
            if mats is None and k in node.rates:
                mats = node.rates.pop(k)
                stepper.prepare(mats[:3], mats[3:], node.x)  # the command-free part, while the controller computes
            if mats is not None and k in node.commands:
                break
            if node.stop.is_set:
                return
            now = time.monotonic()
            if now > deadline:
                raise RunFailed(lockstep_timeout_message(node, k, mats is not None, timeout))
            # with the base sample in hand only the command matters: base samples arriving meanwhile (base_motion
            # runs ahead in bursts) then do not wake this loop
            node.waiter.wait(deadline - now, only_command if mats is not None else None)
        if k == 0:  # start-up: the peers' own start gates (a recorder still being discovered) held step 0 up
            node.start_wait_s = time.perf_counter() - t_sent
            node.t_wall0 = time.monotonic()  # the loop rate is timed from here (start-up excluded)
        else:
            node.round_trip.add(time.perf_counter() - t_sent)
        node.advance(mats, node.commands.pop(k))
        timeout = node.p["command_timeout_s"]
        k += 1
        if k % HOUSEKEEPING_EVERY == 0:
            node.waiter.serve()
            if node.diag.due():
                node.diag.publish(*node.status(), node.values())


def lockstep_timeout_message(node, k: int, have_base: bool, timeout: float) -> str:
    what = []
    if not have_base:
        what.append(f"base sample ({m.BASE_RATES}; base_motion's lead_samples must be at least its rates_block + "
                    f"clock_every - 2 = rates_block + {node.p['clock_every'] - 2})")  # fmt: skip
    if k not in node.commands:
        what.append(f"command on {m.CURRENT} (controller gone?)")
    return f"no {' or '.join(what)} for step {k} (t = {k * node.Ts:.6g} s) within {timeout:g} s"


def run_realtime(node) -> None:
    """Wall-clock ticks: publish y at each tick; the step before it is computed as soon as its command is in.

    The step over [t_k-1, t_k] needs the command that answers sample k-1-d.  When that command arrives before
    tick k, the step is computed while waiting for the tick, and y_k goes out on time; otherwise it is computed at
    the tick with what has arrived (held, or zero current), as a DAC updated at the tick would be.  The step's own
    cost is then off the loop's critical path: y_k is not published a step's computation after t_k.
    """
    ticker = Ticker(node.Ts_ns)
    end = time.monotonic() + node.p["duration_s"] if node.p["duration_s"] > 0 else None
    half = node.Ts_ns // 2
    stepped = False  # the step before the coming tick is done

    def early_step() -> None:
        nonlocal stepped
        node.drain()
        if not stepped and node.samples_out and node.policy.on_time(node.samples_out):
            step_to_tick(node)
            stepped = True

    while not node.stop.is_set:
        skipped = ticker.skipped
        k, lateness, period = ticker.wait_next(node.waiter, early_step, node.stop)
        if node.stop.is_set:
            node.finished = node.p["duration_s"] == 0  # an endless realtime run ends when it is stopped
            return
        node.missed += (lateness > half) + (ticker.skipped - skipped)
        node.skipped = ticker.skipped
        if period is not None:
            node.period_error.add(abs(period - node.Ts_ns) * 1e-9)
        node.k_now = k
        if not stepped:
            step_to_tick(node)
        stepped = False
        node.publish_outputs(k, node.get_clock().now().nanoseconds)
        if end is not None and time.monotonic() >= end:
            node.finished = True
            return
        if k % 16 == 0:
            node.waiter.serve()
            if node.diag.due():
                node.diag.publish(*node.status(), node.values())


def step_to_tick(node) -> None:
    """The step after the last published sample, with the command the policy gives for it.  The command's age
    counts the samples this plant published, so that a plant that falls behind (skipped ticks, reported as missed
    deadlines) does not blame the controller; before levitation starts the rotor stays at its start state."""
    current = node.policy.current(node.samples_out) if node.samples_out else None
    if current is not None:
        node.advance(held_rates(node), current)


def held_rates(node) -> np.ndarray:
    """[Omega, dOmega/dt] at the start of the step after the last published sample: Omega extrapolated from the
    latest IMU sample with the latest dOmega/dt (first-order hold: base_motion samples at rate_hz / imu_every), at
    most ``RATES_HOLD_S`` ahead, so that a base_motion that stopped leaves the rates held rather than ramping."""
    om, dom = node.latest_rates
    if node.imu_at_ns is None:
        return np.concatenate([om, dom])
    ahead = min(max((node.sample_at_ns - node.imu_at_ns) * 1e-9, 0.0), RATES_HOLD_S)
    return np.concatenate([om + ahead * dom, dom])


def wait_connected(node) -> None:
    """Bounded wait until controller and base motion (and min_subscribers readers) are matched."""
    t0 = time.monotonic()
    deadline = t0 + node.p["start_timeout_s"]
    while not node.stop.is_set:
        missing = missing_peers(node)
        if not missing:
            node.connect_s = time.monotonic() - t0
            return
        if time.monotonic() > deadline:
            raise RunFailed(f"no {', '.join(missing)} after {node.p['start_timeout_s']:g} s (start timeout)")
        if node.diag.due():
            node.diag.publish(WARN, f"waiting for {', '.join(missing)}", node.values())
        node.waiter.serve(force=True)
        time.sleep(0.02)


def missing_peers(node) -> list[str]:
    """What the plant still waits for before step 0 (empty: every peer and reader is matched)."""
    missing = []
    if node.disp_pub.get_subscription_count() < node.p["min_subscribers"]:
        missing.append(f"{node.p['min_subscribers']} reader(s) of {m.DISPLACEMENT}")
    for sub, _ in node.handlers:
        if node.count_publishers(sub.topic_name) < 1:
            missing.append(f"publisher of {sub.topic_name}")
    if node.state_pub.get_subscription_count() < node.p["min_state_subscribers"]:
        missing.append(f"{node.p['min_state_subscribers']} reader(s) of {m.STATE}")
    readers = node.diag.readers_missing()
    if readers:
        missing.append(readers)
    if node.clock_pub is not None and node.clock_pub.get_subscription_count() < 1:
        missing.append(f"reader of {m.CLOCK} (base_motion)")
    return missing
