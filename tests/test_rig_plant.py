"""The rig plant stepper (amb_dynamics.rig_plant) and its offline loop (rig_loop.simulate_rig).

* every effect off: equals SampledLoop.simulate (the paper's sampled-data loop) to 1e-12;
* nonlinear bearing law: the differential pair is odd in (x, i), so its departure from ki i + |ks| x is third
  order: a small-amplitude run differs from the linear one by O((a/g0)^2) relative - halving a divides the
  difference by 4;
* touchdown: a rotor dropped (zero control current from t = 0) on backup bearings at the AMB nodes comes to
  rest; the contact force equals the rigid-body statics share of the weight (two supports: determinate, computed
  here from the geometry) plus the bias pull |ks| e of the de-controlled magnets; penetration and energy bounded;
* gravity in the base frame on a slowly pitching base: the AMB sag follows R_j cos(theta(t)) / k_eq.
"""

import math
from pathlib import Path

import numpy as np
import pytest

from amb_dynamics.config import load_config
from amb_dynamics.motion import BaseMotion
from amb_dynamics.rig_loop import simulate_rig
from amb_dynamics.sampled import SampledLoop
from amb_dynamics.structure import build_structure

PAPER = Path(__file__).resolve().parents[1] / "config" / "seed_paper.yaml"


def paper(*overrides):
    cfg = load_config(PAPER, list(overrides))
    return cfg, build_structure(cfg)


def disk_x0(model, v):
    x0 = np.zeros(2 * model.n)
    q = np.zeros(model.fe.n)
    q[4 * 6] = v  # node 7 (the disk), v
    x0[: model.n] = model.from_fe(q)
    return x0


def test_effects_off_equals_sampled_loop():
    cfg, model = paper()
    motion = BaseMotion.from_config(cfg.base_motion)
    x0 = disk_x0(model, 1e-4)
    ref = SampledLoop(model, cfg).simulate(motion, 1500, x0)
    run = simulate_rig(model, cfg, motion, 1500, x0, current_limit=1e9)
    assert np.abs(run.x - ref.x).max() <= 1e-12 * np.abs(ref.x).max()
    assert np.abs(run.y - ref.y).max() <= 1e-12 * np.abs(ref.y).max()


def _rel(a, b):
    return np.abs(a - b).max() / np.abs(b).max()


def test_small_amplitude_nonlinear_equals_linear_to_second_order():
    # i0 = 5 A: g0 = i0 ki/|ks| = 0.639 mm for the nonlinear law (config check)
    g0 = 5.0 * 177.4 / 1.388e6
    cfg_l, model = paper("spin_speed_rpm=0", "base_motion.kind=none")
    cfg_n, _ = paper(
        "spin_speed_rpm=0", "base_motion.kind=none", "bearings.force_law=nonlinear", f"bearings.air_gap={g0}"
    )
    errs = []
    for a in (2e-6, 4e-6):
        x0 = disk_x0(model, a)
        lin = simulate_rig(model, cfg_l, BaseMotion(), 400, x0)
        nl = simulate_rig(model, cfg_n, BaseMotion(), 400, x0)
        errs.append(_rel(nl.displacement, lin.displacement))
    assert errs[1] / errs[0] == pytest.approx(4.0, rel=0.05)  # O(a^2) relative: cubic departure of the law
    assert errs[0] < 1e-3


def rigid_reactions(cfg):
    """Support forces (N, +Y up) at the AMB nodes for gravity along -Y: rigid-body statics from the geometry."""
    sh = cfg.shaft
    L = sh.length
    m_shaft = sh.density * math.pi * sh.diameter**2 / 4 * L
    x_node = lambda node: (node - 1) * L / sh.elements  # noqa: E731
    loads = [(m_shaft, L / 2)]
    for d in cfg.disks:
        loads.append((sh.density * math.pi * (d.diameter**2 - d.bore**2) / 4 * d.thickness, x_node(d.node)))
    a, b = (x_node(nd) for nd in cfg.bearings.nodes)
    W = sum(m for m, _ in loads) * cfg.gravity.g
    Mb = sum(m * cfg.gravity.g * (x - a) for m, x in loads)  # moment about the first support
    Rb = Mb / (b - a)
    return np.array([W - Rb, Rb])


TD = [
    "touchdown.nodes=[1, 5]",
    "touchdown.clearance=2.5e-4",
    "touchdown.stiffness=5.0e7",
    "touchdown.damping=2.0e4",
    "touchdown.friction=0.1",
    "gravity.enabled=true",
    "spin_speed_rpm=0",
    "base_motion.kind=none",
    "modal_cutoff=null",  # static contact loads need the full FE model (a modal basis only projects them)
    "structural_damping.model=rayleigh",
    "structural_damping.alpha=30.0",  # a well-damped rotor (the overhung disk sags 5 mm on its shaft and
    "structural_damping.beta=1e-4",  # bounces at ~25 rad/s): the test settles within 0.5 s
]


def energy(model, cfg, x):
    """Kinetic + elastic + bias-pull + contact energy minus the work of gravity (J), computed here."""
    n = model.n
    q, v = x[:n], x[n : 2 * n]
    T = np.zeros((model.fe.n, 2))
    T[0::4, 0] = 1.0
    Psi = model.basis if model.basis is not None else np.eye(model.fe.n)
    fg = (Psi.T @ model.fe.matrices.mass @ T)[:, 0] * -cfg.gravity.g
    y = model.Ba.T @ q
    E = 0.5 * v @ model.M @ v + 0.5 * q @ model.matrices.shaft_stiffness @ q + 0.5 * model.gains.ks * y @ y - fg @ q
    for j in (0, 2):
        d = math.hypot(y[j], y[j + 1]) - cfg.touchdown.clearance
        E += 0.5 * cfg.touchdown.stiffness * d * d if d > 0 else 0.0
    return E


def test_dropped_rotor_rests_on_backup_bearings():
    """Zero control current from t = 0 (bias on): the rotor falls onto backup bearings at nodes 1 and 5 (node 1
    is lifted by the overhung disk) and comes to rest; radial balance at each node with the analytic statics."""
    cfg, _ = paper(*TD)
    R = rigid_reactions(cfg)  # support force needed at nodes 1, 5 (+Y)
    off = R / cfg.bearings.current_stiffness  # levitated at the centre of both AMBs before the failure
    cfg, model = paper(*TD, f"controller.bias_current_offset=[{off[0]}, 0.0, {off[1]}, 0.0]")
    run = simulate_rig(model, cfg, BaseMotion(), 2500, fail_at_s=0.0)
    assert np.abs(run.displacement[0]).max() < 1e-9
    k_c, c, mu = cfg.touchdown.stiffness, cfg.touchdown.clearance, cfg.touchdown.friction
    ks = -cfg.bearings.displacement_stiffness
    r = run.displacement[-1].reshape(2, 2)  # (node, (y, z))
    e = np.hypot(r[:, 0], r[:, 1])
    nrm = r / e[:, None]
    d = e - c
    # radial balance: contact k_c d inward, bias pull ks e outward, support need R along +Y
    assert np.allclose(k_c * d, ks * e - R * nrm[:, 0], rtol=2e-3)
    # the analytic rest point at the bottom/top of the clearance circle: k_c d = |R| + ks (c + d)
    d_exact = (np.abs(R) + ks * c) / (k_c - ks)
    assert np.allclose(d, d_exact, rtol=0.01)  # friction holds the rotor up to ~5 deg off the vertical
    # friction cone: sideways offset at most mu Fn / (Fn/e - ks) (Coulomb friction can hold it there)
    fn = k_c * d
    assert np.all(np.abs(r[:, 1]) <= mu * fn / (fn / e - ks))
    assert np.abs(run.x[-1, model.n : 2 * model.n]).max() < 5e-3  # at rest (modal velocities, sqrt(kg) m/s)
    # penetration bound: below 3 x its static value (a drop from the centre through the clearance)
    peak = max(ev[2] for ev in run.contacts)
    assert peak < 3 * d_exact.max()
    assert {ev[1] for ev in run.contacts} == {1, 5}
    E = np.array([energy(model, cfg, x) for x in run.x])
    growth = np.max(E - np.minimum.accumulate(E))  # largest rise above the lowest energy so far
    assert growth <= 1e-3 * (E[0] - E[-1])


def test_gravity_on_a_pitching_base_follows_attitude():
    """Slow pitch theta = A sin(w t): AMB sag y_j = -R_j cos(theta) / k_eq (PD statics, determinate supports).

    The run starts levitated (rig_loop.levitated_state); the expectation is the rigid-body statics above."""
    A, w = 0.3, 2.0
    cfg, model = paper("gravity.enabled=true", "spin_speed_rpm=0", "base_motion.kind=none", "modal_cutoff=2000")
    k_eq = model.gains.k_eq
    R = rigid_reactions(cfg)
    steps = round(math.pi / (2 * w) * cfg.controller.rate_hz)
    run = simulate_rig(model, cfg, BaseMotion.single("pitch", A, w), steps, current_limit=100.0)  # PD alone: 18 A
    theta = A * np.sin(w * run.t)
    expected = -np.outer(np.cos(theta), R) / k_eq
    got = run.displacement[:, [0, 2]]
    # within 0.4 % of the static sag (the undamped paper rotor rings a little as the base starts to turn, and
    # the 2000 rad/s modal basis holds the static sag to 0.1 %); the attitude changes it by 1 - cos 0.3 = 4.5 %
    assert np.abs(got - expected).max() < 4e-3 * np.abs(R).max() / k_eq
    assert np.abs(got[-1] - got[0]).max() > 0.04 * np.abs(R).max() / k_eq
    assert np.abs(run.displacement[:, [1, 3]]).max() < 1e-9  # pitch about Z keeps gravity in the X-Y plane
