"""The continuous PID's extra states (integral, derivative filter) against an independent interconnection.

The loop of docs/physics.md#controller is rebuilt here from the open-loop plant and the controller's transfer function
C(s) = kp + kI/s + kd s/(1 + s/wf) (scipy.signal.tf2ss, one copy per AMB axis) closed by i = -C(s) y: its
eigenvalues must equal those of amb_dynamics.system.closed_loop.
"""

import numpy as np
import pytest
import scipy.linalg as sla
from scipy.optimize import linear_sum_assignment
from scipy.signal import tf2ss

from amb_dynamics.config import load_config, paper_config_path
from amb_dynamics.structure import build_structure
from amb_dynamics.system import closed_loop


def reference_eigs(model, kp, kI, kd, wf):
    n, Ba, g = model.n, model.Ba, model.gains
    Minv = sla.inv(model.M)
    Ap = np.block(
        [[np.zeros((n, n)), np.eye(n)], [-Minv @ (model.matrices.shaft_stiffness + g.ks * Ba @ Ba.T), np.zeros((n, n))]]
    )
    Bp = np.vstack([np.zeros((n, 4)), Minv @ Ba * g.ki])
    Cp = np.hstack([Ba.T, np.zeros((4, n))])
    # C(s) as one rational function: (kp s (1+s/wf) + kI (1+s/wf) + kd s^2) / (s (1+s/wf))
    num = np.polyadd(np.polyadd(np.polymul([kp, 0.0], [1 / wf, 1.0]), np.polymul([kI], [1 / wf, 1.0])), [kd, 0.0, 0.0])
    den = np.polymul([1.0, 0.0], [1 / wf, 1.0])
    Ac, Bc, Cc, Dc = tf2ss(num, den)
    k = Ac.shape[0]
    Ak, Bk, Ck, Dk = (sla.block_diag(*[X] * 4) for X in (Ac, Bc, Cc, Dc))
    # i = -(Ck xc + Dk y), xc' = Ak xc + Bk y
    A = np.block([[Ap - Bp @ Dk @ Cp, -Bp @ Ck], [Bk @ Cp, Ak]])
    assert A.shape == (2 * n + 4 * k, 2 * n + 4 * k)
    return np.linalg.eigvals(A)


def matched_error(a, b):
    cost = np.abs(a[:, None] - b[None, :])
    r, c = linear_sum_assignment(cost)
    return np.max(cost[r, c] / np.maximum(np.abs(a[r]), 1.0))


@pytest.mark.parametrize(("kI", "filter_hz"), [(0.0, 800.0), (2.0e5, 800.0), (2.0e5, 3000.0)])
def test_pid_states_match_transfer_function_interconnection(kI, filter_hz):
    cfg = load_config(
        paper_config_path(),
        [f"controller.integral_gain={kI}", f"controller.derivative_filter_hz={filter_hz}", "spin_speed_rpm=0"],
    )
    model = build_structure(cfg)
    loop = closed_loop(model, cfg)
    expected_states = 2 * model.n + (4 if kI else 0) + 4
    assert loop.N == expected_states
    g = model.gains
    ref = reference_eigs(model, g.kp, kI, g.kd, g.omega_f)
    if kI == 0.0:  # tf2ss keeps the pole at s = 0 that kI = 0 cancels: drop one zero root per axis
        ref = ref[np.argsort(np.abs(ref))][4:]
    got = np.linalg.eigvals(loop.A0)
    assert matched_error(got, ref) < 1e-8


def test_filtered_derivative_tends_to_ideal():
    ideal_cfg = load_config(paper_config_path())
    model = build_structure(ideal_cfg)
    ideal = np.sort_complex(np.linalg.eigvals(closed_loop(model, ideal_cfg).A0))
    errs = []
    for hz in (1e5, 1e6):
        cfg = load_config(paper_config_path(), [f"controller.derivative_filter_hz={hz}"])
        lam = np.linalg.eigvals(closed_loop(build_structure(cfg), cfg).A0)
        lam = lam[np.argsort(np.abs(lam))][: ideal.size]  # drop the 4 fast filter poles near -2 pi hz
        errs.append(matched_error(ideal, lam))
    assert errs[0] / errs[1] == pytest.approx(10.0, rel=0.3)  # first order in 1/wf
    assert errs[1] < 2e-3
