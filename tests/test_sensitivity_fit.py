"""The zone at a peak the measurement cannot resolve, from the design model calibrated to the measured S
(amb_dynamics.sensitivity_fit): a synthetic measurement of a rig whose ki and ks differ from the config's by known
factors, over a band that excludes the peak, gives back those factors and the true peak and zone; a measurement the
model cannot explain gives no zone."""

from __future__ import annotations

import numpy as np
import pytest

from amb_dynamics.analysis_sensitivity import model_sensitivity
from amb_dynamics.config import load_config, paper_config_path
from amb_dynamics.sensitivity import ModalResponse, loop_state_spaces, sensitivity_state_space
from amb_dynamics.sensitivity_fit import _scaled, fit_sensitivity
from amb_dynamics.structure import build_structure

CASES = {"paper_1khz": (paper_config_path(), ["controller.rate_hz=1000", "modal_cutoff=800"]), "real_rig": (None, [])}


def measured(model, cfg, ki_scale, ks_scale, f, noise=0.005, seed=0):
    m, c = _scaled(model, cfg, ki_scale, ks_scale)
    S = ModalResponse.of(sensitivity_state_space(*loop_state_spaces(m, c, cfg.spin_speed_rpm, "sampled")))(
        2 * np.pi * f
    )[:, 0, 0]
    rng = np.random.default_rng(seed)
    return S * (1 + noise * (rng.standard_normal(f.size) + 1j * rng.standard_normal(f.size))), (m, c)


@pytest.mark.parametrize("case", sorted(CASES))
def test_calibrated_model_recovers_the_rig_and_its_peak(case):
    path, sets = CASES[case]
    cfg = load_config(path, sets)
    model = build_structure(cfg)
    f = np.arange(10.0, 41.0)  # the first mode (2.5 Hz) is outside the measured band
    S, (m_true, c_true) = measured(model, cfg, 1.08, 0.93, f)
    fit = fit_sensitivity(model, cfg, 0, f, S)
    assert fit["good"] and fit["rms_rel_residual"] < 0.01
    assert fit["ki_scale"] == pytest.approx(1.08, rel=0.01) and fit["ks_scale"] == pytest.approx(0.93, rel=0.01)
    hi = min(500.0, 0.45 * cfg.controller.rate_hz)
    truth = model_sensitivity(m_true, c_true, cfg.spin_speed_rpm, "sampled", (1.0, hi), 2000)["axes"]["amb1_y"]
    assert fit["peak_hz"] == pytest.approx(truth["peak_hz"], rel=2e-3)
    assert fit["peak_abs"] == pytest.approx(truth["peak_abs"], rel=0.01)
    assert fit["zone"] == truth["zone"]


def test_a_measurement_the_model_cannot_explain_gives_no_zone():
    path, sets = CASES["paper_1khz"]
    cfg = load_config(path, sets)
    model = build_structure(cfg)
    f = np.arange(10.0, 41.0)
    S, _ = measured(model, cfg, 1.0, 1.0, f)
    S = S * np.exp(1j * np.linspace(0, 2.0, f.size)) * (1 + 0.4 * np.sin(f))  # phase drift and ripple
    fit = fit_sensitivity(model, cfg, 0, f, S)
    assert not fit["good"] and fit["zone"] is None and "no zone" in fit["reason"]
