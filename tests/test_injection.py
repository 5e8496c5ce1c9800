"""The sensor-signal injection (ISO 14839-3) through the offline digital loop, estimated and compared with the
frequency-domain model of the same loop; the predicted amplifier current and slew against the simulated ones."""

import numpy as np
import pytest

from amb_dynamics.config import load_config
from amb_dynamics.errors import InputError
from amb_dynamics.injection import Injection, InjectionSpec, overload, predicted_load
from amb_dynamics.sampled import SampledLoop
from amb_dynamics.sensitivity import ModalResponse, loop_state_spaces, sensitivity_state_space
from amb_dynamics.sensitivity_estimate import estimate_sensitivity
from amb_dynamics.structure import build_structure

FS = 1000.0
CFG = ("config/seed_paper.yaml", ["controller.rate_hz=1000", "modal_cutoff=800"])


def simulate_injection(model, cfg, inj, axis, steps):
    """The loop as the controller node runs it: y_m = y + E on one axis, then the discrete PID, ZOH plant."""
    loop = SampledLoop(model, cfg, forcing=False)
    pid = loop.new_controller()
    x = np.zeros(2 * model.n)
    E = inj.values(np.arange(steps))
    ym, cur = np.zeros(steps), np.zeros(steps)
    zero = np.zeros(3)
    for k in range(steps):
        y = loop.plant.output(x)
        y[axis] += E[k]
        ym[k] = y[axis]
        u = pid.step(y)
        cur[k] = u[axis]
        x = loop.plant.step(x, u, zero, zero)
    return E, ym, cur


@pytest.mark.parametrize("axis", [0, 3])
def test_multisine_injection_matches_digital_loop_model(axis):
    cfg = load_config(*CFG)
    model = build_structure(cfg)
    inj = Injection(InjectionSpec("multisine", 20e-6, (5.0, 50.0), 20.0, 0.0, 0.5), FS)
    E, ym, cur = simulate_injection(model, cfg, inj, axis, 20000)
    P = inj.period_samples()
    m = estimate_sensitivity(E[2 * P :], ym[2 * P :], FS, nperseg=P, band_hz=(5, 50), window="boxcar", noverlap=0)
    plant, ctrl = loop_state_spaces(model, cfg, cfg.spin_speed_rpm, "sampled")
    S_model = ModalResponse.of(sensitivity_state_space(plant, ctrl))(2 * np.pi * m.frequency_hz)[:, axis, axis]
    good = m.coherence >= 0.9
    assert good.sum() >= 10 and m.segments >= 4
    assert np.max(np.abs(m.S[good] - S_model[good]) / np.abs(S_model[good])) < 0.05
    # the amplifier current the refusal check predicts, against the simulated steady state
    assert predicted_load(model, cfg, axis, inj).current == pytest.approx(np.abs(cur[2 * P :]).max(), rel=0.05)


def test_predicted_slew_matches_the_simulated_amplifier():
    """Real-rig default (5 kHz, first-order 2 kHz current loop, sensor filter), linear digital loop: a multisine
    over 500-1200 Hz on amb1_y.  The amplifier's slope w_a |i_c - i_a| at the sample instants, simulated step by
    step, against the frequency-domain prediction; 10 um exceeds the amplifier's V/L there, 2 um does not."""
    from amb_dynamics.plant_dynamics import PlantDynamics

    cfg = load_config(None)
    model = build_structure(cfg)
    fs = cfg.controller.rate_hz
    inj = Injection(InjectionSpec("multisine", 2e-6, (500.0, 1200.0), 1.0, 0.0, 10.0, ramp_s=0.02), fs)
    loop = SampledLoop(model, cfg, forcing=False)
    law = loop.new_controller()
    amp, wa = loop.plant.layout.amp, PlantDynamics.from_config(cfg).amplifier_rad_s
    x, zero, steps = np.zeros(loop.plant.layout.N), np.zeros(3), 2000
    E = inj.values(np.arange(steps))
    gap, cur = np.zeros(steps), np.zeros(steps)
    for k in range(steps):
        y = loop.plant.output(x)
        y[0] += E[k]
        u = law.step(y)
        gap[k], cur[k] = u[0] - x[amp][0], u[0]
        x = loop.plant.step(x, u, zero, zero)
    last = slice(steps - 2 * inj.period_samples(), steps)  # steady state: the transients of 0.2 s have decayed
    load = predicted_load(model, cfg, 0, inj)
    assert load.slew == pytest.approx(wa * np.abs(gap[last]).max(), rel=0.02)
    assert load.current == pytest.approx(np.abs(cur[last]).max(), rel=0.02)
    assert overload(load, cfg) is None and load.slew > 0.2 * cfg.actuator.slew_limit  # 2 um: well below, not tiny
    big = Injection(InjectionSpec("multisine", 10e-6, (500.0, 1200.0), 1.0, 0.0, 10.0), fs)
    assert "slew" in overload(predicted_load(model, cfg, 0, big), cfg)


def test_signals_peak_band_and_window():
    for kind in ("multisine", "swept", "stepped"):
        inj = Injection(InjectionSpec(kind, 1e-5, (5.0, 50.0), 10.0, 1.0, 0.5, ramp_s=0.0), FS)
        e = inj.values(np.arange(13000))
        assert np.all(e[:1000] == 0) and np.all(e[11000:] == 0)
        assert np.abs(e).max() == pytest.approx(1e-5, rel=1e-3)
        spec = np.abs(np.fft.rfft(e[1000:11000])) ** 2  # energy
        f = np.fft.rfftfreq(10000, 1 / FS)
        inside = (f >= 4.0) & (f <= 51.0)
        assert spec[inside].sum() > 0.95 * spec.sum(), kind


@pytest.mark.parametrize(
    ("spec", "needle"),
    [
        (InjectionSpec("multisine", 1e-5, (50.0, 5.0)), "empty"),
        (InjectionSpec("swept", 1e-5, (5.0, 600.0)), "Nyquist"),
        (InjectionSpec("multisine", 1e-5, (5.0, 50.0), resolution_hz=0.3), "divide"),
        (InjectionSpec("sweep", 1e-5), "kind"),
        (InjectionSpec("swept", 0.0), "amplitude"),
    ],
)
def test_bad_specs(spec, needle):
    with pytest.raises(InputError, match=needle):
        Injection(spec, FS)


def test_per_sample_value_equals_vectorised():
    for kind in ("multisine", "swept", "stepped"):
        inj = Injection(InjectionSpec(kind, 1e-5, (5.0, 50.0), 3.0, 0.5, 0.5, ramp_s=0.3), FS)
        k = np.arange(0, 4000, 7)
        assert np.allclose([inj.value(int(i)) for i in k], inj.values(k), rtol=0, atol=1e-18), kind
