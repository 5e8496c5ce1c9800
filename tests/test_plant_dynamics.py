"""Amplifier lag, sensor anti-alias filter and shaft damping in the continuous and the sampled-data loop.

References are built here independently of amb_dynamics.plant_dynamics:
* continuous: the controller chain C(s) = (kp + kd s) wa/(s + wa) ws/(s + ws) as one transfer function
  (scipy.signal.tf2ss), closed around the open-loop rotor with D_s = beta K_B;
* sampled: the plant discretised by scipy.signal.cont2discrete (ZOH), the backward-difference PD written as its
  own state-space difference equation, the closed-loop step matrix assembled by hand.
"""

from pathlib import Path

import numpy as np
import pytest
import scipy.linalg as sla
from scipy.optimize import linear_sum_assignment
from scipy.signal import cont2discrete, tf2ss

from amb_dynamics.config import load_config
from amb_dynamics.floquet import sampled_floquet
from amb_dynamics.motion import BaseMotion
from amb_dynamics.plant_dynamics import PlantDynamics, structural_damping
from amb_dynamics.sampled import SampledLoop
from amb_dynamics.structure import build_structure
from amb_dynamics.system import closed_loop

PAPER = Path(__file__).resolve().parents[1] / "config" / "seed_paper.yaml"  # every effect off
WA, WS, BETA = 2 * np.pi * 2000.0, 2 * np.pi * 5000.0, 6e-5
RAYLEIGH = ("rayleigh", 0.0, BETA, 0.0)
DYN = PlantDynamics(WA, WS, 1, RAYLEIGH)


def matched_error(a, b):
    cost = np.abs(a[:, None] - b[None, :])
    r, c = linear_sum_assignment(cost)
    return np.max(cost[r, c] / np.maximum(np.abs(a[r]), 1.0))


def rotor(cut="5000.0", rpm=0.0):
    cfg = load_config(PAPER, [f"modal_cutoff={cut}", f"spin_speed_rpm={rpm}"])
    return cfg, build_structure(cfg)


def open_plant(model, beta):
    n, Ba, g = model.n, model.Ba, model.gains
    Minv = sla.inv(model.M)
    Ap = np.block(
        [
            [np.zeros((n, n)), np.eye(n)],
            [
                -Minv @ (model.matrices.shaft_stiffness + g.ks * Ba @ Ba.T),
                -Minv @ (beta * model.matrices.shaft_stiffness),
            ],
        ]
    )
    Bp = np.vstack([np.zeros((n, 4)), Minv @ Ba * g.ki])
    Cp = np.hstack([Ba.T, np.zeros((4, n))])
    return Ap, Bp, Cp


@pytest.mark.parametrize("wa,ws,order", [(WA, WS, 1), (WA, None, 1), (None, WS, 1), (WA, WS, 2)])
def test_continuous_loop_matches_transfer_function_chain(wa, ws, order):
    cfg, model = rotor()
    g = model.gains
    num, den = np.array([g.kd, g.kp]), np.array([1.0])
    if wa is not None:
        num, den = np.polymul(num, [wa]), np.polymul(den, [1.0, wa])
    if ws is not None:
        sens_den = [1.0, ws] if order == 1 else [1.0, np.sqrt(2) * ws, ws * ws]
        num, den = np.polymul(num, [ws**order]), np.polymul(den, sens_den)
    Ac, Bc, Cc, Dc = tf2ss(num, den)
    Ap, Bp, Cp = open_plant(model, BETA)
    Ak, Bk, Ck, Dk = (sla.block_diag(*[X] * 4) for X in (Ac, Bc, Cc, Dc))
    A = np.block([[Ap - Bp @ Dk @ Cp, -Bp @ Ck], [Bk @ Cp, Ak]])
    loop = closed_loop(model, cfg, PlantDynamics(wa, ws, order, RAYLEIGH))
    assert loop.N == A.shape[0]
    assert matched_error(np.linalg.eigvals(loop.A0), np.linalg.eigvals(A)) < 1e-8


def test_paper_loop_unchanged_when_off():
    """All three off: the very same matrices as the paper's loop (no new code path runs)."""
    cfg, model = rotor()
    a = closed_loop(model, cfg).A0
    b = closed_loop(model, cfg, PlantDynamics()).A0
    assert np.array_equal(a, b)
    sa, sb = SampledLoop(model, cfg), SampledLoop(model, cfg, dynamics=PlantDynamics())
    assert np.array_equal(sa.step_map(np.zeros(3), np.zeros(3)), sb.step_map(np.zeros(3), np.zeros(3)))


@pytest.mark.parametrize(
    ("damping", "zeta"),
    [
        (("rayleigh", 3.0, BETA, 0.0), lambda w: 3.0 / (2 * w) + BETA * w / 2),
        (("loss_factor", 0.0, 0.0, 0.02), lambda w: 0.01 + 0 * w),
    ],
)
def test_shaft_damping_ratio_per_mode(damping, zeta):
    """Free-free shaft with D_s: each flexural mode has the stated damping ratio (Rayleigh, or eta/2)."""
    cfg, model = rotor(cut="null")
    n = model.n
    Ds = structural_damping(model, PlantDynamics(damping=damping))
    Minv = sla.inv(model.M)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ model.matrices.shaft_stiffness, -Minv @ Ds]])
    lam = np.linalg.eigvals(A)
    lam = lam[lam.imag > 1.0]
    w = np.abs(lam)
    assert np.allclose(-lam.real / w, zeta(w), rtol=1e-6)
    assert closed_loop(model, cfg, PlantDynamics(damping=damping)).N == 2 * n  # damping adds no state


def test_sampled_loop_matches_cont2discrete_interconnection():
    cfg, model = rotor(rpm=0.0)
    sl = SampledLoop(model, cfg, dynamics=DYN)
    Ts, g, n = sl.Ts, model.gains, model.n
    Ap, Bp, Cp = open_plant(model, BETA)
    # amplifier and sensor states appended by hand: x = [q; q'; ia; yf]
    Z4 = np.zeros((4, 4))
    A = np.block(
        [
            [Ap, Bp, np.zeros((2 * n, 4))],
            [np.zeros((4, 2 * n)), -WA * np.eye(4), Z4],
            [WS * Cp, Z4, -WS * np.eye(4)],
        ]
    )
    B = np.vstack([np.zeros((2 * n, 4)), WA * np.eye(4), Z4])
    C = np.hstack([np.zeros((4, 2 * n + 4)), np.eye(4)])
    Ad, Bd, *_ = cont2discrete((A, B, C, np.zeros((4, 4))), Ts, method="zoh")
    # PD, backward difference: u_k = -(kp y_k + kd (y_k - y_{k-1})/Ts); memory y_{k-1}
    kp, kd = g.kp, g.kd
    Np = A.shape[0]
    F = np.zeros((Np + 4, Np + 4))
    F[:Np, :Np] = Ad - Bd @ ((kp + kd / Ts) * C)
    F[:Np, Np:] = Bd * (kd / Ts)
    F[Np:, :Np] = C
    ref = np.linalg.eigvals(F)
    got = sampled_floquet(sl, BaseMotion(), None).multipliers
    assert matched_error(got, ref) < 1e-8


def test_simulate_matches_step_maps_with_dynamics():
    """The offline simulation and the monodromy's step map are the same linear loop (augmented states included)."""
    cfg, model = rotor()
    sl = SampledLoop(model, cfg, dynamics=DYN)
    x0 = np.zeros(sl.plant.N)
    x0[0] = 1e-4
    run = sl.simulate(BaseMotion(), 50, x0)
    F = sl.step_map(np.zeros(3), np.zeros(3))
    X = np.concatenate([x0, sl.plant.output(x0)])  # memory y_{-1} = y_0
    for _ in range(50):
        X = F @ X
    assert np.allclose(X[: sl.plant.N], run.x[-1], rtol=0, atol=1e-12 * np.abs(run.x).max())


def test_default_digital_loop_stable_on_full_fe_model():
    """The real-rig default (config/seed_rotor.yaml): 5 kHz digital PD with the amplifier, sensor filter and
    shaft damping on the full FE model (no modal cutoff) - sampled-data Floquet at rest, max|mu| per sample."""
    cfg = load_config()
    assert cfg.modal_cutoff is None
    model = build_structure(cfg)
    assert model.basis is None and model.n == 4 * cfg.n_nodes
    sl = SampledLoop(model, cfg, forcing=False)
    assert sl.plant.N == 2 * model.n + 4 + 8  # amplifier states, second-order filter states
    rho = sampled_floquet(sl, BaseMotion(), None).max_abs
    assert rho < 1.0 - 1e-6
    # and the same dynamics without the shaft damping are not: the damping is what keeps the mesh modes out
    bare = load_config(overrides=["structural_damping.model=none"])
    rho_bare = sampled_floquet(SampledLoop(build_structure(bare), bare, forcing=False), BaseMotion(), None).max_abs
    assert rho_bare > 1.0
