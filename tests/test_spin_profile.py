"""Spin profile: constant and ramp (run-up and coast-down), against the kinematics written out."""

import numpy as np
import pytest

from amb_dynamics.config import load_config, paper_config_path
from amb_dynamics.spin import spin_state


def test_constant_spin_is_the_paper_speed():
    cfg = load_config(paper_config_path())
    phi, rate, acc = spin_state(cfg, np.array([0.0, 0.5, 2.0]))
    w = 1000 * np.pi / 30
    np.testing.assert_allclose(phi, [0.0, 0.5 * w, 2.0 * w], rtol=1e-15)
    assert np.all(rate == w) and np.all(acc == 0.0)


@pytest.mark.parametrize(("start", "end"), [(0.0, 600.0), (1000.0, 200.0)])
def test_ramp_then_hold(start, end):
    cfg = load_config(
        paper_config_path(), [f"spin={{profile: ramp, start_rpm: {start}, end_rpm: {end}, rate_rpm_s: 50}}"]
    )
    t_end = abs(end - start) / 50.0
    t = np.linspace(0.0, t_end + 3.0, 4001)
    phi, rate, acc = spin_state(cfg, t)
    rpm = rate * 30 / np.pi
    expected = np.where(t < t_end, start + np.sign(end - start) * 50.0 * t, end)
    np.testing.assert_allclose(rpm, expected, atol=1e-9)
    # phi is the integral of the rate (trapezoid on a fine grid), acc its derivative
    trap = np.concatenate([[0.0], np.cumsum((rate[1:] + rate[:-1]) / 2 * np.diff(t))])
    np.testing.assert_allclose(phi, trap, rtol=1e-6, atol=1e-9)
    assert acc[t < t_end] == pytest.approx(np.sign(end - start) * 50 * np.pi / 30)
    assert np.all(acc[t > t_end] == 0.0)
