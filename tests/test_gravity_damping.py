"""Gravity in the base frame and the static AMB loads (analytic statics of the rotor on two supports), and
structural damping (modal damping ratios of the free-free shaft against the model's definition)."""

import numpy as np
import pytest
import scipy.linalg as sla

from amb_dynamics.config import load_config, paper_config_path
from amb_dynamics.fe import assemble
from amb_dynamics.gravity import gravity_base_frame, gravity_load_shapes, static_amb_load
from amb_dynamics.motion import BaseMotion
from amb_dynamics.structure import build_structure
from amb_dynamics.system import closed_loop

G = 9.81
M_SHAFT = 7810.0 * np.pi * 0.03**2 / 4 * 1.5  # kg, 1.5 m of 30 mm steel
M_DISK = 7810.0 * np.pi * 0.5**2 / 4 * 0.07  # kg, at x = 1.5 m
X_AMB5 = 1.0  # m (AMB1 at x = 0)


def level_reactions():
    """Moments about AMB1 and the force balance: the AMB forces on the rotor (N, +Y up)."""
    r5 = G * (M_SHAFT * 0.75 + M_DISK * 1.5) / X_AMB5
    return G * (M_SHAFT + M_DISK) - r5, r5


def test_level_static_load_is_statics():
    r1, r5 = level_reactions()
    load = static_amb_load(load_config(paper_config_path()))
    np.testing.assert_allclose(load.forces, [r1, 0.0, r5, 0.0], rtol=1e-9, atol=1e-9)
    assert load.forces[2] == pytest.approx(1640.5, abs=0.1) and load.forces[0] == pytest.approx(-506.2, abs=0.1)
    np.testing.assert_allclose(load.currents, load.forces / 177.4, rtol=1e-12)


def test_static_load_follows_a_pitching_and_rolling_base():
    """Pitch beta about Z: g_B = (-g sin b, -g cos b, 0), the Y loads scale with cos b (X is axial).
    Roll phi about X: g_B = (0, -g cos p, g sin p), the Z loads are -tan p times the Y loads."""
    cfg = load_config(paper_config_path())
    r1, r5 = level_reactions()
    for kind in ("pitch", "roll"):
        motion = BaseMotion.single(kind, 0.3, 2.0)
        for t in (0.2, 0.9, 2.1):
            angle = 0.3 * np.sin(2.0 * t)
            q = motion.attitude(np.array([t]))[0]
            f = static_amb_load(cfg, q).forces
            c, s = np.cos(angle), np.sin(angle)
            expected = [r1 * c, 0, r5 * c, 0] if kind == "pitch" else [r1 * c, -r1 * s, r5 * c, -r5 * s]
            np.testing.assert_allclose(f, expected, rtol=1e-9, atol=1e-9)
            g_b = gravity_base_frame(q)
            ref = [-G * s, -G * c, 0.0] if kind == "pitch" else [0.0, -G * c, G * s]
            np.testing.assert_allclose(g_b, ref, atol=1e-12)


def test_gravity_load_is_the_weight():
    fe = assemble(load_config(paper_config_path()))
    shapes = gravity_load_shapes(fe)
    assert shapes[0::4, 0].sum() == pytest.approx(M_SHAFT + M_DISK, rel=1e-12)  # sum of v loads per unit g
    assert abs(shapes[1::4, 0].sum()) < 1e-12  # a Y field loads no w DOF


def test_real_rig_feedforward_is_the_statics():
    """config/seed_rotor.yaml's bias_current_offset carries the level rotor's static load."""
    cfg = load_config()
    np.testing.assert_allclose(cfg.controller.bias_current_offset, static_amb_load(cfg).currents, atol=1e-6)


def free_free_modes(fe, D):
    """Damping ratios of the free-free shaft from the quadratic eigenproblem (pencil form, no M^-1)."""
    eye, zero = np.eye(fe.n), np.zeros((fe.n, fe.n))
    A = np.block([[zero, eye], [-fe.matrices.shaft_stiffness, -D]])
    B = np.block([[eye, zero], [zero, fe.matrices.mass]])
    lam = sla.eig(A, B, right=False)
    lam = lam[(lam.imag > 1.0)]  # flexural modes (rigid-body roots at 0)
    order = np.argsort(lam.imag)
    return np.abs(lam[order]), -lam[order].real / np.abs(lam[order])


@pytest.mark.parametrize(
    ("setting", "zeta"),
    [
        ("structural_damping={model: loss_factor, loss_factor: 0.02}", lambda w: np.full_like(w, 0.01)),
        ("structural_damping={model: rayleigh, alpha: 3.0, beta: 2.0e-5}", lambda w: 3.0 / (2 * w) + 2.0e-5 * w / 2),
    ],
)
def test_structural_damping_ratios(setting, zeta):
    cfg = load_config(paper_config_path(), [setting, "modal_cutoff=null"])
    model = build_structure(cfg)
    w, z = free_free_modes(model.fe, model.matrices.structural_damping)
    assert len(w) == model.fe.n - 4  # 4 rigid-body modes: translation and tilt in two planes
    np.testing.assert_allclose(z, zeta(w), rtol=1e-6)


def test_paper_config_has_no_structural_damping():
    cfg = load_config(paper_config_path(), ["modal_cutoff=null"])
    model = build_structure(cfg)
    assert not model.matrices.structural_damping.any()
    damped = build_structure(load_config(paper_config_path(), ["modal_cutoff=null", "structural_damping.model=rayleigh",
                                                               "structural_damping.beta=1e-5"]))  # fmt: skip
    a0, a1 = closed_loop(model, cfg).A0, closed_loop(damped, cfg).A0
    n = model.n
    np.testing.assert_allclose(
        a0[n:, n:] - a1[n:, n:], np.linalg.solve(model.M, 1e-5 * model.matrices.shaft_stiffness), atol=1e-6
    )
