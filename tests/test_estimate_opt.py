"""The estimator under noise on the snapshots: the plateau floor of the rank test and the variable-projection
refinement ('opt'), on synthetic data with known multipliers (no rotor model involved).

Noise on the snapshots (measurement noise, or the fast modes' response to the excitation injection, which is
white on the period-stacked rows) sits in the regressor too: least squares then attenuates the multipliers, and
a noise level the rank test does not know makes every column look like signal.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from amb_dynamics.estimator.fit import fit_period_map, plateau_floor
from amb_dynamics.estimator.refine import refine_fit
from helpers import MU, matched, synthetic


@pytest.mark.parametrize("forcing", ["none", "alternating", 3])
def test_opt_is_exact_on_exact_data(forcing):
    Z = synthetic(MU, 24, forcing=forcing)
    fit = fit_period_map(Z, forcing, method="opt")
    assert fit.method == "opt" and fit.rank == len(MU)
    assert matched(fit.multipliers, MU) < 1e-9


def test_opt_converges_from_a_perturbed_start():
    """Slightly noisy data of known multipliers: the refinement from a DMD start moved by 1e-3 returns to them."""
    Z = synthetic(MU4, 24, forcing="alternating") + 1e-6 * np.random.default_rng(5).standard_normal((60, 24))
    fit = fit_period_map(Z, "alternating", row_noise=1e-6)
    moved = replace(fit, multipliers=fit.multipliers * (1.0 + 1e-3))
    opt = refine_fit(Z, moved, "alternating")
    assert matched(opt.multipliers, MU4) < 1e-6 < matched(moved.multipliers, MU4)


MU4 = MU[:4]  # a growing pair (1.03) and a decaying one (0.9)


def test_plateau_floor_counts_only_the_modes_under_unknown_noise():
    """Noise 50x the stated level: the measurement floor counts every column, the plateau only the 4 modes."""
    Z = synthetic(MU4, 24, forcing="none") + 0.05 * np.random.default_rng(4).standard_normal((60, 24))
    fit = fit_period_map(Z, "none", row_noise=1e-3)
    assert fit.signal_rank == fit.rank == len(MU4)
    s = np.linalg.svd(Z[:, :-1], compute_uv=False)
    assert np.count_nonzero(s > 1.5 * 1e-3 * (60**0.5 + 23**0.5)) == 23  # the measurement floor alone: all
    assert plateau_floor(s, 10) == 0.0  # fewer rows than pairs: no plateau to read


def noisy_fits(method, seeds, noise=4.0):
    """Large white noise on the snapshots of MU4: only the growing pair stands above it."""
    Z0 = synthetic(MU4, 24, forcing="none", seed=1)
    rng = [np.random.default_rng(seed + 500) for seed in seeds]
    return [
        fit_period_map(Z0 + noise * r.standard_normal(Z0.shape), "none", row_noise=noise, method=method) for r in rng
    ]


def test_opt_removes_the_attenuation_of_least_squares():
    """LS pulls rho = 1.03 down by ~0.015 (40 standard errors of the mean); the refinement is unbiased."""
    ls, opt = noisy_fits("ls", range(150)), noisy_fits("opt", range(150))
    rho_ls, rho_opt = np.array([f.rho for f in ls]), np.array([f.rho for f in opt])
    assert all(f.method == "opt" for f in opt) and not np.allclose(rho_ls, rho_opt)
    assert 1.03 - rho_ls.mean() > 10 * rho_ls.std() / np.sqrt(rho_ls.size)
    assert abs(rho_opt.mean() - 1.03) < 3 * rho_opt.std() / np.sqrt(rho_opt.size)
    assert abs(rho_opt.mean() - 1.03) < 0.1 * (1.03 - rho_ls.mean())


def test_opt_standard_error_matches_the_scatter():
    """The Jacobian's standard error of rho equals the scatter of the refined rho within 20 % (LS: ~6x off)."""
    fits = noisy_fits("opt", range(300))
    spread, predicted = np.std([f.rho for f in fits]), np.median([f.rho_std for f in fits])
    assert 0.8 < spread / predicted < 1.2, (spread, predicted)


def test_opt_keeps_the_dmd_fit_when_mode_and_forcing_look_alike():
    """A real multiplier near -1 over a short record is nearly the alternating forcing sequence: no refinement."""
    mu = np.array([-0.97, 0.5, 0.2])
    Z = synthetic(mu, 12, forcing="alternating") + 1e-3 * np.random.default_rng(2).standard_normal((60, 12))
    ls = fit_period_map(Z, "alternating", row_noise=1e-3)
    opt = refine_fit(Z, ls, "alternating")
    assert opt.method == "opt" and np.array_equal(opt.multipliers, ls.multipliers)
