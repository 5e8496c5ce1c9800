"""The Floquet estimator's numerics on synthetic data with known multipliers (no rotor model involved).

Snapshots z_j = O (sum_l c_l mu_l^j w_l) + forcing_j are built from chosen multipliers; the identification must
return them (to round-off without noise), its standard error must match the scatter it predicts, the verdict
must follow the margin / hysteresis rules, and the base period must come out of angular-velocity samples.
"""

from __future__ import annotations

import numpy as np
import pytest

from amb_dynamics.errors import InputError
from amb_dynamics.estimator.fit import (
    COLLECTING,
    INSUFFICIENT,
    MARGINAL,
    REL_FLOOR,
    STABLE,
    UNSTABLE,
    InstabilityFlag,
    MapFit,
    VerdictPolicy,
    fit_period_map,
    noise_floor,
    plateau_floor,
)
from amb_dynamics.estimator.period import estimate_base_period
from amb_dynamics.estimator.stream import EstimatorConfig, StreamingEstimator, estimate_series
from amb_dynamics.motion import BaseMotion, Harmonic
from helpers import MU, matched, synthetic


@pytest.mark.parametrize("forcing", ["none", "constant", "alternating", 3])
def test_noise_free_fit_is_exact(forcing):
    Z = synthetic(MU, 14, forcing=forcing)
    fit = fit_period_map(Z, forcing)
    assert fit.excited and fit.rank == len(MU) == fit.signal_rank
    assert matched(fit.multipliers, MU) < 1e-9
    assert abs(fit.rho - 1.03) < 1e-10 and fit.rho_std < 1e-8


@pytest.mark.parametrize("noise", [None, 1e-6, 1e-3])
def test_the_noise_floor_is_that_of_the_data_2_norm(noise):
    # the fit skips the SVD of Z where the Frobenius norm shows that its 2-norm cannot change the floor
    Z = synthetic(MU, 14, forcing="constant", noise=noise or 0.0)
    fit = fit_period_map(Z, "constant", row_noise=noise)
    free = Z.shape[1] - 1 - 1  # pairs left once the constant forcing is removed
    exact = noise_floor(noise, Z.shape[0], free, float(np.linalg.norm(Z, 2)))
    assert (exact == REL_FLOOR * np.linalg.norm(Z, 2)) == (noise is None)  # both branches are taken
    if noise is not None:  # noisy data: the innovations' plateau may lie higher
        exact = max(exact, plateau_floor(fit.singular_values, Z.shape[0]))
    assert fit.noise_floor == exact


def test_unmodelled_forcing_is_not_exact():
    """The forcing model matters: alternating data fitted with a constant term leave a visible error."""
    Z = synthetic(MU, 14, forcing="alternating")
    assert matched(fit_period_map(Z, "constant").multipliers, MU) > 1e-3


def process_noise_record(seed, cols=40, m=60):
    """z_j = O x_j with x_{j+1} = A x_j + w_j (innovations), rho(A) = 0.98: the LS model's own assumptions."""
    rng = np.random.default_rng(5)
    mu = np.array([0.98 * np.exp(0.7j), 0.98 * np.exp(-0.7j), 0.9 * np.exp(2.1j), 0.9 * np.exp(-2.1j), 0.5, -0.3])
    V = rng.standard_normal((6, 6)) + 0j
    for k in (0, 2):
        v = rng.standard_normal(6) + 1j * rng.standard_normal(6)
        V[:, k], V[:, k + 1] = v, v.conj()
    A = np.real(V @ np.diag(mu) @ np.linalg.inv(V))
    O = rng.standard_normal((m, 6))
    r = np.random.default_rng(seed + 1000)
    x = r.standard_normal(6)
    Z = np.empty((m, cols))
    for j in range(cols):
        Z[:, j] = O @ x
        x = A @ x + 0.3 * r.standard_normal(6)
    return Z


def test_standard_error_matches_the_scatter_under_process_noise():
    """300 realisations: the spread of rho equals the reported LS standard error within 20 %."""
    fits = [fit_period_map(process_noise_record(seed), "none", max_rank=6) for seed in range(300)]
    spread, predicted = np.std([f.rho for f in fits]), np.median([f.rho_std for f in fits])
    assert abs(np.mean([f.rho for f in fits]) - 0.98) < 0.5 * spread
    assert 0.8 < spread / predicted < 1.2, (spread, predicted)


def test_standard_error_is_conservative_under_measurement_noise():
    """With noise on both snapshot sets the LS covariance over-states the scatter (here about 3x), never under."""
    rhos, stds = [], []
    for seed in range(200):
        Z = synthetic(MU, 16, seed=1) + 2e-3 * np.random.default_rng(seed + 100).standard_normal((60, 16))
        fit = fit_period_map(Z, "alternating", row_noise=2e-3)
        rhos.append(fit.rho)
        stds.append(fit.rho_std)
    spread, predicted = np.std(rhos), np.median(stds)
    assert abs(np.mean(rhos) - 1.03) < 3 * spread
    assert 1.0 < predicted / spread < 5.0, (spread, predicted)


def test_pure_noise_is_insufficient_excitation():
    rng = np.random.default_rng(3)
    for seed in range(20):
        Z = 1e-3 * np.random.default_rng(seed).standard_normal((200, 16)) + rng.standard_normal((200, 1))
        fit = fit_period_map(Z, "constant", row_noise=1e-3)
        assert not fit.excited and fit.reason == "no transient above the noise floor"


def test_a_transient_barely_above_the_floor_identifies_no_map():
    """One decaying mode (mu = 0.9) in measurement noise, at amplitudes from under the floor to far above: a fit
    is excited exactly when its largest singular value is at least MIN_SNR times the floor, and then gives 0.9;
    up to KEEP_FACTOR times the floor it is no direction at all."""
    from amb_dynamics.estimator.fit import KEEP_FACTOR, MIN_SNR

    rng = np.random.default_rng(11)
    o, noise = rng.standard_normal(120), 1e-3 * rng.standard_normal((120, 16))
    weak = 0
    for a in np.geomspace(3e-4, 1e-1, 60):
        Z = a * np.outer(o, 0.9 ** np.arange(16)) + noise
        fit = fit_period_map(Z, "none", row_noise=1e-3)
        ratio = fit.singular_values[0] / fit.noise_floor
        assert fit.excited == (ratio >= MIN_SNR), (a, ratio, fit.reason)
        if KEEP_FACTOR < ratio < MIN_SNR:
            weak += 1
            assert "x the noise floor" in fit.reason
        if ratio <= KEEP_FACTOR:
            assert fit.reason == "no transient above the noise floor"
        if ratio > 2 * MIN_SNR:
            assert abs(fit.rho - 0.9) < 0.02, (a, fit.rho)
    assert weak >= 2  # the gate was met, not only the floor


def test_too_few_periods_and_rank_cap():
    Z = synthetic(MU, 3)
    fit = fit_period_map(Z, "alternating")
    assert not fit.excited and fit.reason == "too few periods"
    fit = fit_period_map(synthetic(MU, 7), "alternating")
    assert fit.rank == 4 and fit.signal_rank == 5 and not fit.resolved and fit.dof == 1  # 5 free pairs, 1 kept


@pytest.mark.parametrize(
    "kwargs",
    [{"method": "svd"}, {"forcing": "sometimes"}, {"forcing": 0}, {"max_rank": 0}],
)
def test_bad_fit_arguments(kwargs):
    with pytest.raises(InputError):
        fit_period_map(synthetic(MU, 10), **kwargs)


def test_nan_snapshots_rejected():
    Z = synthetic(MU, 10)
    Z[3, 4] = np.nan
    with pytest.raises(InputError, match="finite"):
        fit_period_map(Z)


def fake_fit(rho, std=0.001, resolved=True):
    mu = np.array([rho, 0.5], dtype=complex)
    return MapFit(mu, std, np.array([10.0, 1.0]), 0.1, 10, 2 if resolved else 3, 2, 5, "ls")


def test_flag_raises_after_confirmation_and_clears_with_hysteresis():
    flag = InstabilityFlag(VerdictPolicy(margin=0.02, hysteresis=0.02, z=3.0, confirm=2))
    assert flag.update(fake_fit(0.98)) == STABLE
    assert flag.update(fake_fit(1.01)) == MARGINAL  # below the margin
    assert flag.update(fake_fit(1.05)) == MARGINAL and not flag.unstable  # first confirmation only
    assert flag.update(fake_fit(1.05)) == UNSTABLE and flag.unstable
    assert flag.update(fake_fit(0.995)) == UNSTABLE  # rho + 3 std = 0.998 < 1.0: first clear count
    assert flag.update(fake_fit(1.001)) == UNSTABLE  # inside the hysteresis band: count restarts
    assert flag.update(fake_fit(0.99)) == UNSTABLE
    assert flag.update(fake_fit(0.99)) == STABLE and not flag.unstable


def test_flag_needs_confidence():
    flag = InstabilityFlag(VerdictPolicy(confirm=1))
    assert flag.update(fake_fit(1.06, std=0.03)) == MARGINAL  # 1.06 - 3 * 0.03 < 1
    assert flag.update(fake_fit(1.06, std=0.01)) == UNSTABLE


def test_flag_holds_through_missing_information():
    flag = InstabilityFlag(VerdictPolicy(confirm=1))
    empty = MapFit(
        np.zeros(0, complex), np.inf, np.zeros(3), 1.0, 10, 0, 0, 0, "ls", "no transient above the noise floor"
    )
    assert flag.update(empty) == INSUFFICIENT
    few = MapFit(np.zeros(0, complex), np.inf, np.zeros(0), np.nan, 2, 0, 0, 0, "ls", "too few periods")
    assert flag.update(few) == COLLECTING
    flag.update(fake_fit(1.1))
    assert flag.update(empty) == UNSTABLE  # latched


def test_confidence_is_a_probability():
    flag = InstabilityFlag()
    assert flag.confidence(fake_fit(1.0, std=0.01)) == pytest.approx(0.5)
    assert flag.confidence(fake_fit(1.03, std=0.01)) == pytest.approx(0.99865, abs=1e-5)


# ---- streaming: phases, interpolation -----------------------------------------------------------------------
def damped_signal(t, T, channels=4, seed=0):
    """Sum of three damped sinusoids per channel; its one-period multipliers are exp(lambda T)."""
    rng = np.random.default_rng(seed)
    lam = np.array([-0.2 + 7.0j, -1.5 + 23.0j, -4.0 + 61.0j])
    amp = rng.standard_normal((channels, 3)) + 1j * rng.standard_normal((channels, 3))
    S = np.real(np.exp(np.outer(t, lam)) @ amp.T)
    mu = np.exp(np.concatenate([lam, lam.conj()]) * T)
    return S, mu


@pytest.mark.parametrize("ratio", [400.0, 400.37])
def test_stream_recovers_continuous_multipliers(ratio):
    """Whole-sample phases are exact; a non-integer T/Ts goes through interpolation (error ~ (w Ts)^2)."""
    Ts = 1e-3
    T = ratio * Ts
    t = np.arange(int(14 * ratio)) * Ts
    S, mu = damped_signal(t, T)
    cfg = EstimatorConfig(T, Ts, forcing="none", phases=16, window=12, noise_std=0.0)
    est = estimate_series(t, S, cfg)[-1]
    assert est.fit.rank == 6
    assert matched(est.fit.multipliers, mu) < (1e-9 if ratio == int(ratio) else 2e-3)


def test_stream_rejects_bad_samples():
    cfg = EstimatorConfig(0.1, 1e-3, phases=8)
    est = StreamingEstimator(cfg, 4)
    est.push(0.0, np.zeros(4))
    with pytest.raises(InputError, match="shape"):
        est.push(0.001, np.zeros(5))
    with pytest.raises(InputError, match="finite"):
        est.push(0.001, np.array([0.0, np.nan, 0.0, 0.0]))
    with pytest.raises(InputError, match="increase"):
        est.push(0.0, np.zeros(4))


@pytest.mark.parametrize(
    "kwargs",
    [
        {"period": 0.1, "sample_time": 0.0},
        {"period": 1e-4, "sample_time": 1e-3},
        {"period": 0.1, "sample_time": 1e-3, "phases": 200},
        {"period": 0.1, "sample_time": 1e-3, "window": 2},
        {"period": 0.1, "sample_time": 1e-3, "forcing": "weird"},
    ],
)
def test_bad_estimator_config(kwargs):
    with pytest.raises(InputError):
        EstimatorConfig(**kwargs)


# ---- period from the base rates -----------------------------------------------------------------------------
TS = 2e-4


@pytest.mark.parametrize(
    ("motion", "half", "forcing"),
    [
        (BaseMotion.single("pitch", 0.3, np.pi / (641 * TS)), True, "alternating"),
        (BaseMotion.single("yaw", 0.3, 24.5), True, "alternating"),
        (BaseMotion.single("roll", 0.25, 3.0), False, "none"),
        (BaseMotion((Harmonic("pitch", 0.2, 10.0), Harmonic("roll", 0.1, 20.0, 0.3)), "combined"), False, "constant"),
        (BaseMotion((Harmonic("pitch", 0.2, 10.0), Harmonic("yaw", 0.1, 30.0, 0.3)), "combined"), False, "constant"),
    ],
)
def test_period_from_angular_velocity(motion, half, forcing):
    T0 = motion.fundamental_period()
    t = 0.0123 + np.arange(int(3.2 * T0 / TS)) * TS
    Om, _ = motion.angular_velocity(t)
    pe = estimate_base_period(t, Om.T, TS)
    assert pe.base_period == pytest.approx(T0, rel=1e-8)
    assert pe.period == pytest.approx(T0 / 2 if half else T0, rel=1e-8)
    assert pe.forcing == forcing


def test_period_snaps_to_whole_samples():
    motion = BaseMotion.single("pitch", 0.3, np.pi / (641 * TS))
    t = np.arange(4000) * TS
    pe = estimate_base_period(t, motion.angular_velocity(t)[0].T, TS)
    assert pe.snapped and pe.period == 641 * TS


@pytest.mark.parametrize(
    ("Omega", "match"),
    [
        (np.zeros((500, 3)), "does not rotate"),
        (np.column_stack([np.zeros(500), np.zeros(500), np.cos(np.arange(500) * 1e-3)]), "fewer than two"),
        (np.full((500, 3), np.nan), "not finite"),
    ],
)
def test_period_errors(Omega, match):
    with pytest.raises(InputError, match=match):
        estimate_base_period(np.arange(500) * 1e-3, Omega)
