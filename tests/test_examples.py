"""examples/rotor_tour.py runs, and what it prints agrees with independent results.

* its lowest mode at 1000 rpm with ROSS's (README: -0.011 + 15.870j 1/s, tests/reference/ross_modes.py);
* its chart with its single-point Floquet analysis (Chebyshev-interpolated batch vs adaptive Magnus);
* the chart's A = 0 column with the modes: a base at rest gives rho = exp(max Re(lambda) T), T = pi/omega;
* the digital loop with the continuous one (they differ by O(Ts)).
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def tour():
    out = subprocess.run(
        # the paper's rotor: its lowest mode has an independent value (ROSS) to compare with
        [
            sys.executable,
            str(REPO / "examples" / "rotor_tour.py"),
            "--config",
            str(REPO / "config" / "seed_paper.yaml"),
            "--json",
        ],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=REPO,
    )
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout)


def test_lowest_mode_matches_ross(tour):
    mode = tour["lowest_mode_1000rpm"]
    assert abs(mode["frequency_rad_s"] - 15.870) < 1e-3
    # ROSS: real part -0.011 1/s -> damping ratio 0.011 / 15.870
    assert abs(mode["damping_ratio"] - 0.011 / 15.870) < 0.0005 / 15.870


def test_chart_agrees_with_single_point_floquet(tour):
    chart = tour["chart"]
    i, j = chart["omega_rad_s"].index(24.5), chart["amplitude_rad"].index(0.3)
    assert abs(chart["max_abs_multiplier"][i][j] - tour["floquet"]["max_abs_multiplier"]) < 1e-6


def test_chart_at_rest_is_the_least_damped_mode(tour):
    chart = tour["chart"]
    j = chart["amplitude_rad"].index(0.0)
    for omega, row in zip(chart["omega_rad_s"], chart["max_abs_multiplier"], strict=True):
        expected = math.exp(tour["max_real_part_1000rpm"] * math.pi / omega)
        assert abs(row[j] - expected) < 1e-6


def test_digital_loop_close_to_continuous_and_runs_stay_in_the_gap(tour):
    assert tour["floquet"]["verdict"] == "stable"
    assert abs(tour["floquet_digital"]["max_abs_multiplier"] - tour["floquet"]["max_abs_multiplier"]) < 1e-3
    assert all(math.isfinite(v) for v in tour["newmark_peak_state_at_periods"])
    assert 0 < tour["sampled_peak_displacement_m"] < 2.5e-3  # the seed rotor's air gap
