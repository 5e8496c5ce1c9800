"""The realtime plant's command policy (amb_plant.sensor.CommandPolicy): nothing applied before the controller's
first command (the rotor is held at its start state), then fresh, held and zero current by the age of the newest
command counted in samples the plant published (the rotor's own time), not in wall-clock ticks; and the base
rates it steps with between IMU samples."""

from types import SimpleNamespace

import numpy as np

from amb_plant.loops import RATES_HOLD_S, held_rates
from amb_plant.sensor import CommandPolicy

HOLD = 3


def test_before_the_first_command_the_plant_does_not_advance():
    pol = CommandPolicy(4, HOLD)
    assert pol.current(1) is None and pol.current(2) is None
    assert pol.waiting == 2 and pol.zeroed == 0 and pol.state == "waiting"


def test_fresh_held_then_zero_by_the_age_in_published_samples():
    pol = CommandPolicy(4, HOLD)
    i = np.array([1.0, -2.0, 3.0, -4.0])
    pol.command(i, answered_k=0)  # answers published sample 0
    assert pol.current(1) is i and pol.state == "ok"  # the step after sample 0: fresh
    for s in range(2, 2 + HOLD):  # samples 1 .. HOLD published, still answered at 0: held
        assert pol.current(s) is i
    assert pol.held == HOLD and pol.state == "holding"
    z = pol.current(2 + HOLD)  # one sample beyond the hold window: zero current, one loss
    assert np.array_equal(z, np.zeros(4)) and pol.zeroed == 1 and pol.losses == 1 and pol.state == "zeroed"
    pol.current(3 + HOLD)
    assert pol.losses == 1 and pol.zeroed == 2  # the same silence is one loss
    j = -i
    pol.command(j, answered_k=2 + HOLD)  # commands come back
    assert pol.current(3 + HOLD) is j and pol.state == "ok"
    pol.command(i, answered_k=1)  # an older answer than the newest is ignored
    assert pol.current(3 + HOLD) is j


def test_one_sample_of_loop_delay_applies_each_command_one_step_later():
    """controller.delay_samples = 1: the command answering sample k acts over the step after sample k + 1, whether
    it arrived at once or one period later; the step after sample k still runs on the answer to k - 1."""
    pol = CommandPolicy(4, HOLD, delay_samples=1)
    a, b, c = (np.full(4, v) for v in (1.0, 2.0, 3.0))
    pol.command(a, answered_k=0)
    assert pol.current(1) is None and pol.waiting == 1  # the step after sample 0: nothing due yet
    pol.command(b, answered_k=1)  # the answer to sample 1 is already in ...
    assert pol.current(2) is a and pol.state == "ok"  # ... but the step after sample 1 runs on the answer to 0
    assert pol.current(3) is b and pol.state == "ok"  # the step after sample 2: the answer to 1, on time
    assert pol.current(4) is b and pol.state == "holding" and pol.held == 1  # the answer to 2 is late: held
    pol.command(c, answered_k=3)  # the answer to 2 never came; the one to 3 did
    assert pol.current(5) is c and pol.state == "ok"


def test_levitation_starts_once_the_loop_keeps_up():
    """start_samples = 3: the rotor is held until three consecutive steps found their command on time; a late one
    in between starts the count again."""
    pol = CommandPolicy(4, HOLD, delay_samples=0, start_samples=3)
    i = np.ones(4)
    pol.command(i, answered_k=0)
    assert pol.current(1) is None  # the step after sample 0, its answer on time: 1
    assert pol.current(2) is None  # the answer to sample 1 is missing: 0
    for k in (3, 4):
        pol.command(i * k, answered_k=k - 1)
        assert pol.current(k) is None  # on time: 1, 2
    pol.command(i * 5, answered_k=4)
    assert np.array_equal(pol.current(5), i * 5) and pol.state == "ok"  # on time: 3, levitation starts
    assert pol.waiting == 4


def test_on_time_says_when_the_step_before_a_tick_can_be_computed_early():
    """The realtime plant computes the step after sample k - 1 before tick k once ``on_time(k)``: the command
    that answers sample k - 1 - delay has arrived, and ``current(k)`` then returns exactly it."""
    pol = CommandPolicy(4, HOLD, delay_samples=1)
    a, b, c = (np.full(4, v) for v in (1.0, 2.0, 3.0))
    assert not pol.on_time(2)  # nothing in
    pol.command(b, answered_k=1)
    assert not pol.on_time(2)  # the answer to sample 1 is in, but the step after sample 1 needs the one to 0
    assert pol.on_time(3)
    pol.command(a, answered_k=0)  # older than the newest: ignored (it came too late to matter)
    assert not pol.on_time(2)
    assert pol.current(2) is None and pol.current(3) is b  # levitation starts on the answer to sample 1
    pol.command(c, answered_k=3)
    assert not pol.on_time(4)  # the answer to 2 is missing: the tick will hold b
    assert pol.on_time(5) and pol.current(4) is b and pol.state == "holding"
    assert pol.current(5) is c and pol.state == "ok"


def test_the_realtime_plant_holds_the_base_rates_to_first_order_between_imu_samples():
    """base_motion samples the IMU every imu_every ticks; the step after a sample starts with Omega extrapolated by
    dOmega/dt from the IMU sample's arrival to that sample, at most RATES_HOLD_S ahead."""
    om, dom = np.array([1.0, -2.0, 0.5]), np.array([40.0, 0.0, -10.0])
    node = SimpleNamespace(latest_rates=(om, dom), imu_at_ns=None, sample_at_ns=5_000_000)
    np.testing.assert_array_equal(held_rates(node), np.concatenate([om, dom]))  # no IMU yet: as received
    node.imu_at_ns = 3_500_000  # the sample went out 1.5 ms after the IMU sample arrived
    np.testing.assert_allclose(held_rates(node), np.concatenate([om + 1.5e-3 * dom, dom]), rtol=1e-15)
    node.imu_at_ns = 6_000_000  # an IMU sample newer than the step's start: no extrapolation backwards
    np.testing.assert_array_equal(held_rates(node)[:3], om)
    node.imu_at_ns, node.sample_at_ns = 0, 2_000_000_000  # base_motion stopped 2 s ago: held, not ramping
    np.testing.assert_allclose(held_rates(node)[:3], om + RATES_HOLD_S * dom, rtol=1e-15)
    assert RATES_HOLD_S <= 0.02
