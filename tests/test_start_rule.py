"""How a linear controller stage starts (amb_dynamics.control_runtime.start_map): at the fixed point of its first
input in its fast and its unstable modes, empty in its slow stable ones, checked against the modal form of a system
built from known eigenvalues; and the real rig's LQG, whose low-frequency weights are such slow modes, starts as
calmly as it then runs (it kicked the rotor by 0.3 mm when every mode started at its fixed point).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from amb_dynamics.config import load_config
from amb_dynamics.control_runtime import SLOW_MODE, LinearStage, start_map
from amb_dynamics.motion import BaseMotion
from amb_dynamics.rig_loop import RigStepper
from amb_dynamics.state_space import StateSpace
from amb_dynamics.structure import build_structure

LQG = Path(__file__).resolve().parents[1] / "config" / "seed_rotor_2khz_lqg.yaml"

# (eigenvalue, kept at its fixed point): an integrator, a slow stable mode, a slow unstable mode, fast ones and a
# fast complex pair (entered as its real 2x2 block)
MODES = [(1.0, False), (0.99, False), (1.01, True), (0.5, True), (-1.2, True), (0.3 + 0.4j, True)]


def modal_system(seed: int = 3):
    """A = V L V^-1 with L block diagonal (real), a random well-conditioned V, B random: the modes are known."""
    rng = np.random.default_rng(seed)
    blocks, keep = [], []
    for lam, kept in MODES:
        if isinstance(lam, complex):
            blocks.append(np.array([[lam.real, lam.imag], [-lam.imag, lam.real]]))
            keep += [kept, kept]
        else:
            blocks.append(np.array([[lam]]))
            keep.append(kept)
    n = sum(b.shape[0] for b in blocks)
    L = np.zeros((n, n))
    i = 0
    for b in blocks:
        L[i : i + b.shape[0], i : i + b.shape[0]] = b
        i += b.shape[0]
    V = np.linalg.qr(rng.standard_normal((n, n)))[0] @ np.diag(rng.uniform(0.5, 2.0, n))
    Vi = np.linalg.inv(V)
    return V @ L @ Vi, V @ rng.standard_normal((n, 2)), V, Vi, L, np.array(keep)


def test_start_map_is_the_fixed_point_of_the_kept_modes_and_zero_in_the_slow_stable_ones():
    A, B, V, Vi, L, keep = modal_system()
    expected = np.zeros((A.shape[0], B.shape[1]))
    k = np.flatnonzero(keep)  # in the modal coordinates the kept blocks solve (I - L_kk) z = (V^-1 B)_k
    expected[k] = np.linalg.solve(np.eye(k.size) - L[np.ix_(k, k)], (Vi @ B)[k])
    np.testing.assert_allclose(start_map(A, B), V @ expected, rtol=0, atol=1e-10)
    assert SLOW_MODE > 0.01  # the slow modes above are slow by this rule's measure


def test_a_held_input_moves_only_the_slow_modes():
    """Held at y0, the stage's modal coordinates follow z_k = z* + L^k (z_0 - z*): the kept modes stay at their
    fixed point (the unstable ones too: started elsewhere they would run away), the slow stable mode creeps
    towards its own, and the integrator ramps from zero."""
    A, B, _, Vi, L, keep = modal_system()
    stage = LinearStage(StateSpace(A, B, np.eye(A.shape[0]), np.zeros((A.shape[0], 2)), 1.0))
    y0 = np.array([0.7, -1.3])
    b = Vi @ B @ y0
    z = None
    for _ in range(40):
        stage.step(y0)
        z = Vi @ stage.x
    steps = 40
    np.testing.assert_allclose(z[0], steps * b[0], rtol=1e-9)  # integrator: 40 samples of b
    np.testing.assert_allclose(z[1], b[1] * (1 - 0.99**steps) / (1 - 0.99), rtol=1e-9)  # from zero
    kept = np.flatnonzero(keep)
    z_star = np.linalg.solve(np.eye(kept.size) - L[np.ix_(kept, kept)], b[kept])
    np.testing.assert_allclose(z[kept], z_star, rtol=0, atol=1e-9 * np.abs(z_star).max())


def test_without_slow_modes_the_start_is_the_whole_fixed_point():
    rng = np.random.default_rng(5)
    A = 0.5 * np.linalg.qr(rng.standard_normal((6, 6)))[0]  # every eigenvalue on |lambda| = 0.5
    B = rng.standard_normal((6, 3))
    np.testing.assert_allclose(start_map(A, B), np.linalg.solve(np.eye(6) - A, B), rtol=1e-12, atol=1e-14)


def _lqg_peaks(held: int) -> tuple[float, float]:
    """The rig offline from levitation on a static base, every effect on, after the controller answered ``held``
    samples of the held start state (the realtime plant holds its rotor until start_samples commands were on
    time): (peak over the first 20 ms, peak over the last 0.2 s of 0.5 s), all four channels."""
    cfg = load_config(LQG)
    fs = cfg.controller.rate_hz
    steps = round(0.5 * fs)
    run = RigStepper(build_structure(cfg), cfg, BaseMotion.single("none", 0.0, 1.0), steps)
    for _ in range(held):
        run.ctrl.step(0, run.plant.measure(run.x[0]))
    run.advance(steps)
    d = np.abs(run.run().displacement)
    return d[: round(0.02 * fs)].max(), d[-round(0.2 * fs) :].max()


@pytest.mark.parametrize("held", [0, 40])
def test_the_lqg_starts_as_calmly_as_it_runs(held):
    first, steady = _lqg_peaks(held)
    assert first < 1.5 * steady, (first, steady)  # every mode at its fixed point: 304 um against 44 um
    assert steady < 60e-6  # the unbalance, runout and noise response of this rig at 1000 rpm
