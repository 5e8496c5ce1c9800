"""The monitor's window on the real-rig default: 32 periods for a moving base, directions kept 1.3x the floor.

Offline, one Monte Carlo run of the stable default point (pitch 0.3 rad at 24.5 rad/s, model max|mu| 0.99711 per
T = pi/omega), with every disturbance of the config: the plant node's stepping code, then the monitor's pipeline
fed as the node feeds it (stability_monitor.montecarlo).  The issue's accuracy: |rho_hat - rho| <= 0.005 after
32 periods, for the full state and for the four AMB displacements (sensor-only).  The old 16-period window read
the sensor-only estimate low by ~0.007 and scattered by 0.01 on the same data; 32 periods without the 1.3x rule
fitted modes with rho 1.5-2.6 to a few columns' innovations.  A static base keeps 16 periods (a run-up).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from amb_dynamics.config import load_config
from amb_dynamics.estimator import fit as fit_module
from stability_monitor import montecarlo
from stability_monitor.model_check import model_multiplier
from stability_monitor.pipeline import MonitorSettings

T = math.pi / 24.5
SEED = 1001


@pytest.fixture(scope="module")
def stable_run():
    phase = float(np.random.default_rng(SEED).uniform(0.0, 360.0))
    sets = [f"disturbances.seed={SEED}", f"disks.0.unbalance_phase_deg={phase!r}"]
    return montecarlo.simulate(sets, None, 100 * T)


def late_estimates(run, sensor_only: bool, monkeypatch, **settings) -> tuple[np.ndarray, np.ndarray, object]:
    """Times and rho of the excited refits from 32 periods on, and the pipeline, with MonitorSettings fields
    overridden."""
    cfg, model, sim, _ = run

    def settings_with(**kw):
        return replace(MonitorSettings(**kw), **settings)

    monkeypatch.setattr(montecarlo, "MonitorSettings", settings_with)
    pl, ests, _ = montecarlo.monitor(cfg, model, sim, sensor_only, T, "two_periods")
    late = [e for e in ests if e.fit.excited and e.time >= 32 * T]
    return np.array([e.time for e in late]), np.array([e.rho for e in late]), pl


@pytest.mark.parametrize("sensor_only", [False, True], ids=["full", "sensor"])
def test_estimate_after_32_periods_is_the_model_within_0_005(stable_run, sensor_only, monkeypatch):
    rho_model = model_multiplier(load_config(None))[0]
    assert rho_model == pytest.approx(0.99711, abs=1e-5)
    times, late, pl = late_estimates(stable_run, sensor_only, monkeypatch)
    assert pl.flag_time is None
    assert late.size > 400  # 8 refits per period over 68 periods
    assert abs(late[0] - rho_model) <= 0.005, late[0]
    assert abs(np.median(late) - rho_model) <= 0.0025, np.median(late)
    assert np.max(np.abs(late - rho_model)) <= 0.01  # no spurious mode anywhere in the 68 periods
    # the scatter the model check allows: rho's std over the excited refits of the last 32 periods
    last = late[times >= times[-1] - 32 * T]
    assert pl.rho_scatter() == pytest.approx(np.std(last, ddof=1), rel=1e-9)
    if sensor_only:  # the 16-period window on the same data: biased low and twice the scatter
        _, short, _ = late_estimates(stable_run, True, monkeypatch, window=16)
        assert np.median(short) < np.median(late) - 0.003
        assert np.std(short) > 2 * np.std(late)


def test_directions_at_the_floor_fit_spurious_modes(stable_run, monkeypatch):
    """Without the 1.3x rule the 32-period sensor-only window keeps directions just over the floor and fits a
    mode growing by far more than any the loop has (the run is stable: the model's is 0.99711)."""
    monkeypatch.setattr(fit_module, "KEEP_FACTOR", 1.0)
    _, late, _ = late_estimates(stable_run, True, monkeypatch)
    assert late.max() > 1.2


def test_static_base_run_up_needs_the_short_window():
    """A run-up 500 -> 1500 rpm in 20 s on a level base (every disturbance on): the static base's 16 periods of
    0.1 s (the speed moves 80 rpm inside them) raise no flag; the moving base's 32 (160 rpm) flag the stable
    rotor.  The node takes the static window when the base rates show no rotation; here the period is given."""
    ramp = ["spin.profile=ramp", "spin.start_rpm=500", "spin.end_rpm=1500", "spin.rate_rpm_s=50",
            "spin_speed_rpm=500", "base_motion.kind=none"]  # fmt: skip
    cfg, model, sim, _ = montecarlo.simulate(ramp, None, 20.0)
    assert MonitorSettings().static_window == 16 and MonitorSettings().window == 32
    pl, ests, _ = montecarlo.monitor(cfg, model, sim, False, 0.1, "constant", static_base=True)
    excited = [e.fit.rho for e in ests if e.fit.excited]
    assert pl.estimator.cfg.window == 16
    assert len(excited) > 0.9 * len(ests) and pl.flag_time is None, max(excited)
    pl, _, _ = montecarlo.monitor(cfg, model, sim, False, 0.1, "constant")
    assert pl.estimator.cfg.window == 32 and pl.flag_time is not None
