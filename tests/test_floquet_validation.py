"""Floquet analysis of the seed rotor: Magnus and the fast chart against solve_ivp, Newmark, the digital loop."""

import numpy as np
import pytest

from amb_dynamics import chart
from amb_dynamics.chart import A_NODES, CHART_STEPS, _Row, reduce_to_range, stability_chart
from amb_dynamics.config import load_config, paper_config_path
from amb_dynamics.floquet import floquet, sampled_floquet
from amb_dynamics.motion import BaseMotion
from amb_dynamics.newmark import disk_initial_state, fit_growth_rate, newmark
from amb_dynamics.sampled import SampledLoop
from amb_dynamics.structure import build_structure
from amb_dynamics.system import closed_loop, periodic_system
from amb_dynamics.validation import rho_ivp


def seed_system(*overrides):
    cfg = load_config(paper_config_path(), list(overrides))
    model = build_structure(cfg)
    return cfg, model, closed_loop(model, cfg)


# (kind, formulation, A, omega, expected verdict): one stable and one unstable point per axis.  Derived roll
# with base-fixed AMB damping is never unstable (docs/physics.md#formulations): roll's unstable point is seed's.
CASES = [
    ("pitch", "derived", 0.3, 15.0, "stable"),
    ("pitch", "derived", 0.5, 22.1, "unstable"),
    ("yaw", "derived", 0.3, 24.5, "stable"),
    ("yaw", "derived", 0.5, 28.6, "unstable"),
    ("roll", "seed", 0.25, 3.0, "stable"),
    ("roll", "seed", 0.5, 31.0, "unstable"),
]


@pytest.mark.parametrize(("kind", "form", "A", "w", "expected"), CASES, ids=[f"{c[0]}-{c[4]}" for c in CASES])
def test_magnus_matches_solve_ivp(kind, form, A, w, expected):
    cfg, _, loop = seed_system(f"formulation={form}")
    ps = periodic_system(loop, BaseMotion.single(kind, A, w), cfg.spin_rad_s)
    res = floquet(ps)
    ref = rho_ivp(ps, rtol=1e-11, atol=1e-13)
    assert abs(res.max_abs - ref) <= 1e-7, (res.max_abs, ref)
    assert res.verdict == expected


def test_chart_matches_single_point_floquet():
    cfg, _, loop = seed_system()
    omegas, amps = np.array([15.87, 22.1, 28.6, 37.0]), np.linspace(0.0, 0.5, 26)
    chart = stability_chart(loop, "pitch", omegas, amps, cfg.spin_rad_s, workers=1)
    for i, w in enumerate(omegas):
        for j in (5, 13, 20, 25):
            ps = periodic_system(loop, BaseMotion.single("pitch", amps[j], w), cfg.spin_rad_s)
            assert abs(chart.rho[i, j] - floquet(ps, tol=1e-9).max_abs) <= 1e-6
    assert (chart.rho > 1).any() and (chart.rho < 1).any()


def test_chart_parallel_equals_serial():
    cfg, _, loop = seed_system()
    args = (loop, "roll", np.array([3.0, 7.0, 11.0]), np.array([0.1, 0.25]), cfg.spin_rad_s)
    a = stability_chart(*args, workers=1, steps=64)
    b = stability_chart(*args, workers=2, steps=64)
    np.testing.assert_array_equal(a.rho, b.rho)


def test_newmark_growth_rate_matches_floquet():
    cfg, model, loop = seed_system()
    ps = periodic_system(loop, BaseMotion.single("pitch", 0.5, 22.1), cfg.spin_rad_s)
    T, per = ps.period, 200
    run = newmark(ps, model.M, disk_initial_state(model, loop.N, 7), T / per, 120 * per, every=per)
    sigma, _, _ = fit_growth_rate(run.t, np.linalg.norm(run.x, axis=1))
    sigma_f = np.log(floquet(ps).max_abs) / T
    assert sigma_f > 0.2
    assert abs(sigma - sigma_f) <= 0.01 * sigma_f


def test_sampled_multipliers_converge_to_continuous():
    """Pitch with T = 0.1 s, an integer number of samples at every rate: the error falls like Ts."""
    cfg, model, loop = seed_system()
    motion = BaseMotion.single("pitch", 0.5, np.pi / 0.1)
    rho_c = floquet(periodic_system(loop, motion, cfg.spin_rad_s), tol=1e-10).max_abs
    errors = []
    for rate in (5000.0, 10000.0, 20000.0, 40000.0):
        sl = SampledLoop(model, cfg, Ts=1.0 / rate, forcing=False)
        res = sampled_floquet(sl, motion, 0.1)
        assert res.method.startswith("sampled-product")
        errors.append(abs(res.max_abs - rho_c))
    errors = np.array(errors)
    assert np.all(np.diff(errors) < 0)
    assert errors[-1] < 2e-4
    np.testing.assert_allclose(errors[:-1] / errors[1:], 2.0, rtol=0.15)  # first order in Ts


def test_default_rate_stable_at_rest_with_margin():
    """The paper's digital loop (config/seed_paper.yaml) is stable at rest; the margins printed in the README."""
    cfg, model, _ = seed_system()
    sl = SampledLoop(model, cfg, forcing=False)
    res = sampled_floquet(sl, BaseMotion(), None)
    mu = res.multipliers
    assert res.max_abs < 1.0
    digital = np.abs(mu[np.abs(np.angle(mu)) / sl.Ts > 2000.0])  # modes near Nyquist: the sampling artefacts
    assert digital.max() < 0.95
    slower = SampledLoop(model, cfg, Ts=1.2 / cfg.controller.rate_hz, forcing=False)  # 20 % rate margin
    assert sampled_floquet(slower, BaseMotion(), None).max_abs < 1.0


def test_full_model_digital_artefact_of_physics_3_3():
    """docs/physics.md#modal-cutoff: the full 6-element model with a 10 kHz PD is unstable through its mesh modes."""
    cfg, model, _ = seed_system("modal_cutoff=null")
    for Ts, unstable in ((1e-4, True), (5e-5, True), (2e-5, False)):
        res = sampled_floquet(SampledLoop(model, cfg, Ts=Ts, forcing=False), BaseMotion(), None)
        assert (res.max_abs > 1.0) == unstable
        if unstable:
            assert abs(np.angle(res.multipliers[0])) / Ts > 2e4  # the critical multiplier is a mesh mode


@pytest.mark.parametrize(("kind", "form"), [("pitch", "derived"), ("roll", "seed")])
def test_chart_row_interpolation_matches_every_amplitude_on_the_full_model(kind, form):
    """A continuous chart row on the full FE model (100 amplitudes): the monodromy interpolated from a few
    Chebyshev amplitudes equals each amplitude's own product to 1e-9, and only a few products are formed."""
    cfg = load_config(paper_config_path(), [f"formulation={form}", "modal_cutoff=null"])
    loop = closed_loop(build_structure(cfg), cfg)
    amps = np.linspace(0.0, 0.5, 100)
    row = _Row(loop, kind, cfg.spin_rad_s, amps, CHART_STEPS)
    formed = []
    products = row.monodromies
    row.monodromies = lambda ps, w, a: formed.append(len(a)) or products(ps, w, a)
    for w in (1.0, 15.7, 22.3, 37.0):
        formed.clear()
        rho, crit = row.evaluate(w)
        assert sum(formed) <= 3 * A_NODES + 4, formed  # at most two rounds: n, then 2n nodes (+2 checks each)
        rho_each, crit_each = row.evaluate(w, exact=True)
        assert np.abs(rho - rho_each).max() <= 1e-9
        near = np.abs(rho - 1) > 1e-3  # the critical frequency of a well-separated multiplier
        assert np.abs(crit - crit_each)[near].max() <= 1e-6


@pytest.mark.parametrize("kind", ["pitch", "roll"])
def test_eigenvalues_on_the_numerical_range_equal_the_full_ones(kind, monkeypatch):
    """The chart's eigenvalue problems on the monodromies' common numerical range (r < 56 states) give the rho and
    critical frequency of the full 56 x 56 eigenvalue problems to 1e-12 along whole rows of the full FE model."""
    cfg = load_config(paper_config_path(), ["modal_cutoff=null"])
    loop = closed_loop(build_structure(cfg), cfg)
    amps = np.linspace(0.0, 0.5, 100)
    row = _Row(loop, kind, cfg.spin_rad_s, amps, CHART_STEPS)
    for w in (1.0, 22.3, 40.0):
        ps = periodic_system(loop, BaseMotion.single(kind, 1.0, w), cfg.spin_rad_s)
        P = row.monodromies(ps, w, np.array([0.1, 0.3, 0.5]))
        (Pr,) = reduce_to_range(P)
        assert Pr.shape[-1] < P.shape[-1] * 3 // 4, Pr.shape  # it compresses
        rho, crit = row.evaluate(w)
        monkeypatch.setattr(chart, "RANGE_TOL", 0.0)  # every singular direction kept: the full problem
        rho_full, crit_full = row.evaluate(w)
        monkeypatch.setattr(chart, "RANGE_TOL", 1e-15)
        assert np.abs(rho - rho_full).max() <= 1e-12
        assert np.abs(crit - crit_full).max() <= 1e-9
