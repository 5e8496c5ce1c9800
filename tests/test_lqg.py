"""The real rig's model-based controllers (amb_dynamics.lqg, issue 19): config/seed_rotor_2khz_lqg.yaml (2 kHz, one
sample of delay) and config/seed_rotor_1khz_lqg.yaml (1 kHz, no delay, the current's increment weighed).

The design is checked against a second implementation (the Riccati equations solved by doubling and the textbook
observer recursion run sample by sample); the shipped file against a fresh design; the
loop it closes by the digital loop's step map about the levitated operating point (amb_dynamics.preflight, the
check amb-rig runs) over the speed
range and the perturbed plants, with and without the one sample of delay it is designed for; and in the time
domain by the rig's own stepping code with every nonlinear effect (a 50 um kick settles); a lockstep amb-rig run
of each file is in tests/test_controller_2khz.py.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from test_controller_2khz import RIG_2KHZ, VARIANTS, _kicked, controller_search

from amb_dynamics.analysis_sensitivity import model_sensitivity
from amb_dynamics.config import load_config, paper_config_path
from amb_dynamics.errors import InputError
from amb_dynamics.lqg import LqgWeights, lqg_controller
from amb_dynamics.motion import BaseMotion
from amb_dynamics.preflight import digital_at_rest
from amb_dynamics.rig_loop import simulate_rig
from amb_dynamics.sensitivity import sampled_plant_state_space
from amb_dynamics.structure import build_structure

REPO = Path(__file__).resolve().parents[1]
LQG = REPO / "config" / "seed_rotor_2khz_lqg.yaml"
LQG_1KHZ = REPO / "config" / "seed_rotor_1khz_lqg.yaml"
# (file, rate, delay_samples, the design's weights beyond tools/lqg_design.py's defaults): its command line
SHIPPED = [(LQG, 2000.0, 1, {}), (LQG_1KHZ, 1000.0, 0, {"increment_weight": 10.0, "sensor_noise_m": 5e-6})]
IDS = ["2khz", "1khz"]
sys.path.insert(0, str(REPO / "tools"))
import lqg_design  # noqa: E402  (tools/ is not a package)


def _riccati_doubling(F, G, Q, R, tol=1e-12, max_iter=100):
    """X = Q + F^T X F - F^T X G (R + G^T X G)^-1 G^T X F by the structure-preserving doubling algorithm (Chu, Fan,
    Lin 2005): H_k is the cost of a horizon of 2^k steps, so it converges in tens of steps; a different algorithm
    from scipy's Schur-vector solver."""
    A, S, H = F.copy(), G @ np.linalg.solve(R, G.T), Q.copy()
    I = np.eye(F.shape[0])
    for _ in range(max_iter):
        W = np.linalg.inv(I + S @ H)
        A, S, H_next = A @ W @ A, S + A @ W @ S @ A.T, H + A.T @ H @ W @ A
        S, H_next = 0.5 * (S + S.T), 0.5 * (H_next + H_next.T)
        if np.abs(H_next - H).max() <= tol * np.abs(H_next).max():
            return H_next
        H = H_next
    raise AssertionError("the doubling did not converge")


def test_the_controller_is_the_textbook_lqg_recursion_with_independently_computed_gains():
    """On the paper rotor at 1 kHz (56 states + 4 delay + 4 low-pass states): L and M from Riccati equations
    solved by doubling, then x_k|k = x_k|k-1 + M (y_k - H x_k|k-1), u_k = -L x_k|k, x_k+1|k = F x_k|k + G u_k
    run on random y."""
    cfg = load_config(paper_config_path(), ["controller.rate_hz=1000", "controller.delay_samples=1"])
    model = build_structure(cfg)
    w = LqgWeights(output_weight=1e9, low_frequency_weight=1e10, low_frequency_corner_hz=5.0, velocity_weight=10.0,
                   input_noise_a=1.0, sensor_noise_m=1e-6, speed_noise=0.0,
                   design_speed_rpm=cfg.spin_speed_rpm)  # fmt: skip
    K = lqg_controller(model, cfg, w)
    P = sampled_plant_state_space(model, cfg, 1e-3, cfg.spin_speed_rpm)
    n, m = P.B.shape
    a = np.exp(-2 * np.pi * 5.0 * 1e-3)
    # [x; i_k-1; z]: x_k+1 = F x_k + G i_k-1, i_k = u_k, z_k+1 = a z_k + (1 - a) y_k
    F = np.block([[P.A, P.B, np.zeros((n, m))],
                  [np.zeros((m, n + 2 * m))],
                  [(1 - a) * P.C, np.zeros((m, m)), a * np.eye(m)]])  # fmt: skip
    G = np.vstack([np.zeros((n, m)), np.eye(m), np.zeros((m, m))])
    H = np.hstack([P.C, np.zeros((m, 2 * m))])
    na = n + 2 * m
    Q = w.output_weight * H.T @ H
    vel = np.arange(model.n, 2 * model.n)
    Q[vel, vel] += w.velocity_weight
    Q[n + m :, n + m :] += w.low_frequency_weight * np.eye(m)
    Q += 1e-14 * np.trace(Q) / na * np.eye(na)
    X = _riccati_doubling(F, G, Q, np.eye(m))
    L = np.linalg.solve(np.eye(m) + G.T @ X @ G, G.T @ X @ F)
    W = np.zeros((na, na))
    W[:n, :n] = w.input_noise_a**2 * P.B @ P.B.T
    W += 1e-24 * np.eye(na)
    V = w.sensor_noise_m**2 * np.eye(m)
    Y = _riccati_doubling(F.T, H.T, W, V)
    M = Y @ H.T @ np.linalg.inv(H @ Y @ H.T + V)
    rng = np.random.default_rng(3)
    ys = 1e-5 * rng.standard_normal((200, m))
    x_pred, xc = np.zeros(na), np.zeros(na)
    for y in ys:
        x_f = x_pred + M @ (y - H @ x_pred)
        u_ref = -L @ x_f
        x_pred = F @ x_f + G @ u_ref
        u = K.C @ xc + K.D @ y
        xc = K.A @ xc + K.B @ y
        assert np.allclose(u, u_ref, rtol=1e-6, atol=1e-9 * np.abs(u_ref).max()), (u, u_ref)


def test_the_increment_form_is_the_textbook_recursion_too():
    """Without delay, with the current's increment weighed (increment_weight): on the paper rotor at 1 kHz, the
    state [x; i_k-1; z] with the increment as input, gains from Riccati equations solved by doubling, then
    x_k|k = x_k|k-1 + M (y_k - H x_k|k-1), du_k = -L x_k|k, i_k = (i_k-1)_k|k + du_k, x_k+1|k = F x_k|k + G du_k."""
    cfg = load_config(paper_config_path(), ["controller.rate_hz=1000", "controller.delay_samples=0"])
    model = build_structure(cfg)
    w = LqgWeights(output_weight=1e9, low_frequency_weight=1e10, low_frequency_corner_hz=5.0, velocity_weight=10.0,
                   input_noise_a=1.0, sensor_noise_m=1e-6, speed_noise=0.0, design_speed_rpm=cfg.spin_speed_rpm,
                   delay_samples=0, increment_weight=7.0)  # fmt: skip
    K = lqg_controller(model, cfg, w)
    P = sampled_plant_state_space(model, cfg, 1e-3, cfg.spin_speed_rpm)
    n, m = P.B.shape
    a = np.exp(-2 * np.pi * 5.0 * 1e-3)
    I, Z = np.eye(m), np.zeros((m, m))
    F = np.block([[P.A, P.B, np.zeros((n, m))], [np.zeros((m, n)), I, Z], [(1 - a) * P.C, Z, a * I]])
    G = np.vstack([P.B, I, Z])  # du acts at once on the plant and on the stored current
    H = np.hstack([P.C, np.zeros((m, 2 * m))])
    na = n + 2 * m
    Q = w.output_weight * H.T @ H
    vel = np.arange(model.n, 2 * model.n)
    Q[vel, vel] += w.velocity_weight
    Q[n : n + m, n : n + m] += I  # the current itself
    Q[n + m :, n + m :] += w.low_frequency_weight * I
    Q += 1e-14 * np.trace(Q) / na * np.eye(na)
    R = 7.0 * I
    X = _riccati_doubling(F, G, Q, R)
    L = np.linalg.solve(R + G.T @ X @ G, G.T @ X @ F)
    W = np.zeros((na, na))
    W[:n, :n] = w.input_noise_a**2 * P.B @ P.B.T
    W += 1e-24 * np.eye(na)
    V = w.sensor_noise_m**2 * I
    Y = _riccati_doubling(F.T, H.T, W, V)
    M = Y @ H.T @ np.linalg.inv(H @ Y @ H.T + V)
    rng = np.random.default_rng(4)
    x_pred, xc = np.zeros(na), np.zeros(na)
    for y in 1e-5 * rng.standard_normal((200, m)):
        x_f = x_pred + M @ (y - H @ x_pred)
        du = -L @ x_f
        u_ref = x_f[n : n + m] + du
        x_pred = F @ x_f + G @ du
        u = K.C @ xc + K.D @ y
        xc = K.A @ xc + K.B @ y
        assert np.allclose(u, u_ref, rtol=1e-6, atol=1e-9 * np.abs(u_ref).max()), (u, u_ref)


@pytest.mark.parametrize("path, rate, delay, weights", SHIPPED, ids=IDS)
def test_the_shipped_file_is_the_design_of_its_weights(path, rate, delay, weights):
    """Each shipped file is tools/lqg_design.py's output: a fresh design with the tool's default weights and the
    file's rate, delay and own weights gives the same controller (frequency response to 1e-6)."""
    shipped = load_config(path)
    assert (shipped.controller.rate_hz, shipped.controller.delay_samples) == (rate, delay)
    A, B, C, D = shipped.controller.state_space.matrices()
    cfg = load_config(REPO / "config" / "seed_rotor.yaml", [f"controller.rate_hz={rate}",
                                                             f"controller.delay_samples={delay}"])  # fmt: skip
    K = lqg_controller(build_structure(cfg), cfg, LqgWeights(**{**lqg_design.WEIGHTS, **weights},
                                                              delay_samples=delay))  # fmt: skip
    for f in (1.0, 17.0, 120.0, 0.24 * rate, 0.475 * rate):
        z = np.exp(2j * np.pi * f / rate)
        H1 = C @ np.linalg.solve(z * np.eye(len(A)) - A, B) + D
        H2 = K.C @ np.linalg.solve(z * np.eye(K.A.shape[0]) - K.A, K.B) + K.D
        assert np.abs(H1 - H2).max() <= 1e-6 * np.abs(H2).max(), f


@pytest.mark.parametrize("path, rate, delay, weights", SHIPPED, ids=IDS)
@pytest.mark.parametrize("variant", VARIANTS, ids=lambda v: v[0] if v else "nominal")
def test_the_lqg_loop_is_stable_over_the_speed_range_and_the_perturbed_plants(variant, path, rate, delay, weights):
    """The step map of the loop about the levitated operating point (amb-rig's preflight, gravity and bias offsets
    on the nonlinear law: the point the rig runs at) from 0 to 3000 rpm every 250 rpm, and the design tool's own
    check (controller_search.judge) on the same plants; its sensitivity peak stays below 45 (zone D: above 5)."""
    for rpm in np.arange(0.0, 3001.0, 250.0):
        cfg = load_config(path, [*variant, f"spin_speed_rpm={rpm}"])
        d = digital_at_rest(build_structure(cfg), cfg)
        assert d["rate_hz"] == rate and d["delay_samples"] == delay and d["stable"], (variant, rpm, d)
    radius, peak = controller_search.judge([], np.arange(0.0, 3001.0, 250.0), [variant], path=path)
    assert radius < 1.0 - 1e-6 and peak < 45.0, (variant, radius, peak)


def test_the_preflight_linearises_the_bearing_where_the_rotor_rests():
    """At 3000 rpm the preflight's spectral radius is the step map's about the operating point, built here from
    the tangent of the bearing law (amb_dynamics.operating_point), and amb-rig accepts the run.  Linearised at the
    bearing centre instead (the unloaded bias point, no gravity) the same loop has a 114 Hz mode at 1.0013 per
    sample: the two linearisations differ, and the rig runs at the first."""
    from amb_dynamics.operating_point import operating_point, tangent_gains
    from amb_dynamics.preflight import rig_preflight
    from amb_dynamics.rig_loop import start_gain
    from amb_dynamics.sampled import SampledLoop

    cfg = load_config(LQG, ["spin_speed_rpm=3000"])
    model = build_structure(cfg)
    Ts = 1.0 / cfg.controller.rate_hz
    op = operating_point(model, cfg, start_gain(cfg, model.gains, Ts))
    assert np.abs(op.i[[0, 2]]).min() > 1.0  # gravity loads the y axes: the tangent is not the centre's
    rest = SampledLoop(model, cfg, Ts=Ts, forcing=False, bearing=tangent_gains(cfg, op))
    mu = np.abs(np.linalg.eigvals(rest.step_map(np.zeros(3), np.zeros(3)))).max()
    assert digital_at_rest(model, cfg)["spectral_radius_per_sample"] == pytest.approx(mu, rel=1e-12)
    assert mu < 1.0 - 1e-6 and rig_preflight(cfg)[0]
    centre = SampledLoop(model, cfg, Ts=Ts, forcing=False).step_map(np.zeros(3), np.zeros(3))
    w = np.linalg.eigvals(centre)
    k = int(np.argmax(np.abs(w)))
    assert abs(w[k]) == pytest.approx(1.0013, abs=2e-4)
    assert abs(np.angle(w[k])) / (2 * np.pi * Ts) == pytest.approx(114.0, abs=3.0)


@pytest.mark.parametrize("path, rate, delay, weights", SHIPPED, ids=IDS)
def test_the_design_needs_the_delay_it_was_made_for(path, rate, delay, weights):
    """With the other delay the same controller is unstable (the 2 kHz one without its sample of delay, the 1 kHz
    one with a sample): the realtime plant applies each command exactly as delay_samples says, not whenever it
    arrives (amb_plant.sensor)."""
    cfg = load_config(path, [f"controller.delay_samples={1 - delay}"])
    assert not digital_at_rest(build_structure(cfg), cfg)["stable"]


def test_its_sensitivity_peak_is_below_the_2khz_pd():
    """The largest |S_jj| from 0.5 Hz to Nyquist at 0 and 3000 rpm: the LQG's is below the PD's (which needs a
    loop without delay)."""
    peaks = {}
    for path in (LQG, RIG_2KHZ):
        cfg = load_config(path)
        model = build_structure(cfg)
        peaks[path] = max(
            a["peak_abs"]
            for rpm in (0.0, 3000.0)
            for a in model_sensitivity(model, cfg, rpm, "sampled", (0.5, 999.0), 400)["axes"].values()
        )
    assert peaks[LQG] < 0.75 * peaks[RIG_2KHZ], peaks


@pytest.mark.parametrize("path", [LQG, LQG_1KHZ], ids=IDS)
@pytest.mark.parametrize("rpm", [1000.0, 3000.0])
def test_a_kick_settles_on_the_lqg_controller_with_every_effect(rpm, path):
    """The rig's own stepping code with every nonlinear effect (bearing law, gravity, noise, runout, unbalance,
    slew, touchdown) and the one sample of delay: a 50 um kick at AMB5 dies down without touchdown or saturation.

    The kick's own response is the kicked run less the same run without the kick (the noise is seeded, so both see
    the same): at 3000 rpm the unbalance and noise response alone is larger than the kick."""
    cfg, run = _kicked(path, [f"spin_speed_rpm={rpm}"], 1.0)
    assert not run.contacts
    calm = simulate_rig(build_structure(cfg), cfg, BaseMotion(), run.t.size - 1)
    n = round(0.2 * cfg.controller.rate_hz)
    d = run.displacement - calm.displacement
    env = np.array([np.abs(d[i : i + n]).max() for i in range(0, run.t.size - n, n)])
    assert env[0] > 40e-6 and env[2:].max() < 0.05 * env[0]  # 96 um, then 0.1-2 um after 0.4 s
    assert np.abs(run.displacement).max() < 0.3 * cfg.bearings.air_gap
    assert np.abs(run.i).max() < cfg.controller.current_limit  # never saturated: nothing for the observer to miss


def test_bad_weights_are_one_clear_error():
    good = dict(lqg_design.WEIGHTS)
    with pytest.raises(InputError, match="sensor_noise_m"):
        LqgWeights(**{**good, "sensor_noise_m": float("nan")})
    with pytest.raises(InputError, match="delay_samples"):
        LqgWeights(**good, delay_samples=2)
    with pytest.raises(InputError, match="increment_weight needs delay_samples 0"):
        LqgWeights(**good, increment_weight=1.0)  # delay_samples 1 by default
