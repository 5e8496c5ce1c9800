"""The Monte Carlo's runs a chunk at a time give the numbers of the whole run (stability_monitor.montecarlo).

``RigStepper`` steps ``simulate_rig``'s loop in chunks, ``MonitorFeed`` feeds the monitor's pipeline in chunks,
and ``mc_run(stop_on_flags=True)`` ends a run at the first chunk boundary after both modes have flagged.  Each
must give exactly what the whole run gives: the same arrays, the same estimates, the same flag times.
"""

from __future__ import annotations

import math

import numpy as np

from amb_dynamics.config import load_config
from amb_dynamics.motion import BaseMotion
from amb_dynamics.rig_loop import RigStepper, simulate_rig
from amb_dynamics.structure import build_structure
from stability_monitor.montecarlo import CHUNK_S, MODES, MonitorFeed, mc_run, monitor

TONGUE = ("base_motion.amplitude=0.6", "base_motion.frequency=21.8")  # the real rig's tongue point (bench)


def test_stepper_in_uneven_chunks_equals_simulate_rig():
    cfg = load_config(None)
    model = build_structure(cfg)
    motion = BaseMotion.from_config(cfg.base_motion)
    steps = 700
    whole = simulate_rig(model, cfg, motion, steps)
    stepper = RigStepper(model, cfg, motion, steps)
    for k_end in (1, 250, 251, 699, 5000):
        stepper.advance(k_end)
        part = stepper.run()
        assert part.t.size == min(k_end, steps) + (k_end >= steps)
    assert stepper.closed and stepper.measured == steps + 1
    for name in ("t", "x", "y", "displacement", "i", "spin"):
        np.testing.assert_array_equal(getattr(stepper.run(), name), getattr(whole, name), err_msg=name)


def test_monitor_fed_in_chunks_equals_the_whole_run():
    cfg = load_config(None, list(TONGUE))
    model = build_structure(cfg)
    run = simulate_rig(model, cfg, BaseMotion.from_config(cfg.base_motion), 10000)
    T = math.pi / 21.8
    for sensor_only in (False, True):
        pl, ests, _ = monitor(cfg, model, run, sensor_only, T, "two_periods")
        feed = MonitorFeed(cfg, model.n, sensor_only, T, "two_periods")
        for k_end in (3, 26, 1249, 1250, 7000, run.t.size):  # across tachometer messages (every 25 samples)
            feed.feed(run, k_end)
        assert len(feed.ests) == len(ests) > 10
        assert [e.time for e in feed.ests] == [e.time for e in ests]
        np.testing.assert_array_equal([e.fit.rho for e in feed.ests], [e.fit.rho for e in ests])
        assert sum(e.fit.excited for e in ests) > 10
        assert pl.flag_time is not None and feed.pl.flag_time == pl.flag_time


def test_a_run_stopped_at_its_flags_flags_when_the_whole_run_does():
    T = math.pi / 21.8
    seconds = 2.5  # the flags come after 1.3-2.1 s here (bench: 4.6-7.2 base periods of 0.288 s)
    whole = mc_run(TONGUE, seconds, T, "two_periods", 3)
    early = mc_run(TONGUE, seconds, T, "two_periods", 3, stop_on_flags=True)
    flags = [float(whole[f"{mode}_flag_s"]) for mode in MODES]
    assert all(np.isfinite(flags)) and abs(float(whole["simulated_s"]) - seconds) < 1e-9
    assert [float(early[f"{mode}_flag_s"]) for mode in MODES] == flags
    # it ended at the first chunk boundary after the later flag
    assert max(flags) <= float(early["simulated_s"]) < max(flags) + CHUNK_S
