"""ISO 14839-2 grade of the end of a run: the trailing window's vibration, not the start-up transient's."""

from __future__ import annotations

import numpy as np
import pytest

from amb_dynamics.config import load_config, paper_config_path
from amb_dynamics.errors import InputError
from amb_dynamics.iso14839 import TrailingPeaks, clearance_of, vibration_zones


def test_trailing_window_forgets_the_start():
    Ts = 1e-3
    t = np.arange(5000) * Ts
    # a 200 um start transient that decays in ~0.3 s, then a 30 um / 10 um steady vibration
    y = np.column_stack([200e-6 * np.exp(-t / 0.05) + 30e-6 * np.sin(60 * t), 10e-6 * np.cos(60 * t) + 5e-6])
    tp = TrailingPeaks(2, Ts, window_s=1.0, blocks=4)
    for row in y:
        tp.add(row)
    zero_peak, p2p = tp.values()
    tail = y[-tp.covered :]
    assert tp.covered == 1250  # 4 completed quarter-second blocks and the current one, full at t = 5 s
    assert np.allclose(zero_peak, np.abs(tail).max(axis=0)) and np.allclose(p2p, np.ptp(tail, axis=0))
    assert zero_peak[0] == pytest.approx(30e-6, rel=1e-3) and zero_peak[1] == pytest.approx(15e-6, rel=1e-3)
    # the whole record (vibration_zones on all samples) still sees the transient
    whole = vibration_zones({"a": y[:, 0]}, 1e-4, (0.3, 0.4, 0.5))["a"]
    assert whole.zone == "D" and whole.displacement_m > 150e-6
    end = tp.zones(("a", "b"), 1e-4, (0.3, 0.4, 0.5))
    assert end["a"].zone == "A" and end["a"].ratio == pytest.approx(0.30, rel=1e-2)  # on the A/B boundary
    assert tp.zones(("a", "b"), 1e-4, (0.3, 0.4, 0.5), "peak_to_peak")["a"].zone == "D"  # 60 um p-p = 0.6 C_min
    with pytest.raises(InputError):
        tp.zones(("a", "b"), 1e-4, (0.3, 0.4, 0.5), "rms")


def test_c_min_defaults_to_the_touchdown_clearance():
    assert clearance_of(load_config(None)) == pytest.approx(1.0e-3)  # the real rig's backup bearings
    assert clearance_of(load_config(None, ["iso14839.touchdown_clearance=8e-4"])) == pytest.approx(8e-4)
    assert clearance_of(load_config(paper_config_path())) is None  # the paper's rotor has none: no zone


def test_offline_rig_run_grades_its_last_second(venv_bin):
    import json
    import subprocess

    from amb_dynamics.iso14839 import zone_of

    out = subprocess.run([str(venv_bin / "amb-dynamics"), "simulate", "--sampled", "--duration", "1.2", "--motion",
                          "none", "--json"], capture_output=True, text=True, timeout=300)  # fmt: skip
    assert out.returncode == 0, out.stderr[-2000:]
    data = json.loads(out.stdout)
    zones = data["vibration_last_s"]
    assert set(zones) == set(data["peak_displacement_m"])
    for axis, z in zones.items():
        # the unbalance response at 1000 rpm: micrometres, well inside zone A of the 1.0 mm backup clearance
        assert 1e-6 < z["displacement_m"] <= data["peak_displacement_m"][axis]
        assert z["ratio_to_c_min"] == pytest.approx(z["displacement_m"] / 1.0e-3, rel=1e-12)
        assert z["zone"] == zone_of(z["ratio_to_c_min"], (0.3, 0.4, 0.5)) == "A"
