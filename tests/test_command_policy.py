"""The realtime plant's command policy (amb_plant.sensor.CommandPolicy): nothing applied before the controller's
first command (the rotor is held at its start state), then fresh, held and zero current by the age of the newest
command counted in samples the plant published (the rotor's own time), not in wall-clock ticks."""

import numpy as np

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
