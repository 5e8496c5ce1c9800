"""docs/physics.md#checks, the Floquet, sampled-data and Newmark checks of the FE rotor: T16, T18, T19, T20.

Multipliers come from the production paths (``system.periodic_system`` -> ``floquet.floquet`` / ``monodromy``,
``sampled.SampledLoop`` -> ``floquet.sampled_floquet``, ``newmark``); the references are the specification's
claims, an independent DOP853 integration of the same A(t), and the continuous closed loop.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import linear_sum_assignment

from amb_dynamics import floquet, motion, newmark, sampled, structure, system
from physics_helpers import constant_rates, dop853_monodromy, load

FULL = "modal_cutoff=null"
UNDAMPED = "controller.derivative_gain=0"  # c_eq = ki kd = 0


def _loop(*overrides):
    cfg = load(*overrides)
    model = structure.build_structure(cfg)
    return cfg, model, system.closed_loop(model, cfg)


def _rho(Phi: np.ndarray) -> float:
    return float(np.abs(np.linalg.eigvals(Phi)).max())


# ---- T16: periodic roll of the undamped FE rotor is neutrally stable -----------------------------------------
def test_periodic_roll_undamped_rotor_neutral_T16():
    cfg, model, loop = _loop(FULL, UNDAMPED)
    assert model.gains.c_eq == 0.0
    worst = 0.0
    for w in np.arange(1.0, 40.0 + 1e-9, 0.5):
        ps = system.periodic_system(loop, motion.BaseMotion.single("roll", 0.25, w), cfg.spin_rad_s)
        # N0 = 64 (not 128) keeps the 79-point sweep fast; step doubling still has to converge (to 1e-7)
        res = floquet.floquet(ps, N0=64)
        assert res.converged
        mod = np.abs(res.multipliers)
        worst = max(worst, np.abs(mod - 1.0).max())
    assert worst < 1e-8


def test_periodic_roll_undamped_rotor_seed_fails_T16():
    """The seed matrices: max |mu| ~ 1.043 at w = 31.5 (checked as a local maximum of the 0.5 rad/s grid)."""
    cfg, _, loop = _loop(FULL, UNDAMPED, "formulation=seed")
    rho = {
        w: floquet.floquet(
            system.periodic_system(loop, motion.BaseMotion.single("roll", 0.25, w), cfg.spin_rad_s)
        ).max_abs
        for w in (31.0, 31.5, 32.0)
    }
    assert rho[31.5] == pytest.approx(1.043, abs=5e-4)
    assert rho[31.5] > max(rho[31.0], rho[32.0])
    assert floquet.verdict(rho[31.5]) == "unstable"


# ---- T18: Magnus N vs 2N, and vs the DOP853 validation solver ------------------------------------------------
@pytest.mark.parametrize(
    ("kind", "A", "w", "overrides", "validate"),
    [
        ("pitch", 0.4, 15.0, (FULL,), True),
        ("roll", 0.25, 3.0, (FULL,), False),  # DOP853 on the full roll period: ~2e5 stiff RHS calls (~25 s)
        ("roll", 0.25, 3.0, (), True),  # the default config (modal_cutoff 5000 rad/s)
    ],
    ids=["T18-pitch-full", "T18-roll-full", "T18-roll-modal"],
)
def test_magnus_converged_and_validated_T18(kind, A, w, overrides, validate):
    cfg, _, loop = _loop(*overrides)
    ps = system.periodic_system(loop, motion.BaseMotion.single(kind, A, w), cfg.spin_rad_s)
    res = floquet.floquet(ps)
    assert res.converged
    N = res.steps
    rho_2N = _rho(floquet.monodromy(ps, 2 * N))
    assert abs(res.max_abs - rho_2N) < 1e-8
    if validate:
        # A(t) rebuilt from the closed-form rates of docs/physics.md#base-motion (beta = A sin wt about one axis)
        axis = {"roll": 0, "yaw": 1, "pitch": 2}[kind]

        def A_of_t(t):
            Om, dOm = np.zeros(3), np.zeros(3)
            Om[axis], dOm[axis] = A * w * np.cos(w * t), -A * w * w * np.sin(w * t)
            return loop.matrix(system.coefficients_from_rates(Om, dOm, cfg.spin_rad_s))

        Phi = dop853_monodromy(A_of_t, loop.N, ps.period)
        assert abs(res.max_abs - _rho(Phi)) < 1e-8


# ---- T19: the fast digital loop approaches the continuous PD loop ----------------------------------------------
SLOW = 200.0  # rad/s: "the slowest poles" (the three lowest pairs, 15.9, 29.6 and 103.7 rad/s)
REAL_ONLY = 1500.0  # rad/s: real parts also checked up to here (includes the overdamped pole near -1200 1/s)


def _sampled_pole_errors(model, cfg, continuous, Ts):
    """Matched continuous poles -> (relative real error, imaginary error / |lambda|) of ln(mu)/Ts."""
    loop = sampled.SampledLoop(model, cfg, Ts=Ts)
    res = floquet.sampled_floquet(loop, motion.BaseMotion.single("none", 0.0, 0.0), None)
    assert res.period == Ts
    discrete = res.exponents
    cost = np.abs(continuous[:, None] - discrete[None, :])
    rows, cols = linear_sum_assignment(cost)
    matched = discrete[cols[np.argsort(rows)]]
    re_err = np.abs(matched.real - continuous.real) / np.abs(continuous.real)
    im_err = np.abs(matched.imag - continuous.imag) / np.abs(continuous)
    return re_err, im_err


def test_sampled_data_matches_continuous_T19():
    cfg, model, loop = _loop(FULL)
    assert cfg.controller.derivative_filter_hz is None and cfg.controller.delay_samples == 0
    lam = np.linalg.eigvals(loop.matrix(constant_rates([0.0, 0.0, 0.0], cfg.spin_rad_s)))
    lam = lam[np.abs(lam) < REAL_ONLY]
    slow = np.abs(lam) < SLOW
    assert slow.sum() == 6 and (~slow).sum() >= 9
    re4, im4 = _sampled_pole_errors(model, cfg, lam, 4e-6)
    assert re4.max() < 0.01
    assert im4[slow].max() < 1e-5
    re2, im2 = _sampled_pole_errors(model, cfg, lam, 2e-6)
    # the error is proportional to Ts
    np.testing.assert_allclose(re4 / re2, 2.0, rtol=0.1)
    np.testing.assert_allclose(im4[slow] / im2[slow], 2.0, rtol=0.1)


# ---- T20: Newmark average acceleration vs Floquet at an unstable pitch point -----------------------------------
T20_W = 29.0  # rad/s: rho = 1.0201 on the A = 0.4 pitch chart of the full model (critical at arg mu = pi)


@pytest.fixture(scope="module")
def t20_system():
    cfg, model, loop = _loop(FULL)
    ps = system.periodic_system(loop, motion.BaseMotion.single("pitch", 0.4, T20_W), cfg.spin_rad_s)
    res = floquet.floquet(ps)
    assert res.converged and res.verdict == "unstable"
    return model, loop, ps, res


@pytest.mark.parametrize(("steps", "tol"), [(200, 2e-3), (400, 5e-4)], ids=["T20-map-200", "T20-map-400"])
def test_newmark_period_map_T20(t20_system, steps, tol):
    model, _, ps, res = t20_system
    rho_nm = _rho(newmark.newmark_period_map(ps, model.M, steps))
    assert abs(np.log(rho_nm) / np.log(res.max_abs) - 1) < tol


def test_newmark_free_response_growth_T20(t20_system):
    model, loop, ps, res = t20_system
    mod = np.abs(res.multipliers)
    ratio = mod[mod < mod[0] * (1 - 1e-9)][0] / mod[0]  # largest subdominant / dominant
    k0 = int(np.ceil(np.log(1e-2) / np.log(ratio)))  # periods until the subdominant part decayed by 1e-2
    steps = 100  # h = T/100 << 2 pi/(40 w_j) for the resonant mode
    x0 = newmark.disk_initial_state(model, loop.N, node=7)
    run = newmark.newmark(ps, model.M, x0, ps.period / steps, steps * (k0 + 60), every=steps)
    norms = np.linalg.norm(run.x, axis=1)
    sigma_nm = np.polyfit(run.t[k0:], np.log(norms[k0:]), 1)[0]
    sigma_f = np.log(res.max_abs) / ps.period
    assert abs(sigma_nm / sigma_f - 1) < 0.02
