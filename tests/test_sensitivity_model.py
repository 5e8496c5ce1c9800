"""Model sensitivity S_jj against independent computations: the FE model's second-order transfer matrix, an
analytic second-order loop, and the continuous limit of the digital loop."""

import numpy as np
import pytest

from amb_dynamics.config import load_config
from amb_dynamics.fe import assemble
from amb_dynamics.sensitivity import (
    StateSpace,
    discrete_pid_state_space,
    find_peaks,
    loop_state_spaces,
    pid_state_space,
    sensitivity_matrix,
)
from amb_dynamics.structure import build_structure

PAPER = "config/seed_paper.yaml"
CHANNELS = (("amb1_y", 1, 0), ("amb1_z", 1, 1), ("amb5_y", 5, 0), ("amb5_z", 5, 1))  # name, node, v|w


def second_order_S(cfg, speed_rpm, f_hz):
    """S = I - ki c(jw) Ba^T Z_cl^-1 Ba with the closed-loop dynamic stiffness of the assembled FE matrices,
    Z_cl = -w^2 M + jw (Phi G + ki kd Ba Ba^T) + K_B + (ks + ki kp) Ba Ba^T, c = kp + jw kd (ideal PD).

    Derivation: Z_ol q = ki Ba u, u = -c (Ba^T q + E)  =>  Z_cl q = -ki c Ba E,  y_m = E + Ba^T q.
    """
    mats = assemble(cfg).matrices
    M, K, G = mats.mass, mats.shaft_stiffness, mats.gyroscopic
    n = M.shape[0]
    Ba = np.zeros((n, 4))
    for j, (_, node, d) in enumerate(CHANNELS):
        Ba[4 * (node - 1) + d, j] = 1.0
    b, c = cfg.bearings, cfg.controller
    ki, ks, kp, kd = b.current_stiffness, b.displacement_stiffness, c.proportional_gain, c.derivative_gain
    Phi = speed_rpm * np.pi / 30
    BB = Ba @ Ba.T
    w = 2 * np.pi * np.asarray(f_hz, dtype=float)[:, None, None]
    Z = -(w**2) * M + 1j * w * (Phi * G + ki * kd * BB) + K + (ks + ki * kp) * BB
    X = np.linalg.solve(Z, np.broadcast_to(Ba, (Z.shape[0], n, 4)))
    return np.eye(4) - ki * (kp + 1j * w * kd) * (Ba.T @ X)


def zoom_peaks(cfg, speed, lo, hi, n0=16000):
    """Peak of each |S_jj|(f) by one fine log grid and five zooms per axis (no knowledge of the poles)."""
    f0 = np.geomspace(lo, hi, n0)
    v0 = np.abs(np.diagonal(second_order_S(cfg, speed, f0), axis1=1, axis2=2))
    out = []
    for j in range(4):
        f, v = f0, v0[:, j]
        for _ in range(6):
            i = int(v.argmax())
            a, b = f[max(i - 2, 0)], f[min(i + 2, f.size - 1)]
            f = np.linspace(a, b, 201)
            v = np.abs(second_order_S(cfg, speed, f)[:, j, j])
        out.append((float(v.max()), float(f[v.argmax()])))
    return out


@pytest.mark.parametrize("speed", [0.0, 1000.0])
def test_paper_rotor_peaks_match_second_order_fe(speed):
    cfg = load_config(PAPER, ["modal_cutoff=null"])  # the full FE model on both routes
    model = build_structure(cfg)
    plant, ctrl = loop_state_spaces(model, cfg, speed, "continuous")
    f = np.geomspace(1.0, 500.0, 2000)
    S = sensitivity_matrix(plant, ctrl, 2 * np.pi * f)
    peaks = find_peaks(plant, ctrl, 2 * np.pi * f, S, (2 * np.pi, 2 * np.pi * 500))
    # the curve itself, at frequencies away from the sharp peaks
    f_chk = np.geomspace(1.0, 500.0, 37)
    ref = second_order_S(cfg, speed, f_chk)
    core = sensitivity_matrix(plant, ctrl, 2 * np.pi * f_chk)
    d_core, d_ref = np.diagonal(core, axis1=1, axis2=2), np.diagonal(ref, axis1=1, axis2=2)
    assert np.max(np.abs(d_core - d_ref) / np.abs(d_ref)) < 1e-6
    assert np.max(np.abs(core - ref)) < 1e-8  # the cross terms too (S is of order 1)
    for j, (ref_abs, ref_hz) in enumerate(zoom_peaks(cfg, speed, 1.0, 500.0)):
        name = CHANNELS[j][0]
        assert peaks[j].abs == pytest.approx(ref_abs, rel=1e-3), name
        assert peaks[j].hz == pytest.approx(ref_hz, rel=1e-3), name
    # the seed rotor's first mode is barely damped: its peak is far outside zone A (issue 17)
    assert max(p.abs for p in peaks) > 5.0


def _double_integrator(zeta, wn=2 * np.pi * 10):
    """Plant 1/s^2, controller -(wn^2 + 2 zeta wn s): S = s^2/(s^2 + 2 zeta wn s + wn^2)."""
    plant = StateSpace(
        np.array([[0.0, 1.0], [0.0, 0.0]]), np.array([[0.0], [1.0]]), np.array([[1.0, 0.0]]), np.zeros((1, 1))
    )
    ctrl = StateSpace(
        np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), np.array([[-(wn**2)]]), None, np.array([[-2 * zeta * wn]])
    )
    return plant, ctrl


@pytest.mark.parametrize("target", [1.5, 3.5, 4.5, 20.0, 2000.0])
def test_peak_of_analytic_loop_independent_of_grid(target):
    """max|S| = 1/(2 zeta sqrt(1 - zeta^2)) at w = wn/sqrt(1 - 2 zeta^2), found on a 30-point grid."""
    zeta = np.sqrt((1 - np.sqrt(1 - 1 / target**2)) / 2)
    wn = 2 * np.pi * 10
    plant, ctrl = _double_integrator(zeta, wn)
    w = 2 * np.pi * np.geomspace(1.0, 100.0, 30)
    S = sensitivity_matrix(plant, ctrl, w)
    s = 1j * w
    assert np.allclose(S[:, 0, 0], s**2 / (s**2 + 2 * zeta * wn * s + wn**2), rtol=1e-10)
    (peak,) = find_peaks(plant, ctrl, w, S, (w[0], w[-1]))
    assert peak.abs == pytest.approx(target, rel=1e-6)
    assert peak.w == pytest.approx(wn / np.sqrt(1 - 2 * zeta**2), rel=1e-6)


def test_discrete_pid_state_space_matches_its_transfer_function():
    """K(z) = -(kp + kI Ts z/(z-1) + kd b (1 - z^-1)/(1 - a z^-1)), times z^-1 with a one-sample delay."""
    cfg = load_config(PAPER, ["controller.integral_gain=300", "controller.derivative_filter_hz=800"])
    g = build_structure(cfg).gains
    Ts = 1 / 5000
    wf = 2 * np.pi * 800
    a, b = 1 / (1 + wf * Ts), wf / (1 + wf * Ts)
    w = 2 * np.pi * np.array([3.0, 70.0, 900.0, 2400.0])
    z = np.exp(1j * w * Ts)
    K = -(g.kp + g.kI * Ts * z / (z - 1) + g.kd * b * (1 - 1 / z) / (1 - a / z))
    for delay, factor in ((0, 1.0), (1, 1 / z)):
        H = discrete_pid_state_space(g, Ts, delay).freqresp(w)
        assert np.allclose(H[:, 0, 0], K * factor, rtol=1e-10)
        assert np.allclose(H[:, 0, 1], 0.0)
    Hc = pid_state_space(g).freqresp(w)[:, 2, 2]
    s = 1j * w
    assert np.allclose(Hc, -(g.kp + g.kI / s + g.kd * wf * s / (s + wf)), rtol=1e-10)


def test_digital_loop_converges_to_continuous():
    """Peak |S| and the S curve of the sampled loop approach the continuous ones with an error ~ Ts."""
    cfg = load_config(PAPER, ["spin_speed_rpm=1000"])
    model = build_structure(cfg)
    f = np.geomspace(1.0, 200.0, 400)
    w = 2 * np.pi * f
    pc, kc = loop_state_spaces(model, cfg, 1000.0, "continuous")
    Sc = sensitivity_matrix(pc, kc, w)
    peak_c = find_peaks(pc, kc, w, Sc, (w[0], w[-1]))[2].abs
    away = (f > 10) & (f < 200)  # the curve away from the sharp first mode
    peak_err, curve_err = [], []
    for rate in (5000.0, 10000.0, 20000.0, 40000.0):
        c = load_config(PAPER, [f"controller.rate_hz={rate}"])
        ps, ks = loop_state_spaces(model, c, 1000.0, "sampled")
        Ss = sensitivity_matrix(ps, ks, w)
        peak_err.append(abs(find_peaks(ps, ks, w, Ss, (w[0], w[-1]))[2].abs - peak_c) / peak_c)
        curve_err.append(np.max(np.abs(Ss[away] - Sc[away])))
    ratios = np.array(peak_err[:-1]) / np.array(peak_err[1:])
    assert np.all((ratios > 1.7) & (ratios < 2.3)), (peak_err, ratios)
    cr = np.array(curve_err[:-1]) / np.array(curve_err[1:])
    assert np.all((cr > 1.7) & (cr < 2.3)), (curve_err, cr)
    assert peak_err[-1] < 0.02


@pytest.mark.parametrize(
    ("controller", "sets"),
    [
        ("continuous", ["controller.integral_gain=300", "controller.derivative_filter_hz=800"]),
        ("sampled", ["controller.integral_gain=300", "controller.delay_samples=1", "controller.rate_hz=20000"]),
        ("sampled", ["controller.derivative_filter_hz=1500"]),
    ],
)
def test_closed_loop_modes_equal_direct_inverse(controller, sets):
    """S from the closed loop's eigen-decomposition equals (I - P K)^-1 of the separately evaluated plant and
    controller (batched solves), for filtered/integral PIDs and a one-sample delay."""
    cfg = load_config(PAPER, sets)
    plant, ctrl = loop_state_spaces(build_structure(cfg), cfg, 1000.0, controller)
    w = 2 * np.pi * np.geomspace(1.0, 2000.0, 60)
    direct = np.linalg.inv(np.eye(4) - plant.freqresp(w) @ ctrl.freqresp(w))
    assert np.max(np.abs(sensitivity_matrix(plant, ctrl, w) - direct)) < 1e-8 * np.max(np.abs(direct))
