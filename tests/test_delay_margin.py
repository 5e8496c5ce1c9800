"""The digital loop's delay margin (amb_dynamics.delay_margin): the extra input delay the loop at rest tolerates.

At whole samples of delay the modified-z step map must be the preflight's (SampledLoop, a separate code path); at
fractions of a sample it must be the step map of an independent construction: the plant discretised by scipy's
``cont2discrete`` at a fraction of the period, stepped sample by sample with the command that is active in each
sub-interval (a lifted fast-rate loop), whose product over one period is the slow loop's step map.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.signal import cont2discrete

from amb_dynamics.config import load_config, paper_config_path
from amb_dynamics.control_law import discrete_controller
from amb_dynamics.delay_margin import delay_margin, margin_text, spectral_radius
from amb_dynamics.preflight import digital_at_rest, rig_preflight
from amb_dynamics.sensitivity import plant_state_space
from amb_dynamics.structure import build_structure

REPO = Path(__file__).resolve().parents[1]
RIG = REPO / "config" / "seed_rotor.yaml"
LQG = REPO / "config" / "seed_rotor_2khz_lqg.yaml"


def _loop(path, sets=()):
    cfg = load_config(path, list(sets))
    model = build_structure(cfg)
    Ts = 1.0 / cfg.controller.rate_hz
    return cfg, model, Ts, plant_state_space(model, cfg), discrete_controller(cfg, model.gains, Ts, 0, 4)


def _lifted_radius(P, K, Ts: float, delay_fast: int, N: int) -> float:
    """Spectral radius of the loop whose command answering sample k acts from t_k + delay_fast Ts / N: the plant
    discretised at Ts / N (scipy, ZOH) and stepped N times per sample with the command active in each step."""
    Ef, Gf, *_ = cont2discrete((P.A, P.B, P.C, np.zeros((P.C.shape[0], P.B.shape[1]))), Ts / N, method="zoh")
    n, m = Gf.shape
    nc = K.A.shape[0]
    q = delay_fast // N + 2  # commands kept: u_k-1 ... u_k-q
    size = n + q * m + nc
    U = np.zeros((m, size))  # u_k = Cc xc_k + Dc C x_k
    U[:, :n], U[:, n + q * m :] = K.D @ P.C, K.C

    def command(i):  # u_k-i as a function of the state
        if i == 0:
            return U
        R = np.zeros((m, size))
        R[:, n + (i - 1) * m : n + i * m] = np.eye(m)
        return R

    X = np.eye(n, size)
    for j in range(N):  # at t_k + j Ts/N the active command answers sample k - i, the latest with i N >= delay - j
        X = Ef @ X + Gf @ command(int(np.ceil((delay_fast - j) / N)))
    F = np.zeros((size, size))
    F[:n], F[n : n + m] = X, U
    for i in range(2, q + 1):
        F[n + (i - 1) * m : n + i * m] = command(i - 1)
    F[n + q * m :, :n], F[n + q * m :, n + q * m :] = K.B @ P.C, K.A
    return float(np.abs(np.linalg.eigvals(F)).max())


def test_whole_samples_of_delay_give_the_preflights_loop():
    """The real rig's 5 kHz PD (no delay) and the 2 kHz LQG (one sample): the radius at the loop's own delay, and the
    PD's with one more sample, equal the preflight's (SampledLoop at delay_samples 0 and 1) to 1e-10."""
    cfg = load_config(RIG)
    m = delay_margin(build_structure(cfg), cfg)
    assert m["rho_own"] == pytest.approx(digital_at_rest(build_structure(cfg), cfg)["spectral_radius_per_sample"],
                                         abs=1e-10)  # fmt: skip
    one = load_config(RIG, ["controller.delay_samples=1"])
    rho_one = digital_at_rest(build_structure(one), one)["spectral_radius_per_sample"]
    assert rho_one > 1.05 and m["rho_one_more"] == pytest.approx(rho_one, abs=1e-10)
    lqg = load_config(LQG)
    m2 = delay_margin(build_structure(lqg), lqg)
    assert m2["delay_samples"] == 1
    assert m2["rho_own"] == pytest.approx(digital_at_rest(build_structure(lqg), lqg)["spectral_radius_per_sample"],
                                          abs=1e-10)  # fmt: skip


@pytest.mark.parametrize("path", [paper_config_path(), LQG], ids=["paper", "rig-2khz-lqg"])
@pytest.mark.parametrize("N, M", [(2, 1), (4, 1), (5, 3), (3, 2)])
def test_a_fraction_of_a_sample_agrees_with_a_lifted_fast_rate_loop(path, N, M):
    cfg, _, Ts, P, K = _loop(path)
    d = cfg.controller.delay_samples
    rho = spectral_radius(P, K, Ts, (d + M / N) * Ts)
    assert rho == pytest.approx(_lifted_radius(P, K, Ts, d * N + M, N), abs=1e-9)


@pytest.mark.parametrize("path", [RIG, LQG], ids=["rig-5khz-pd", "rig-2khz-lqg"])
def test_the_margin_is_where_the_loop_becomes_unstable(path):
    """Stable at the loop's own delay and up to the margin, unstable a thousandth of a sample beyond it."""
    cfg, model, Ts, P, K = _loop(path)
    m = delay_margin(model, cfg)
    d = cfg.controller.delay_samples
    extra = m["margin_samples"]
    assert 0.0 < extra < 1.0  # neither loop tolerates a whole sample more: m["rho_one_more"] > 1
    for f in np.linspace(0.0, extra, 6):
        assert spectral_radius(P, K, Ts, (d + f) * Ts) < 1.0
    assert spectral_radius(P, K, Ts, (d + extra + 1e-3) * Ts) > 1.0
    assert m["margin_us"] == pytest.approx(extra * Ts * 1e6)


def test_an_unstable_loop_has_no_margin_and_the_preflight_line_says_the_margin():
    cfg = load_config(RIG, ["controller.delay_samples=1"])  # the 5 kHz PD with one sample of delay: 1.12 per sample
    m = delay_margin(build_structure(cfg), cfg)
    assert m["margin_samples"] == 0.0 and m["rho_own"] > 1.0
    cfg = load_config(LQG)
    ok, line = rig_preflight(cfg)
    assert ok and line.endswith(margin_text(delay_margin(build_structure(cfg), cfg)))
    assert "delay margin 0.1" in line and "beyond its 1" in line  # 0.138 samples (69 us) at 1500 rpm
