"""The plant's interpolated step exponentials (rate_family.RateFamily) against the exact per-step exponential.

On a base moving about one axis the plant interpolates its step exponential in the base rate instead of computing
one expm per step.  The exact path is the same RigPlant with no single-axis motion known to it (``_axis`` None), so
every difference below is the interpolation's.  Tolerances: each step matrix is checked at build time to 1e-12 per
column (FAMILY_TOL); over 2,000 steps of a loop with multipliers near 1 that may add up to ~1e-10 of the signal,
asserted at 1e-9.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from amb_dynamics import rig_plant
from amb_dynamics.config import load_config
from amb_dynamics.motion import BaseMotion
from amb_dynamics.rate_family import RateFamily
from amb_dynamics.rig_loop import simulate_rig
from amb_dynamics.structure import build_structure

ROOT = Path(__file__).resolve().parents[1]
PAPER, REAL = ROOT / "config" / "seed_paper.yaml", ROOT / "config" / "seed_rotor.yaml"


def _runs(monkeypatch, path, motion_sets, steps, x0_disk=0.0):
    cfg = load_config(path, motion_sets)
    model = build_structure(cfg)
    motion = BaseMotion.from_config(cfg.base_motion)
    x0 = None
    if x0_disk:
        x0 = np.zeros(2 * model.n)
        x0[4 * 6] = x0_disk  # disk node 7, v (full FE model: no modal basis in these configs)
    interp = simulate_rig(model, cfg, motion, steps, x0)
    with monkeypatch.context() as m:
        m.setattr(rig_plant, "single_axis_bounds", lambda harmonics: None)  # every step exact
        exact = simulate_rig(model, cfg, motion, steps, x0)
    return interp, exact


def _rel(a, b):
    return float(np.abs(a - b).max() / np.abs(b).max())


def test_real_rig_pitching_equals_the_exact_steps(monkeypatch):
    # the tongue point of tests/test_rig_monitor_real.py: unbalance, gravity, noise, nonlinear law, all on
    interp, exact = _runs(monkeypatch, REAL, ["base_motion.amplitude=0.6", "base_motion.frequency=21.8"], 2000)
    assert 0.0 < _rel(interp.y, exact.y) < 1e-9  # > 0: the interpolated path was taken (1.8e-11 here)
    assert _rel(interp.x, exact.x) < 1e-9
    assert _rel(interp.i, exact.i) < 1e-9


def test_paper_roll_uses_the_rate_derivative_and_equals_the_exact_steps(monkeypatch):
    # roll turns about the shaft axis: the step depends on w and dw/dt (a 2-D interpolant), not on w^2 alone
    cfg = load_config(PAPER, ["base_motion.kind=roll", "base_motion.amplitude=0.3", "base_motion.frequency=24.5"])
    plant = rig_plant.RigPlant(build_structure(cfg), cfg, 1.0 / cfg.controller.rate_hz)
    Om, dOm = BaseMotion.from_config(cfg.base_motion).angular_velocity(np.array([0.01]))
    plant.matrices(Om[:, 0], dOm[:, 0], plant.spin_speed())
    (fam,) = plant._families.values()
    assert fam.uses_v and not fam.even and fam.error <= rig_plant.FAMILY_TOL
    interp, exact = _runs(
        monkeypatch, PAPER, ["base_motion.kind=roll", "base_motion.amplitude=0.3", "base_motion.frequency=24.5"],
        1500, x0_disk=1e-4,
    )  # fmt: skip
    assert 0.0 < _rel(interp.y, exact.y) < 1e-9  # 7e-16 here


def test_rates_outside_the_box_are_stepped_exactly(monkeypatch):
    # the plant was told of a small motion, the base moves more: every step takes the exact path, bit for bit
    cfg = load_config(PAPER, ["base_motion.amplitude=0.01"])
    model = build_structure(cfg)
    big = BaseMotion.single("pitch", 0.3, 24.5)
    Ts = 1.0 / cfg.controller.rate_hz
    t = Ts * np.arange(300)
    Om, dOm = big.angular_velocity(t)
    plants = [rig_plant.RigPlant(model, cfg, Ts)]
    with monkeypatch.context() as m:
        m.setattr(rig_plant, "single_axis_bounds", lambda harmonics: None)
        plants.append(rig_plant.RigPlant(model, cfg, Ts))
    x = [np.zeros(plants[0].N) for _ in plants]
    x[0][4 * 6] = x[1][4 * 6] = 1e-4
    i = np.zeros(4)
    for k in range(t.size):
        x = [p.step(xi, i, Om[:, k], dOm[:, k]) for p, xi in zip(plants, x, strict=True)]
    assert np.array_equal(x[0], x[1])
    assert all(not fam.covers(0.3 * 24.5, 0.0) for fam in plants[0]._families.values())


def test_family_interpolates_an_analytic_matrix_function():
    # F(w) = expm(h (A0 + w^2 A1)) for a small random pair: the interpolant at random rates equals expm there
    import scipy.linalg as sla

    rng = np.random.default_rng(7)
    A0, A1 = rng.normal(size=(5, 5)), rng.normal(size=(5, 5))
    e = np.array([0.0, 0.0, 1.0])

    def F(Om, dOm):
        return sla.expm(0.1 * (A0 + (Om @ e) ** 2 * A1))

    fam = RateFamily(F, e, 2.0, 5.0, tol=1e-12)
    assert fam.even and not fam.uses_v
    for w in rng.uniform(-2.0, 2.0, 5):
        assert np.abs(fam.at(w, 0.0) - F(w * e, 0 * e)).max() < 1e-11 * np.abs(F(w * e, 0 * e)).max()
