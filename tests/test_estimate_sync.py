"""The synchronous response (unbalance, runout) in the Floquet estimator: removed, not mistaken for a mode.

At constant spin speed Phi the response of a T-periodic loop to a load e^{i h phi(t)} is e^{i h phi(t)} p(t) with p
T-periodic, so over the period-stacked columns it is the geometric sequence e^{i h Phi T j}: a multiplier of
modulus exactly 1 at the angle h Phi T.  Fitted as a mode it pins rho_hat at 1 for a stable rotor; modelled as
known sequences (cos, sin of h phi_j, phi_j the spin angle at column j) it is removed exactly.

Truth for the rotor cases: ``floquet.sampled_floquet`` of the paper's digital loop (config/seed_paper.yaml with
base forcing) at pitch 0.3 rad, N = 641 (rho = 0.99879) and 0.6 rad, N = 718 (rho = 1.0617); data:
``simulate_rig`` with the G2.5 unbalance of the real-rig config at the disk (1000 rpm), from a 10 um disk start.
"""

from __future__ import annotations

import numpy as np
import pytest

from amb_dynamics.config import load_config, paper_config_path
from amb_dynamics.estimator.fit import fit_period_map
from amb_dynamics.estimator.mapfit import forcing_rank, synchronous_regressors
from amb_dynamics.estimator.stream import EstimatorConfig, estimate_series
from amb_dynamics.fe import dof_index
from amb_dynamics.floquet import sampled_floquet
from amb_dynamics.motion import BaseMotion
from amb_dynamics.rig_loop import simulate_rig
from amb_dynamics.sampled import SampledLoop
from amb_dynamics.structure import build_structure
from helpers import matched, synthetic

STABLE_MU = np.array([0.98 * np.exp(0.7j), 0.98 * np.exp(-0.7j), 0.9 * np.exp(2.1j), 0.9 * np.exp(-2.1j), 0.5, -0.3])
EXACT_TOL = 1e-6  # noise-free multipliers against the model (issue 16)
VISIBLE = 0.1


def with_synchronous(Z, phi, harmonics=1, seed=0):
    """Z plus a response Re(c_h e^{i h phi_j}) per harmonic, c_h random vectors (the rows see the spin)."""
    rng = np.random.default_rng(seed)
    for h in range(1, harmonics + 1):
        c = rng.standard_normal(Z.shape[0]) + 1j * rng.standard_normal(Z.shape[0])
        Z = Z + np.real(c[:, None] * np.exp(1j * h * phi))
    return Z


def test_synchronous_sequences_are_removed_exactly():
    theta = 1.3  # Phi T mod 2 pi
    cols = 24
    E = synchronous_regressors(theta * np.arange(cols), 1, drift=False)
    Z = with_synchronous(synthetic(STABLE_MU, cols, forcing="none"), theta * np.arange(cols))
    fit = fit_period_map(Z, E)
    assert fit.rank == STABLE_MU.size and matched(fit.multipliers, STABLE_MU) < 1e-9
    # fitted as free modes instead, the synchronous response is a pair of modulus 1 at +-theta: rho_hat = 1
    free = fit_period_map(Z, "none")
    assert abs(free.rho - 1.0) < 1e-9 and abs(abs(np.angle(free.multipliers[0])) - theta) < 1e-9


def test_synchronous_sequences_with_the_base_forcing():
    cols = 30
    j = np.arange(cols)
    E = np.vstack([np.where(j % 2 == 0, 1.0, -1.0), synchronous_regressors(2.2 * j + 0.4, 2, drift=False)])
    assert forcing_rank(E, cols - 1) == 5
    Z = with_synchronous(synthetic(STABLE_MU, cols, forcing="alternating", seed=3), 2.2 * j + 0.4, harmonics=2)
    assert matched(fit_period_map(Z, E).multipliers, STABLE_MU) < 1e-9
    # a spin harmonic at 2 pi (a whole number of turns per period) is the constant sequence: counted once
    still = np.vstack([np.ones(cols), synchronous_regressors(2 * np.pi * j, 1, drift=False)])
    assert forcing_rank(still, cols - 1) == 1


def test_drift_terms_follow_a_changing_speed():
    """A speed that changes over the window: amplitude and phase of the synchronous response drift linearly."""
    cols = 40
    j = np.arange(cols)
    phi = 1.1 * j + 0.004 * j**2  # the speed per period rises 1.1 -> 1.41 rad
    E = synchronous_regressors(phi, 1, drift=True)
    assert E.shape == (6, cols)
    Z = synthetic(STABLE_MU, cols, forcing=np.zeros((0, cols)), seed=4)
    rng = np.random.default_rng(4)
    c0, c1 = rng.standard_normal((2, Z.shape[0])) + 1j * rng.standard_normal((2, Z.shape[0]))
    Z = Z + np.real((c0[:, None] + c1[:, None] * j / cols) * np.exp(1j * phi))
    # the snapshots themselves are exact in [V; E]: the refinement's model Z = M V + D E
    from amb_dynamics.estimator.refine import refine_fit

    ls = fit_period_map(Z, E, method="ls")
    assert abs(ls.rho - 0.98) < 0.01  # the map's forcing is only first-order in the drift (seen 0.0012)
    opt = refine_fit(Z, ls, E)
    assert matched(opt.multipliers, STABLE_MU) < 1e-6


@pytest.fixture(scope="module")
def unbalanced(tmp_path_factory):
    text = paper_config_path().read_text()
    disk = "{node: 7, diameter: 0.5, thickness: 0.07}"
    assert disk in text
    path = tmp_path_factory.mktemp("cfg") / "paper_unbalance.yaml"
    path.write_text(text.replace(disk, disk[:-1] + ", balance_grade: 2.5}\nmax_speed_rpm: 3000.0"))
    cfg = load_config(path, ["base_forcing=true"])
    model = build_structure(cfg)
    return cfg, model, SampledLoop(model, cfg)


@pytest.mark.parametrize("case", [(0.3, 641), (0.6, 718)], ids=["stable", "unstable"])
def test_noise_free_rotor_with_unbalance(unbalanced, case):
    cfg, model, loop = unbalanced
    A, N = case
    T = N * loop.Ts
    motion = BaseMotion.single("pitch", A, np.pi / T)
    mu = sampled_floquet(loop, motion, T).multipliers
    q_fe = np.zeros(model.fe.n)
    q_fe[[dof_index(7, 0), dof_index(7, 1)]] = 1e-5
    x0 = np.concatenate([model.from_fe(q_fe), np.zeros(model.n)])
    run = simulate_rig(model, cfg, motion, 24 * N, x0=x0, current_limit=1e6)  # linear: no clamp
    assert np.ptp(run.spin) == 0.0
    phi = run.spin[0] * run.t  # the tachometer's angle at constant speed
    n = model.n
    visible = mu[np.abs(mu) >= VISIBLE]
    assert visible.size >= 6
    for name, S, groups in (("full", run.x[:, : 2 * n], tuple([0] * n + [1] * n)), ("sensor", run.y, None)):
        ecfg = EstimatorConfig(T, loop.Ts, forcing="alternating", scale_groups=groups, noise_std=0.0, window=16,
                               sync_harmonics=1)  # fmt: skip
        fit = estimate_series(run.t, S, ecfg, phi)[-1].fit
        assert matched(fit.multipliers, visible) < EXACT_TOL, name
        assert abs(fit.rho - abs(mu[0])) < EXACT_TOL, name
    if A == 0.3:  # without the synchronous model the stable rotor reads rho = 1 (the unbalance response)
        ecfg = EstimatorConfig(T, loop.Ts, forcing="alternating", noise_std=0.0, window=16)
        rho = estimate_series(run.t, run.y, ecfg)[-1].fit.rho
        assert abs(rho - 1.0) < 1e-6 < abs(rho - abs(mu[0]))
