"""Digital-loop Floquet for any T/Ts: the ratio-interpolation estimate against exact hybrid products, and the chart
kernel (interpolated step maps and amplitudes) against single-point ``sampled_floquet`` (one expm per step).

Config: config/seed_paper.yaml (5 kHz loop, 5000 rad/s modal model).  References are exact products of the step
maps over the hybrid period r T for rational T/Ts = p/r (``floquet.sampled_floquet``), computed independently of
the interpolation in T/Ts and of the chart's Chebyshev interpolation.
"""

from pathlib import Path

import numpy as np
import pytest

from amb_dynamics.config import load_config
from amb_dynamics.digital_chart import _tree_product_into, digital_row
from amb_dynamics.digital_floquet import estimate_point, interpolate_ratio, plan_ratio
from amb_dynamics.floquet import sampled_floquet
from amb_dynamics.motion import BaseMotion
from amb_dynamics.sampled import SampledLoop
from amb_dynamics.structure import build_structure

PAPER = Path(__file__).resolve().parents[1] / "config" / "seed_paper.yaml"
W, A = 22.3, 0.4  # the issue's point: T/Ts = 704.393 at 5 kHz
T = np.pi / W  # pitch: A(t) has period pi/omega


@pytest.fixture(scope="module")
def paper():
    cfg = load_config(PAPER)
    model = build_structure(cfg)
    return cfg, model, SampledLoop(model, cfg, forcing=False)


def exact(paper, x, amplitude=A, omega=W):
    """max|mu| per base period at Ts = T/x by the plain product of one-expm step maps (hybrid period)."""
    cfg, model, _ = paper
    period = np.pi / omega
    loop = SampledLoop(model, cfg, Ts=period / x, forcing=False)
    res = sampled_floquet(loop, BaseMotion.single("pitch", amplitude, omega), period)
    assert res.method.startswith("sampled-product")
    return res.max_abs


@pytest.fixture(scope="module")
def integer_values(paper):
    return {m: exact(paper, m) for m in (703, 704, 705, 706)}


def test_plan_is_exact_for_rational_ratios_and_interpolates_otherwise():
    assert plan_ratio(704.0).kind == "exact" and plan_ratio(704.0).ratios == ((704, 1),)
    assert plan_ratio(704.4).ratios == ((3522, 5),)
    p = plan_ratio(704.3929716569043)
    assert p.kind == "interp" and [m for m, _ in p.ratios] == [703, 704, 705]
    assert [m for m, _ in plan_ratio(704.71234567).ratios] == [704, 705, 706]


def test_interpolation_is_exact_for_a_parabola_and_its_bound_is_the_linear_error():
    f = lambda x: 1.0 + 1e-6 * x + 3e-9 * x * x  # noqa: E731
    ms = [703, 704, 705]
    val, bound = interpolate_ratio(704.3, ms, [f(m) for m in ms])
    assert val == pytest.approx(f(704.3), abs=1e-14)
    lin_err = abs(f(704) + 0.3 * (f(705) - f(704)) - f(704.3))
    assert bound == pytest.approx(2 * lin_err + 1e-11, rel=1e-6)


@pytest.mark.parametrize(("x", "r"), [(704.4, 5), (704.5, 2)])
def test_estimate_within_bound_of_exact_hybrid_product(paper, integer_values, x, r):
    ref = exact(paper, x)  # p = r x steps over r base periods
    ms = [m for m, _ in plan_ratio(x, max_r=1).ratios]  # force the estimate
    est, bound = interpolate_ratio(x, ms, [integer_values[m] for m in ms])
    assert abs(est - ref) <= bound, (est, ref, bound)
    assert bound < 1e-8


def test_issue_point_no_silent_error(paper, integer_values):
    """0.4 rad, 22.3 rad/s at 5 kHz: the estimate is within its bound of the nearby exact rational 704.4 (plus the
    slope over the 0.007 difference in T/Ts), and 1.0234, not the old 40-period Lyapunov value 1.0377."""
    _, _, loop = paper
    data = estimate_point(loop, BaseMotion.single("pitch", A, W), T)
    x = T / loop.Ts
    assert data["sampling_ratio"] == pytest.approx(704.3929716569043)
    assert data["method"].startswith("ratio-interpolation")
    ref = exact(paper, 704.4)
    slope = abs(integer_values[705] - integer_values[704])
    assert abs(data["max_abs_multiplier"] - ref) <= data["error_bound"] + slope * abs(704.4 - x)
    assert data["max_abs_multiplier"] == pytest.approx(1.0234, abs=1e-4)
    assert data["verdict"] == "unstable"
    assert [v for _, v in data["ratio_values"]] == [integer_values[m] for m in (703, 704, 705)]


@pytest.mark.parametrize("x", [700.0, 700.5])
def test_chart_row_equals_single_point_on_commensurate_rows(paper, x):
    """A row of 9 amplitudes (more than the 6 amplitude nodes: interpolation and checks in use)."""
    _, _, loop = paper
    omega = np.pi / (x * loop.Ts)
    amps = np.linspace(0.0, 0.5, 9)
    row = digital_row(loop, "pitch", omega, amps)
    assert row.method == 0
    for j in (2, 5, 8):
        assert abs(row.rho[j] - exact(paper, x, amps[j], omega)) <= 1e-10


def test_chart_row_equals_single_point_estimate(paper):
    _, _, loop = paper
    amps = np.array([0.0, 0.1, 0.2, 0.25, 0.3, 0.35, 0.4, 0.45, 0.5])
    row = digital_row(loop, "pitch", W, amps)
    assert row.method == 1
    point = estimate_point(loop, BaseMotion.single("pitch", 0.4, W), T)
    assert abs(row.rho[6] - point["max_abs_multiplier"]) <= 1e-10
    assert row.bound[6] >= point["error_bound"]


def test_chart_row_with_one_sample_delay_equals_single_point(paper):
    cfg, model, _ = paper
    loop = SampledLoop(model, cfg, delay_samples=1, forcing=False)
    omega = np.pi / (700 * loop.Ts)
    row = digital_row(loop, "pitch", omega, np.array([0.2, 0.45]))
    ref_loop = SampledLoop(model, cfg, delay_samples=1, forcing=False)
    ref = sampled_floquet(ref_loop, BaseMotion.single("pitch", 0.45, omega), np.pi / omega).max_abs
    assert abs(row.rho[1] - ref) <= 1e-10 * ref  # relative: with the delay this loop is unstable at rest
    no_delay = digital_row(SampledLoop(model, cfg, forcing=False), "pitch", omega, np.array([0.45])).rho[0]
    assert abs(no_delay - row.rho[1]) > 1e-6  # the delay changes the answer: it is really in the maps


@pytest.mark.parametrize("n", [1, 2, 7, 64, 45])
def test_buffered_pairwise_product_equals_the_ordered_product(n):
    rng = np.random.default_rng(n)
    S = rng.normal(size=(3, n, 5, 5))
    ref = np.broadcast_to(np.eye(5), (3, 5, 5)).copy()
    for k in range(n):  # S[:, n-1] @ ... @ S[:, 0], one factor at a time
        ref = S[:, k] @ ref
    got = _tree_product_into(S.copy(), np.empty((3, (n + 1) // 2, 5, 5)))
    assert np.abs(got - ref).max() <= 1e-12 * np.abs(ref).max()
