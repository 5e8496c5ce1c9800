"""H1/coherence estimator of a measured sensitivity against a known discrete system driven with noise."""

import numpy as np
import pytest
from scipy import signal

from amb_dynamics.errors import InputError
from amb_dynamics.sensitivity_estimate import estimate_sensitivity

FS = 1000.0


def resonant_S(f0=60.0, r_pole=0.97, f_zero=15.0, r_zero=0.995):
    """A discrete S(z) with a resonance (pole pair at f0) and a dip (zero pair at f_zero): b(z)/a(z)."""
    th_p, th_z = 2 * np.pi * f0 / FS, 2 * np.pi * f_zero / FS
    b = np.array([1.0, -2 * r_zero * np.cos(th_z), r_zero**2])
    a = np.array([1.0, -2 * r_pole * np.cos(th_p), r_pole**2])
    return b / b.sum() * a.sum(), a  # |S(1)| = 1


def test_h1_matches_known_system_where_coherent():
    rng = np.random.default_rng(7)
    b, a = resonant_S()
    e = rng.standard_normal(60000)
    noise = 0.5 * rng.standard_normal(e.size)  # uncorrelated with the injection (sensor noise, other loops)
    ym = signal.lfilter(b, a, e) + noise
    m = estimate_sensitivity(e, ym, FS, nperseg=1000, band_hz=(5, 200))
    _, S_true = signal.freqz(b, a, worN=m.frequency_hz, fs=FS)
    good = m.coherence >= 0.9
    assert good.sum() >= 10
    rel = np.abs(m.S[good] - S_true[good]) / np.abs(S_true[good])
    assert rel.max() < 0.05
    # the coherence is an estimate, not 1 by construction: for white E (variance 1) and white noise (0.25) it is
    # |S|^2 / (|S|^2 + 0.25), low in the dip where S is small against the noise
    coh_theory = np.abs(S_true) ** 2 / (np.abs(S_true) ** 2 + 0.25)
    assert coh_theory.min() < 0.5
    assert np.max(np.abs(m.coherence - coh_theory)) < 0.06
    assert m.resolution_hz == pytest.approx(1.0) and m.segments >= 100
    pk = m.peak()
    assert pk["resolved"] and pk["peak_hz"] == pytest.approx(60.0, abs=1.0)
    assert pk["peak_abs"] == pytest.approx(np.abs(S_true).max(), rel=0.05)


def test_sharp_peak_reported_unresolved_until_the_record_resolves_it():
    rng = np.random.default_rng(3)
    b, a = resonant_S(f0=100.0, r_pole=0.9995)  # half-power half-width ~ (1 - r) fs / (2 pi) = 0.08 Hz
    e = rng.standard_normal(400000)
    ym = signal.lfilter(b, a, e)
    coarse = estimate_sensitivity(e, ym, FS, nperseg=500).peak()  # 2 Hz bins
    fine = estimate_sensitivity(e, ym, FS, nperseg=50000).peak()  # 0.02 Hz bins
    assert not coarse["resolved"] and "resolution" in coarse["reason"]
    assert fine["resolved"]
    true_peak = np.abs(signal.freqz(b, a, worN=[fine["peak_hz"]], fs=FS)[1][0])
    assert fine["peak_abs"] == pytest.approx(true_peak, rel=0.1)
    assert coarse["peak_abs"] < 0.7 * fine["peak_abs"]


def test_refuses_single_segment_and_bad_records():
    e = np.random.default_rng(0).standard_normal(1000)
    with pytest.raises(InputError, match="Welch segments"):
        estimate_sensitivity(e, e, FS, nperseg=1000)
    with pytest.raises(InputError, match="equal length"):
        estimate_sensitivity(e, e[:-1], FS)
    bad = e.copy()
    bad[3] = np.nan
    with pytest.raises(InputError, match="NaN"):
        estimate_sensitivity(bad, e, FS)


@pytest.mark.parametrize("segments", [4, 16])
def test_random_error_is_the_scatter_of_repeated_measurements(segments):
    """A periodic multisine (one period per rectangular segment, as amb-rig injects it) through a known resonant S
    with white sensor noise, 400 records with fresh noise and phases: the observed RMS scatter of |S_hat|/|S| - 1
    per bin equals the estimator's ``random_error`` formula evaluated at the true coherence, within 10 %, and the
    reported per-record ``random_error`` (from the estimated coherence) has that size on average (within 20 %:
    4 segments overestimate the coherence)."""
    b, a = resonant_S()
    P, runs, sigma = 500, 400, 0.5
    lines = np.arange(1, P // 2)
    errs, reported = [], []
    for seed in range(runs):
        rng = np.random.default_rng(1000 + seed)
        X = np.zeros(P // 2 + 1, complex)
        X[lines] = np.exp(2j * np.pi * rng.random(lines.size))
        one = np.fft.irfft(X, P)
        e = np.tile(one / one.std(), segments + 2)
        y = signal.lfilter(b, a, e)[2 * P :]  # the periodic steady state
        e = e[2 * P :]
        m = estimate_sensitivity(e, y + sigma * rng.standard_normal(e.size), FS, nperseg=P, band_hz=(5, 200),
                                 window="boxcar", noverlap=0)  # fmt: skip
        _, S_true = signal.freqz(b, a, worN=m.frequency_hz, fs=FS)
        errs.append(m.abs / np.abs(S_true) - 1.0)
        reported.append(m.random_error)
    assert m.segments == segments
    # the true coherence per line, |S|^2 p_E / (|S|^2 p_E + p_N): the unit variance of E spread over its lines,
    # p_E = 1 / lines, and the noise's sigma^2 over the P / 2 bins, p_N = sigma^2 / (P / 2)
    g2 = np.abs(S_true) ** 2 / (np.abs(S_true) ** 2 + sigma**2 * lines.size / (P / 2))
    predicted = np.sqrt(1 - g2) / (np.sqrt(g2) * np.sqrt(2 * segments))
    sel = (g2 > 0.5) & (g2 < 0.97)
    assert sel.sum() >= 5
    observed = np.sqrt(np.mean(np.array(errs)[:, sel] ** 2, axis=0))
    np.testing.assert_allclose(observed, predicted[sel], rtol=0.1)
    # the estimate's own number, from its estimated coherence (biased high for few segments: a smaller error)
    mean_reported = np.mean(np.array(reported)[:, sel], axis=0)
    np.testing.assert_allclose(mean_reported, predicted[sel], rtol=0.2)


def test_a_model_that_is_not_the_rig_is_named_and_noise_is_not():
    """sensitivity_report beside a model: a measurement of the true S (noise only) stays within the noise bound and
    gets no note; against a model 15 % off over the band (a rig that is not the config) the largest difference is
    many random errors and one note names it."""
    from amb_bag.sensitivity import NOISE_BOUND, sensitivity_report

    rng = np.random.default_rng(3)
    b, a = resonant_S()
    e = rng.standard_normal(60000)
    ym = signal.lfilter(b, a, e) + 0.2 * rng.standard_normal(e.size)
    m = estimate_sensitivity(e, ym, FS, nperseg=1000, band_hz=(5, 200))
    _, S_true = signal.freqz(b, a, worN=m.frequency_hz, fs=FS)
    same = sensitivity_report(m, [], "amb1_y", (3.0, 4.0, 5.0), np.abs(S_true))
    assert same["coherent_bins"] >= 50 and same["max_difference_in_random_errors"] < NOISE_BOUND
    assert not any("random errors" in n for n in same["notes"])
    off = sensitivity_report(m, [], "amb1_y", (3.0, 4.0, 5.0), 1.15 * np.abs(S_true))
    assert off["max_difference_in_random_errors"] > 3 * NOISE_BOUND
    assert sum("random errors" in n and "is the rig the config?" in n for n in off["notes"]) == 1
